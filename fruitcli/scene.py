"""Scene files: one TOML per experiment, validated strictly against `SCHEMA`.

Every user-facing key carries its unit in its name (`young_modulus_kpa`,
`spacing_x_mm`). Relative paths are resolved against the scene file's folder,
then against the project root (the nearest parent holding `pyproject.toml`).
"""

from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fruitcli.errors import SceneError

NUM = (int, float)


@dataclass(frozen=True)
class Key:
    """One scene key: its accepted type, default (None: optional), and meaning."""

    kind: str  # "str", "path", "num", "int", "bool", "vec2", "vec3", "box", "list", "table",
    # "range" (a number or [lo, hi])
    default: Any = None
    doc: str = ""
    required: bool = False


LINEAR_SOLVERS = ("pcg", "direct", "jacobi")
"""[solver].linear_solver values (see `fruitcli.fem.solver.linsolve`)."""

# Sections that are tables (one per scene).
SCHEMA: dict[str, dict[str, Key]] = {
    "scene": {
        "name": Key("str", None, "scene name (default: file stem)"),
        "description": Key("str", "", "free text"),
        "configuration": Key("str", "Rest", "configuration label in tables (Rest, Deformed, ...)"),
    },
    "geometry": {
        "artist": Key("path", None, "artist's high-resolution closed mesh (STL/OBJ/PLY)"),
        "generate_artist": Key("bool", False, "write the default fruit to `artist` if missing"),
        "unit": Key("str", "mm", "unit of the mesh files (artist, solid, surface): mm, cm, m"),
        "fit_mm": Key("num", None, "scale the artist mesh (after unit) so that its largest "
                                   "extent is this (mm); chambers stay as given (mm)"),
        "solid": Key("path", None, "closed surface used as the FEM body as is ([geometry].unit)"),
        "pad_size_mm": Key("vec3", None, "flat pad [x, y, thickness] in mm, centred at x=y=0"),
        "chamber": Key("list", [], "pneumatic chambers ([[geometry.chamber]])"),
    },
    "tracks": {
        "cover_mm": Key("num", 2.0, "inward offset for the cover layer (mm)"),
        "faces": Key("int", 5000, "target triangle count of the reduced surface"),
        "track_radius_mm": Key("num", 0.6, "radius of the yarn tubes (mm)"),
        "split_z_mm": Key("num", None, "casting split plane height (mm; default: automatic)"),
        "yarn_max_stretch": Key("num", 0.25, "warn when a track stretches more than this "
                                             "fraction (yarn limit 0.3 minus a 0.05 margin)"),
        "zigzag_pitch_mm": Key("num", 4.0, "zig-zag pitch of the sewn yarn (mm): the warnings' "
                                           "amplitude and the length of the local stretch"),
        "file": Key("path", None, "track centre lines given directly (track,axis,index,point,"
                                  "x_mm,y_mm,z_mm; default: make-tracks' tracks.csv)"),
    },
    "grid": {
        "spacing_x_mm": Key("num", 16.0, "distance between x = const planes (mm)"),
        "spacing_y_mm": Key("num", 12.0, "distance between y = const planes (mm)"),
        "origin_mm": Key("vec2", None, "[x0, y0] of plane (0, 0) (mm; default: centred)"),
        "count": Key("list", None, "[nx, ny] taxels on a flat pad"),
        "taxels": Key("path", None, "taxel CSV given directly (id,i,j,x_mm,y_mm,z_mm)"),
    },
    "mold": {
        "wall_mm": Key("num", 4.0, "mold wall thickness (mm, at least 1)"),
        "clearance_mm": Key("num", 0.3, "gap between keys and sockets, pins and holes (mm)"),
        "key_radius_mm": Key("num", 3.0, "radius of the registration keys (mm)"),
        "pour_diameter_mm": Key("num", 8.0, "pour hole diameter (mm)"),
        "vent_diameter_mm": Key("num", 2.0, "vent diameter (mm)"),
        "pin_diameter_mm": Key("num", 3.0, "diameter of the pins holding chamber cores (mm)"),
        "vents": Key("int", 4, "vents at the cavity's highest points besides the pour hole"),
    },
    "mesh": {
        "size_mm": Key("num", 3.0, "target tetrahedron edge length (mm)"),
        "min_size_mm": Key("num", None, "smallest edge near chambers and taxels (mm)"),
        "time_limit_s": Key("num", 120.0, "gmsh is killed after this many seconds"),
        "min_quality": Key("num", 0.05, "refuse meshes whose worst SICN is below this"),
    },
    "fem": {
        "element": Key("str", "p2", "p2 (quadratic tets, P2/P0 mean dilatation: no locking), "
                       "p2-pure (quadratic, displacement only) or p1 (linear tets, the "
                       "paper's SOFA element)"),
    },
    "material": {
        "model": Key("str", "neo-hookean", "neo-hookean (from E and nu), yeoh (c10_kpa, "
                     "c20_kpa, c30_kpa) or corotational (the paper's SOFA Hooke, p1 only)"),
        "c10_kpa": Key("num", None, "yeoh: C10 (kPa; the shear modulus is 2 C10)"),
        "c20_kpa": Key("num", 0.0, "yeoh: C20 (kPa)"),
        "c30_kpa": Key("num", 0.0, "yeoh: C30 (kPa)"),
        "bulk_modulus_kpa": Key("num", None, "bulk modulus kappa (kPa; default from E, nu)"),
        "young_modulus_kpa": Key("num", 100.0, "Young's modulus E (kPa)"),
        "poisson_ratio": Key("num", 0.45, "Poisson's ratio nu (-1 < nu < 0.5)"),
        "density_kg_m3": Key("num", 1070.0, "density (kg/m^3)"),
    },
    "gravity": {
        "vector_m_s2": Key("vec3", [0.0, 0.0, -9.81], "gravity acceleration (m/s^2)"),
    },
    "fixed": {},  # array of tables, see ARRAY_SCHEMA
    "jig": {},
    "actuation": {
        "pressure_kpa": Key("table", None, "per chamber: one pressure per state (kPa)"),
        "volume_growth_mm3": Key("table", None, "per chamber: one volume growth per state (mm^3)"),
        "period_s": Key("num", None, "duration of one cycle of the states (s), for animations"),
    },
    "solver": {
        "tolerance": Key("num", 1e-6, "Newton stops when |residual| <= tolerance * |load|"),
        "displacement_tolerance_mm": Key("num", 1e-4, "... or when the kept factor estimates "
                                         "the correction left within half this (mm; 0 = "
                                         "off)"),
        "max_iterations": Key("int", 25, "Newton iterations per load step"),
        "max_subdivisions": Key("int", 6, "times a failing load step may be halved"),
        "linear_solver": Key("str", "pcg", "pcg (CG on a kept Cholesky), direct or jacobi"),
        "jig_steps": Key("int", 1, "load steps to apply the jig rotation"),
        "first_steps": Key("int", 4, "load steps of the state solved from rest (hyperelastic "
                           "models)"),
    },
    "reduced": {  # the reduced model of the live loop (fruitcli.fem.reduced_build)
        "pressure_range_kpa": Key("vec2", None, "[lo, hi] kPa for every chamber (default: "
                                  "each chamber's [actuation] pressures plus the margin)"),
        "margin": Key("num", 0.1, "fraction of each chamber's [actuation] span added on "
                      "either side"),
        "points_per_axis": Key("int", 5, "Chebyshev-Lobatto full solves per chamber"),
        "max_degree": Key("int", 4, "highest total degree tried (chosen by leave-one-out)"),
        "validation": Key("int", 50, "held-out random pressure vectors solved in full"),
        "seed": Key("int", 0, "seed of the held-out pressure vectors"),
    },
    "board": {
        "rows": Key("int", 21, "frame rows (Tx lines)"),
        "cols": Key("int", 12, "frame columns (Rx lines)"),
        "offset_i": Key("int", 0, "frame row of taxel i = 0"),
        "offset_j": Key("int", 0, "frame column of taxel j = 0"),
        "flip_i": Key("bool", False, "taxel i counts down the frame rows"),
        "flip_j": Key("bool", False, "taxel j counts down the frame columns"),
        "transpose": Key("bool", False, "taxel i runs along frame columns"),
        "format": Key("str", "auto", "frames on the port and in raw captures: auto, ascii "
                      "(stock Muca_Raw) or binary (stock SendRawByte packets)"),
    },
    "frames": {
        "recording": Key("path", None, "recorded frames (.npz or MuCa ASCII log)"),
        "model": Key("str", "reduced", "a recording with chamber pressures: reduced (taxels "
                     "from the reduced model at each frame's pressures) or full (along the "
                     "simulated states)"),
    },
    "detection": {
        "threshold_counts": Key("num", 20.0, "touch threshold on v = C - C0 (counts)"),
        "baseline_frames": Key("int", 10, "frames averaged into the baseline C0"),
        "method": Key("str", "n9", "n9 (paper), n9_floor, peaks or fit2 (two footprints "
                      "of the [skin] fitted around each peak: fingers close together)"),
        "noise_floor_counts": Key("num", 0.0, "subtracted from v before weighting (n9_floor)"),
        "hysteresis_counts": Key("num", 0.0, "touch ends below threshold - hysteresis"),
        "debounce_frames": Key("int", 0, "frames above threshold before a touch starts"),
        "drift_rate": Key("num", 0.0, "baseline tracking rate per untouched frame (0: off)"),
        "track_gate_mm": Key("num", 0.0, "touch IDs across frames within this distance (0: off)"),
        "project": Key("str", "none", "none (the N9 average of the 3D taxels, the paper) or "
                                      "surface (moved to the nearest point of the body)"),
        "divide_by_gain": Key("bool", False, "divide each taxel's activation by its gain in "
                              "[skin].taxel_gain before detection (threshold, maxima and N9 "
                              "weights on the divided v; off: the paper)"),
        "hovers": Key("bool", False, "report hovers (below the touch threshold) as kind hover"),
        "hover_threshold_counts": Key("num", None, "hover threshold (counts; default 8 x the "
                                      "[skin] noise std); below threshold_counts"),
        "hover_hysteresis_counts": Key("num", None, "a hover ends below its threshold minus "
                                       "this (counts; default 3 x the [skin] noise std)"),
        "footprint": Key("str", None, "[skin].footprint_sigma_mm entry heights and strengths "
                         "assume (default: the only one, else small)"),
    },
    "bench": {
        "indenters": Key("list", ["small", "medium"], "indenters to replay: small, medium"),
        "samples": Key("str", "quarter", "quarter (a quarter taxel off the grid) or a CSV path"),
        "state": Key("int", 0, "FEM state the bench runs on"),
        "step_mm": Key("num", 0.1, "indenter descent step (mm)"),
        "seed": Key("int", 0, "seed of the noise"),
        "baseline_frames": Key("int", 10, "idle frames recorded before each descent"),
        "reference_length_mm": Key("num", None, "for % errors (default: largest truth span)"),
        "register": Key("str", "none", "registration of the bench rows: none, translation, "
                                       "rigid or similarity (see [[evaluate]].register)"),
    },
    "skin": {  # the skin's forward model (fruitcli.sensing.skin.forward); defaults: its assumptions
        "footprint_sigma_mm": Key("table", None, "per indenter: lateral Gaussian width (mm); "
                                                 "default small 6.18, medium 7.21"),
        "contact_counts": Key("num", 60.0, "activation of the taxel under the indenter at "
                                           "contact (counts)"),
        "gap_decay_mm": Key("num", 2.0, "activation falls as exp(-gap / gap_decay_mm) (mm)"),
        "gain_spread": Key("num", 0.0, "taxel gains drawn uniformly in 1 +- spread (seeded)"),
        "noise_std_counts": Key("range", [0.5, 1.85], "noise std (counts): one value, or "
                                                      "[lo, hi] drawn per taxel (seeded)"),
        "taxel_gain": Key("path", None, "CSV (id, gain) of measured taxel gains, e.g. fruit "
                                        "calibrate's gains.csv (with gain_spread = 0)"),
    },
    "printer": {  # the real bench: a Marlin printer with an indenter (fruit bench --printer)
        "model_origin_mm": Key("vec3", None, "where the model's origin is, printer coordinates "
                               "(mm; required with [printer])"),
        "rotate_z_deg": Key("num", 0.0, "model rotated about z on the bed (degrees)"),
        "safe_height_mm": Key("num", 20.0, "tip height above the model's highest point "
                              "between samples (mm)"),
        "step_mm": Key("num", 0.1, "descent step (mm, 0 < step <= 1)"),
        "feed_mm_min": Key("num", 600.0, "feed rate of every move (mm/min)"),
        "max_press_mm": Key("num", 1.5, "deepest press below the expected surface before the "
                            "sample is an error (mm)"),
        "bed_mm": Key("box", [0.0, 0.0, 0.0, 220.0, 220.0, 250.0], "reachable volume "
                      "[xmin, ymin, zmin, xmax, ymax, zmax], printer coordinates (mm)"),
        "baud": Key("int", 115200, "the printer's serial baud rate"),
        "home": Key("bool", False, "send G28 (home all axes) first"),
        "timeout_s": Key("num", 30.0, "longest wait for an 'ok' (s; busy lines extend it)"),
    },
    "sensitivity": {
        "noise_frames": Key("int", 300, "frames at rest for the per-taxel noise std"),
        "animation_frames": Key("int", 60, "frames over one animation cycle"),
    },
    "report": {
        "paper_rows": Key("list", [], "paper Table I rows to show next to ours"),
    },
    "evaluate": {},
}

ARRAY_SCHEMA: dict[str, dict[str, Key]] = {
    "geometry.chamber": {
        "name": Key("str", None, "chamber name, used in [actuation]", required=True),
        "ellipsoid": Key("table", None, "{center_mm = [x,y,z], radii_mm = [a,b,c]}"),
        "surface": Key("path", None, "closed surface of the cavity ([geometry].unit)"),
    },
    "fixed": {
        "box_mm": Key("box", None, "[xmin, ymin, zmin, xmax, ymax, zmax] (mm)", required=True),
        "displacement_mm": Key("vec3", None, "the clamp moved by [dx, dy, dz] (mm), ramped "
                               "with the load steps (default: held at rest)"),
    },
    "jig": {
        "region_box_mm": Key("box", None, "nodes pulled by the springs (mm)", required=True),
        "rotate_deg": Key("num", 0.0, "rotation of the target about `axis` (degrees)"),
        "axis": Key("vec3", [0.0, 0.0, 1.0], "rotation axis"),
        "pivot_mm": Key("vec3", [0.0, 0.0, 0.0], "point on the rotation axis (mm)"),
        "translate_mm": Key("vec3", [0.0, 0.0, 0.0], "translation after the rotation (mm)"),
        "stiffness_n_per_mm": Key("num", 10.0, "spring stiffness per node (N/mm)"),
    },
    "evaluate": {
        "label": Key("str", None, "row label, e.g. 'Rest, small'", required=True),
        "truth": Key("path", None, "ground-truth CSV (sample,x_mm,y_mm[,z_mm])", required=True),
        "measured": Key("path", None, "measured CSV (same samples)", required=True),
        "reference_length_mm": Key("num", None, "for % errors (default: largest truth span)"),
        "register": Key("str", "none", "none, translation (the paper's protocol), rigid or "
                                       "similarity: measurement mapped onto the truth first"),
    },
}
ARRAY_SECTIONS = {"fixed", "jig", "evaluate"}
SUBTABLES = {"ellipsoid": {"center_mm": Key("vec3", required=True),
                          "radii_mm": Key("vec3", required=True)}}


@dataclass
class Scene:
    """A validated scene: `data[section][key]` with defaults filled in."""

    path: Path
    data: dict[str, Any]
    declared: set[str] = field(default_factory=set)  # sections present in the file

    @property
    def name(self) -> str:
        return self.data["scene"]["name"] or self.path.stem

    def has(self, section: str) -> bool:
        """True when the file declares `section` (or a non-empty array of it)."""
        return section in self.declared

    def __getitem__(self, section: str) -> Any:
        return self.data[section]

    @property
    def chambers(self) -> list[dict]:
        return self.data["geometry"]["chamber"]


def _closest(name: str, options) -> str:
    match = difflib.get_close_matches(name, list(options), n=1, cutoff=0.0)
    return f" (did you mean '{match[0]}'?)" if match else ""


def _project_root(start: Path) -> Path | None:
    for parent in [start, *start.parents]:
        if (parent / "pyproject.toml").exists():
            return parent
    return None


def resolve_path(scene_path: Path, value: str) -> Path:
    """Resolve a scene-relative path: scene folder first, then the project root."""
    p = Path(value).expanduser()
    if p.is_absolute():
        return p
    first = (scene_path.parent / p).resolve()
    if first.exists():
        return first
    root = _project_root(scene_path.parent.resolve())
    if root is not None and ((root / p).exists() or not first.parent.exists()):
        return (root / p).resolve()
    return first


def _check(where: str, key: str, spec: Key, value: Any, scene_path: Path, must_exist: bool):
    def fail(expected: str):
        raise SceneError(f"{where}.{key}: expected {expected}, got {value!r}")

    k = spec.kind
    if k == "str":
        if not isinstance(value, str):
            fail("a string")
        return value
    if k == "path":
        if not isinstance(value, str) or not value:
            fail("a file path string")
        p = resolve_path(scene_path, value)
        if must_exist and not p.exists():
            raise SceneError(f"{where}.{key}: file not found: {value}")
        return p
    if k == "bool":
        if not isinstance(value, bool):
            fail("true or false")
        return value
    if k == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            fail("an integer")
        return value
    if k == "num":
        if isinstance(value, bool) or not isinstance(value, NUM) or not math.isfinite(value):
            fail("a finite number")
        return float(value)
    if k == "range":
        if isinstance(value, NUM) and not isinstance(value, bool) and math.isfinite(value) \
                and value >= 0:
            return float(value)
        ok = isinstance(value, list) and len(value) == 2 and all(
            isinstance(v, NUM) and not isinstance(v, bool) and math.isfinite(v) for v in value)
        if not ok or not 0 <= value[0] <= value[1]:
            fail("a number >= 0 or [lo, hi] with 0 <= lo <= hi")
        return [float(v) for v in value]
    if k in ("vec2", "vec3", "box"):
        n = {"vec2": 2, "vec3": 3, "box": 6}[k]
        ok = isinstance(value, list) and len(value) == n
        ok = ok and all(isinstance(v, NUM) and not isinstance(v, bool) for v in value)
        if not ok or not all(math.isfinite(v) for v in value):
            fail(f"a list of {n} numbers")
        out = [float(v) for v in value]
        if k == "box" and any(out[a] > out[a + 3] for a in range(3)):
            fail("[xmin, ymin, zmin, xmax, ymax, zmax] with min <= max")
        return out
    if k == "list":
        if not isinstance(value, list):
            fail("a list")
        return value
    if k == "table":
        if not isinstance(value, dict):
            fail("a table {key = value}")
        return value
    raise AssertionError(k)


def _validate_table(where, table, spec, scene_path, must_exist):
    if not isinstance(table, dict):
        raise SceneError(f"{where}: expected a table, got {type(table).__name__}")
    out = {}
    for key, value in table.items():
        if key not in spec:
            raise SceneError(f"{where}: unknown key '{key}'{_closest(key, spec)}")
        if key in SUBTABLES:
            sub = _check(where, key, spec[key], value, scene_path, must_exist)
            out[key] = _validate_table(f"{where}.{key}", sub, SUBTABLES[key], scene_path,
                                       must_exist)
            for sk, sspec in SUBTABLES[key].items():
                if sspec.required and sk not in out[key]:
                    raise SceneError(f"{where}.{key}: missing key '{sk}'")
            continue
        out[key] = _check(where, key, spec[key], value, scene_path, must_exist)
    for key, kspec in spec.items():
        if key not in out:
            if kspec.required:
                raise SceneError(f"{where}: missing key '{key}' ({kspec.doc})")
            out[key] = kspec.default
    return out


def parse_scene(text: str, path: Path, must_exist: bool = True) -> Scene:
    """Validate TOML `text` (from `path`) into a `Scene`; raise `SceneError` naming the field."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    where0 = path.name
    data: dict[str, Any] = {}
    for section in raw:
        if section not in SCHEMA:
            raise SceneError(f"{where0}: unknown section [{section}]{_closest(section, SCHEMA)}")
    for section, spec in SCHEMA.items():
        where = f"{where0}: [{section}]"
        value = raw.get(section)
        if section in ARRAY_SECTIONS:
            items = value if value is not None else []
            if isinstance(items, dict):
                items = [items]
            if not isinstance(items, list):
                raise SceneError(f"{where}: expected [[{section}]] tables")
            data[section] = [
                _validate_table(f"{where0}: [[{section}]] #{n + 1}", item,
                                ARRAY_SCHEMA[section], path, must_exist)
                for n, item in enumerate(items)
            ]
            continue
        table = dict(value or {})
        chambers = table.pop("chamber", []) if section == "geometry" else None
        # the artist mesh may be generated by the make-artist stage: checked below
        data[section] = _validate_table(where, table, spec, path,
                                        must_exist and section != "geometry")
        if section == "geometry" and data[section]["solid"] is not None and must_exist \
                and not data[section]["solid"].exists():
            raise SceneError(f"{where}.solid: file not found: {table['solid']}")
        if section == "geometry":
            if isinstance(chambers, dict):
                chambers = [chambers]
            if not isinstance(chambers, list):
                raise SceneError(f"{where}.chamber: expected [[geometry.chamber]] tables")
            data[section]["chamber"] = [
                _validate_table(f"{where0}: [[geometry.chamber]] #{n + 1}", c,
                                ARRAY_SCHEMA["geometry.chamber"], path, must_exist)
                for n, c in enumerate(chambers)
            ]
    scene = Scene(path=path, data=data, declared={s for s, v in raw.items() if v not in ([], {})})
    _cross_checks(scene, where0, must_exist)
    return scene


def _cross_checks(scene: Scene, where: str, must_exist: bool) -> None:
    name = scene["scene"]["name"]
    if name is not None and (not name.strip() or name in (".", "..")
                             or any(c in name for c in "/\\")):
        raise SceneError(f"{where}: [scene].name: expected a plain folder name (it names "
                         f"out/<name>), got {name!r}")
    geo = scene["geometry"]
    sources = [k for k in ("artist", "solid", "pad_size_mm") if geo[k] is not None]
    if len(sources) > 1:
        raise SceneError(f"{where}: [geometry] give one of artist, solid, pad_size_mm, "
                         f"not {sources}")
    if geo["artist"] is not None and geo["generate_artist"]:
        pass  # the make-artist stage writes it
    elif geo["artist"] is not None and must_exist and not Path(geo["artist"]).exists():
        raise SceneError(f"{where}: [geometry].artist: file not found: {geo['artist']}")
    if geo["unit"] not in ("mm", "cm", "m"):
        raise SceneError(f"{where}: [geometry].unit: expected mm, cm or m, got {geo['unit']!r}")
    names = []
    for n, ch in enumerate(scene.chambers):
        if (ch["ellipsoid"] is None) == (ch["surface"] is None):
            raise SceneError(
                f"{where}: [[geometry.chamber]] #{n + 1} '{ch['name']}': give exactly one of "
                "ellipsoid or surface")
        if ch["ellipsoid"] is not None and min(ch["ellipsoid"]["radii_mm"]) <= 0:
            raise SceneError(f"{where}: [[geometry.chamber]] '{ch['name']}'.ellipsoid.radii_mm: "
                             "expected positive radii")
        if ch["name"] in names:
            raise SceneError(f"{where}: [[geometry.chamber]]: duplicate name '{ch['name']}'")
        names.append(ch["name"])
    mat = scene["material"]
    if mat["young_modulus_kpa"] <= 0:
        raise SceneError(f"{where}: [material].young_modulus_kpa: expected > 0, "
                         f"got {mat['young_modulus_kpa']}")
    if not -1.0 < mat["poisson_ratio"] < 0.5:
        raise SceneError(f"{where}: [material].poisson_ratio: expected -1 < nu < 0.5, "
                         f"got {mat['poisson_ratio']}")
    if mat["density_kg_m3"] < 0:
        raise SceneError(f"{where}: [material].density_kg_m3: expected >= 0")
    from fruitcli.fem.elements.lagrange import ELEMENTS
    from fruitcli.fem.materials.build import from_scene

    element = scene["fem"]["element"]
    if element not in ELEMENTS:
        near = _closest(element, ELEMENTS)
        raise SceneError(f"{where}: [fem].element: expected one of {', '.join(ELEMENTS)}, "
                         f"got {element!r}{near}")
    try:
        material = from_scene(mat)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    if material.model == "corotational" and element != "p1":
        raise SceneError(f"{where}: [material].model = \"corotational\" is the paper's SOFA "
                         f"model on linear tets: set [fem].element = \"p1\" (got "
                         f"{element!r}), or use model = \"neo-hookean\"")
    tr = scene["tracks"]
    if not 0 < tr["yarn_max_stretch"] < 1:
        raise SceneError(f"{where}: [tracks].yarn_max_stretch: expected a fraction 0 < value "
                         f"< 1 (0.25 = 25 %), got {tr['yarn_max_stretch']}")
    if tr["zigzag_pitch_mm"] <= 0:
        raise SceneError(f"{where}: [tracks].zigzag_pitch_mm: expected > 0 (mm), got "
                         f"{tr['zigzag_pitch_mm']}")
    if scene["mesh"]["size_mm"] <= 0:
        raise SceneError(f"{where}: [mesh].size_mm: expected > 0")
    red = scene["reduced"]
    rng = red["pressure_range_kpa"]
    if rng is not None and not rng[0] < rng[1]:
        raise SceneError(f"{where}: [reduced].pressure_range_kpa: expected [lo, hi] with "
                         f"lo < hi, got {rng}")
    if red["margin"] < 0 or red["points_per_axis"] < 2 or red["max_degree"] < 1 \
            or red["validation"] < 1:
        raise SceneError(f"{where}: [reduced]: expected margin >= 0, points_per_axis >= 2, "
                         "max_degree >= 1, validation >= 1")
    sol = scene["solver"]
    if sol["linear_solver"] not in LINEAR_SOLVERS:
        raise SceneError(f"{where}: [solver].linear_solver: expected one of "
                         f"{', '.join(LINEAR_SOLVERS)}, got {sol['linear_solver']!r}")
    if sol["tolerance"] <= 0 or sol["max_iterations"] < 1 or sol["jig_steps"] < 1 \
            or sol["first_steps"] < 1 or not sol["displacement_tolerance_mm"] >= 0:
        raise SceneError(f"{where}: [solver]: expected tolerance > 0, max_iterations >= 1, "
                         "jig_steps >= 1, first_steps >= 1, displacement_tolerance_mm >= 0")
    act = scene["actuation"]
    lengths = set()
    for key in ("pressure_kpa", "volume_growth_mm3"):
        table = act[key]
        if table is None:
            continue
        for cname, values in table.items():
            if cname not in names:
                hint = _closest(cname, names) if names else " (the scene has no chambers)"
                raise SceneError(f"{where}: [actuation].{key}.{cname}: no such chamber{hint}")
            ok = isinstance(values, list) and values and all(
                isinstance(v, NUM) and not isinstance(v, bool) and math.isfinite(v)
                for v in values)
            if not ok:
                raise SceneError(f"{where}: [actuation].{key}.{cname}: expected a non-empty "
                                 "list of numbers, one per state")
            lengths.add(len(values))
    if len(lengths) > 1:
        raise SceneError(f"{where}: [actuation]: every chamber needs the same number of states, "
                         f"got {sorted(lengths)}")
    if act["pressure_kpa"] and act["volume_growth_mm3"]:
        both = set(act["pressure_kpa"]) & set(act["volume_growth_mm3"])
        if both:
            raise SceneError(f"{where}: [actuation]: chamber {sorted(both)[0]} is controlled by "
                             "both pressure_kpa and volume_growth_mm3")
    for n, jig in enumerate(scene["jig"]):
        if jig["stiffness_n_per_mm"] <= 0:
            raise SceneError(f"{where}: [[jig]] #{n + 1}.stiffness_n_per_mm: expected > 0")
        if math.hypot(*jig["axis"]) == 0:
            raise SceneError(f"{where}: [[jig]] #{n + 1}.axis: expected a non-zero vector")
    grid = scene["grid"]
    count = grid["count"]
    if count is not None and not (len(count) == 2 and all(
            isinstance(c, int) and not isinstance(c, bool) and c > 0 for c in count)):
        raise SceneError(f"{where}: [grid].count: expected two positive integers [nx, ny], "
                         f"got {count}")
    if grid["spacing_x_mm"] <= 0 or grid["spacing_y_mm"] <= 0:
        raise SceneError(f"{where}: [grid]: expected spacing_x_mm and spacing_y_mm > 0")
    skin = scene["skin"]
    for key in ("contact_counts", "gap_decay_mm"):
        if skin[key] <= 0:
            raise SceneError(f"{where}: [skin].{key}: expected > 0, got {skin[key]}")
    if not 0 <= skin["gain_spread"] < 1:
        raise SceneError(f"{where}: [skin].gain_spread: expected 0 <= spread < 1, "
                         f"got {skin['gain_spread']}")
    if skin["taxel_gain"] is not None and skin["gain_spread"] > 0:
        raise SceneError(f"{where}: [skin].gain_spread: expected 0 with taxel_gain (the gains "
                         f"are measured, not drawn), got {skin['gain_spread']}")
    feet = skin["footprint_sigma_mm"] or {}
    for ind, sigma in feet.items():
        if isinstance(sigma, bool) or not isinstance(sigma, NUM) or not sigma > 0 \
                or not math.isfinite(sigma):
            raise SceneError(f"{where}: [skin].footprint_sigma_mm.{ind}: expected a width > 0 "
                             f"mm, got {sigma!r}")
    if scene.has("bench"):
        bench = scene["bench"]
        # the paper's indenters (fruitcli.sensing.skin.forward) and those [skin] gives a width
        names = tuple(dict.fromkeys(["small", "medium", *feet]))
        if not bench["indenters"] or any(i not in names for i in bench["indenters"]):
            raise SceneError(f"{where}: [bench].indenters: expected a non-empty list of "
                             f"{', '.join(names)}, got {bench['indenters']}")
        if bench["step_mm"] <= 0:
            raise SceneError(f"{where}: [bench].step_mm: expected > 0, got {bench['step_mm']}")
        ref = bench["reference_length_mm"]
        if ref is not None and ref <= 0:
            raise SceneError(f"{where}: [bench].reference_length_mm: expected > 0, got {ref}")
        if bench["baseline_frames"] < 1:
            raise SceneError(f"{where}: [bench].baseline_frames: expected >= 1")
    if scene.has("printer"):
        _check_printer(scene["printer"], where)
    period = scene["actuation"]["period_s"]
    if period is not None and period <= 0:
        raise SceneError(f"{where}: [actuation].period_s: expected > 0, got {period}")
    if scene["board"]["format"] not in ("auto", "ascii", "binary"):
        raise SceneError(f"{where}: [board].format: expected auto, ascii or binary, got "
                         f"{scene['board']['format']!r}")
    det = scene["detection"]
    if det["threshold_counts"] <= 0:
        raise SceneError(f"{where}: [detection].threshold_counts: expected > 0")
    if det["baseline_frames"] < 1:
        raise SceneError(f"{where}: [detection].baseline_frames: expected >= 1")
    if det["project"] not in ("none", "surface"):
        raise SceneError(f"{where}: [detection].project: expected none or surface, "
                         f"got {det['project']!r}")
    if det["divide_by_gain"] and skin["taxel_gain"] is None:
        raise SceneError(f"{where}: [detection].divide_by_gain: needs the gains, [skin]."
                         "taxel_gain = \"gains.csv\" (written by fruit calibrate)")
    if scene["frames"]["model"] not in ("reduced", "full"):
        raise SceneError(f"{where}: [frames].model: expected reduced or full, "
                         f"got {scene['frames']['model']!r}")
    if det["method"] not in ("n9", "n9_floor", "peaks", "fit2"):
        raise SceneError(f"{where}: [detection].method: expected n9, n9_floor, peaks or fit2, "
                         f"got {det['method']!r}")
    from fruitcli.evaluation.register import METHODS

    for what, reg in ([("[bench]", scene["bench"]["register"])]
                      + [(f"[[evaluate]] '{ev['label']}'", ev["register"])
                         for ev in scene["evaluate"]]):
        if reg not in METHODS:
            raise SceneError(f"{where}: {what}.register: expected one of {', '.join(METHODS)}, "
                             f"got {reg!r}")
    for ev in scene["evaluate"]:
        ref = ev["reference_length_mm"]
        if ref is not None and ref <= 0:
            raise SceneError(f"{where}: [[evaluate]] '{ev['label']}'.reference_length_mm: "
                             "expected > 0")


def _check_printer(pr: dict, where: str) -> None:
    """[printer] values that cannot drive a bench: one line naming the key."""
    def fail(key: str, expected: str):
        raise SceneError(f"{where}: [printer].{key}: expected {expected}, got {pr[key]!r}")

    if pr["model_origin_mm"] is None:
        raise SceneError(f"{where}: [printer]: missing key 'model_origin_mm' (where the "
                         "model's origin is, printer coordinates, mm)")
    if pr["safe_height_mm"] <= 0:
        fail("safe_height_mm", "> 0 (mm above the model's highest point; lower would "
             "drag the tip through the model)")
    if not 0 < pr["step_mm"] <= 1.0:
        fail("step_mm", "0 < step <= 1 mm")
    if pr["feed_mm_min"] <= 0:
        fail("feed_mm_min", "> 0 mm/min")
    if pr["max_press_mm"] <= 0:
        fail("max_press_mm", "> 0 mm")
    if pr["baud"] <= 0:
        fail("baud", "> 0")
    if pr["timeout_s"] <= 0:
        fail("timeout_s", "> 0 s")
    bed = pr["bed_mm"]
    if any(bed[a] >= bed[a + 3] for a in range(3)):
        fail("bed_mm", "[xmin, ymin, zmin, xmax, ymax, zmax] with min < max")


def load_skin_table(path: str | Path) -> dict:
    """The validated [skin] table of a file that holds only one (`fruit calibrate`'s
    skin.toml); its paths are resolved against that file's folder."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read: {exc}") from None
    skin = parse_scene(text, path)
    other = sorted(skin.declared - {"skin"})
    if "skin" not in skin.declared or other:
        raise SceneError(f"{path.name}: expected only a [skin] table"
                         + (f", found [{'], ['.join(other)}]" if other else ", found none"))
    return skin["skin"]


def n_states(scene: Scene) -> int:
    """Number of actuation states (1 when the scene has no [actuation])."""
    act = scene["actuation"]
    for key in ("pressure_kpa", "volume_growth_mm3"):
        if act[key]:
            return len(next(iter(act[key].values())))
    return 1


def has_deformation(scene: Scene) -> bool:
    """True when something moves the body: non-zero actuation or a jig."""
    act = scene["actuation"]
    for key in ("pressure_kpa", "volume_growth_mm3"):
        if act[key] and any(v != 0 for vals in act[key].values() for v in vals):
            return True
    return bool(scene["jig"])


def load_scene(path: str | Path, must_exist: bool = True) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    if not path.exists():
        raise SceneError(f"{path}: scene file not found")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read scene: {exc}") from None
    return parse_scene(text, path.resolve(), must_exist=must_exist)
