"""Scene files: one TOML per experiment, validated strictly against `SCHEMA`.

Every user-facing key carries its unit in its name (`young_modulus_kpa`,
`spacing_x_mm`). Relative paths are resolved against the scene file's folder,
then against the project root (the nearest parent holding `pyproject.toml`).

The schema is the one definition of the keys: their kinds, defaults, and the choices,
ranges or conditions a value must meet (checked by one validator; `_cross_checks` holds
only the checks across keys). Each section becomes a frozen record generated from it
(`scene.fem.element`, `scene.skin.contact_counts`), each array of tables a tuple of
records (`scene.fixed`, `scene.chambers[0].name`); a key the schema lacks is an
AttributeError naming the closest one. `Scene.values` gives a section as plain data (stage
hashes), `Scene.with_values` a checked copy with values changed (studies).
"""

from __future__ import annotations

import difflib
import functools
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass, make_dataclass, replace
from pathlib import Path
from typing import Any

from fruitcli.errors import FruitError, SceneError, echo
from fruitcli.evaluation.registrations import REGISTRATIONS
from fruitcli.fem.elements.families import ELEMENT_FAMILIES
from fruitcli.fem.materials.build import from_scene
from fruitcli.fem.materials.models import MATERIAL_MODELS
from fruitcli.fem.solver.solvers import LINEAR_SOLVERS
from fruitcli.fsutil import slug
from fruitcli.geometry.mesh.units import MAX_EXTENT_MM, UNIT_TO_MM
from fruitcli.sensing.detection.methods import METHODS as DETECTION_METHODS
from fruitcli.sensing.detection.methods import method_help
from fruitcli.sensing.frames.formats import BOARD_COLS, BOARD_FORMATS, BOARD_ROWS
from fruitcli.sensing.skin.models import SKIN_MODELS

NUM = (int, float)
MAX_MODEL_FRAMES = 60  # a second at the board's 60 frames/s


@dataclass(frozen=True)
class Key:
    """One scene key: its accepted type, default (None: optional), meaning, and the
    values it accepts beyond its type (`choices`, a range [`min`, `max`], `valid`).

    `expected` is the error's "expected ..." text when the derived one ("one of a, b",
    "> 0", "0 <= value < 1") says too little. A range applies to a number, to each
    number of a vector, and to each value of a table."""

    kind: str  # "str", "path", "num", "int", "bool", "vec2", "vec3", "box", "list", "table",
    # "range" (a number or [lo, hi])
    default: Any = None
    doc: str = ""
    required: bool = False
    choices: tuple[str, ...] | None = None
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = False
    max_exclusive: bool = False
    valid: Callable[[Any], bool] | None = None
    expected: str | None = None
    max_items: int | None = None  # most entries of a list or table
    unbounded: str = ""  # why a number has no declared min or max (where it is checked)

    def in_range(self, value: float) -> bool:
        """True when `value` lies in [min, max] (ends excluded as declared)."""
        if self.min is not None and (value <= self.min if self.min_exclusive else value < self.min):
            return False
        return self.max is None or (value < self.max if self.max_exclusive else value <= self.max)

    def expectation(self, value: Any = None) -> str:
        """What a valid value is, for error messages; given the number refused, the side of
        the range it broke (a number too small: the lower bound only)."""
        hi = "" if self.max is None else f" {'<' if self.max_exclusive else '<='} {self.max:g}"
        above = isinstance(value, NUM) and self.max is not None and not self.in_range(value)
        above = above and (value >= self.max if self.max_exclusive else value > self.max)
        if self.expected is not None and self.max is not None:
            forms = {f"{self.max:g}", f"{self.max:,}"}
            if float(self.max).is_integer():
                forms.add(f"{int(self.max):,}")
            # the text already gives an upper end: the max itself, or "lo < value < hi"
            said = any(form in self.expected for form in forms) or self.expected.count("<") >= 2
            return f"{self.expected} and{hi}" if above and not said else self.expected
        if self.expected is not None:
            return self.expected
        if self.choices is not None:
            return f"one of {', '.join(self.choices)}"
        lo = "" if self.min is None else f"{self.min:g} {'<' if self.min_exclusive else '<='} "
        if isinstance(value, NUM) and not above:
            hi = ""
        if lo and hi:
            return f"{lo}value{hi}"
        if lo:
            return f"{'>' if self.min_exclusive else '>='} {self.min:g}"
        return f"{'<' if self.max_exclusive else '<='} {self.max:g}"


POSITIVE = {"min": 0.0, "min_exclusive": True}
SEED = {"min": 0, "max": 2**63 - 1, "expected": "a seed 0 <= seed < 2^63"}
MAX_FACES = 10_000_000
"""Most triangles a reduced surface may ask for (a 10 M triangle surface is ~1 GB)."""
OPEN_FRACTION = {"min": 0.0, "max": 1.0, "min_exclusive": True, "max_exclusive": True}
LENGTH = {"min": 0.0, "max": MAX_EXTENT_MM}
"""A length in mm: no longer than the largest body (`geometry.mesh.load.MAX_EXTENT_MM`)."""
POSITIVE_LENGTH = {**POSITIVE, "max": MAX_EXTENT_MM}
FAR_MM = 1e6
"""Farthest coordinate (mm) of a point or box: any body (at most MAX_EXTENT_MM across, near
the origin) and any box drawn around it fit within it."""
COORDINATE = {"min": -FAR_MM, "max": FAR_MM}
ANGLE = {"min": -360.0, "max": 360.0}
MAX_COUNTS = 65535
"""Largest CDC count a board reports (16-bit)."""
COUNTS = {"min": 0.0, "max": MAX_COUNTS}
MODULUS_KPA = 1e9
"""Largest modulus (kPa): 1 TPa, stiffer than any solid."""
PRESSURE_KPA = 1e5
"""Largest chamber pressure, either sign (kPa): 100 MPa, far past any silicone's burst."""
MAX_SECONDS = 1e6
"""Longest time budget or period (s): about 11 days."""
MAX_FRAMES = 10**8
"""Most frames a key may ask for (a bench's idle frames are also sized by `memory`)."""
MAX_STATES = 10_000
"""Most actuation states (each one a quasi-static solve)."""
MAX_ITEMS = 1000
"""Most tables in an array ([[fixed]], [[geometry.chamber]], ...) and entries of a list."""
MAX_INDENTERS = 64
"""Most indenters a bench may replay, or [skin] may give a width."""


def _plain_folder_name(name: str) -> bool:
    return bool(name.strip()) and name not in (".", "..") and not any(c in name for c in "/\\")


def _two_positive_ints(count: list) -> bool:
    return len(count) == 2 and all(
        isinstance(c, int) and not isinstance(c, bool) and 0 < c <= MAX_GRID_LINES for c in count
    )


MAX_GRID_LINES = 10_000
"""Most taxels along one axis of a flat pad's grid (its rows are also sized by `memory`)."""


def _increasing_pair(pair: list[float]) -> bool:
    return pair[0] < pair[1]


def _nonzero_vector(v: list[float]) -> bool:
    return math.hypot(*v) != 0


def _gap_table(gaps) -> bool:
    """At least two finite gaps (mm), increasing from 0 (contact)."""
    return (
        isinstance(gaps, (list, tuple))
        and len(gaps) >= 2
        and all(_number(g) and g <= MAX_EXTENT_MM for g in gaps)
        and gaps[0] == 0
        and all(b > a for a, b in zip(gaps[:-1], gaps[1:], strict=False))
    )


def _nonempty_box(box: list[float]) -> bool:
    return all(box[a] < box[a + 3] for a in range(3))


# Sections that are tables (one per scene).
SCHEMA: dict[str, dict[str, Key]] = {
    "scene": {
        "name": Key(
            "str",
            None,
            "scene name (default: file stem)",
            valid=_plain_folder_name,
            expected="a plain folder name (it names out/<name>)",
        ),
        "description": Key("str", "", "free text"),
        "configuration": Key("str", "Rest", "configuration label in tables (Rest, Deformed, ...)"),
    },
    "geometry": {
        "artist": Key("path", None, "artist's high-resolution closed mesh (STL/OBJ/PLY)"),
        "generate_artist": Key("bool", False, "write the default fruit to `artist` if missing"),
        "unit": Key(
            "str",
            "mm",
            "unit of the mesh files (artist, solid, surface): mm, cm, m",
            choices=tuple(UNIT_TO_MM),
        ),
        "fit_mm": Key(
            "num",
            None,
            "scale the artist mesh (after unit) so that its largest "
            "extent is this (mm); chambers stay as given (mm)",
            **POSITIVE_LENGTH,
        ),
        "solid": Key("path", None, "closed surface used as the FEM body as is ([geometry].unit)"),
        "pad_size_mm": Key(
            "vec3",
            None,
            "flat pad [x, y, thickness] in mm, centred at x=y=0",
            **POSITIVE_LENGTH,
            expected=f"[x, y, thickness] each > 0 and <= {MAX_EXTENT_MM:g} mm",
        ),
        "chamber": Key(
            "list", [], "pneumatic chambers ([[geometry.chamber]])", max_items=MAX_ITEMS
        ),
    },
    "tracks": {
        "cover_mm": Key(
            "num",
            2.0,
            "inward offset for the cover layer (mm)",
            **LENGTH,
            expected="a thickness >= 0 mm",
        ),
        "faces": Key(
            "int",
            5000,
            "target triangle count of the reduced surface",
            min=4,
            max=MAX_FACES,
            expected=f"a triangle count 4 <= faces <= {MAX_FACES:,}",
        ),
        "track_radius_mm": Key(
            "num",
            0.6,
            "radius of the yarn tubes (mm)",
            **POSITIVE_LENGTH,
            expected="a radius > 0 mm",
        ),
        "split_z_mm": Key(
            "num", None, "casting split plane height (mm; default: automatic)", **COORDINATE
        ),
        "yarn_max_stretch": Key(
            "num",
            0.25,
            "warn when a track stretches more than this "
            "fraction (yarn limit 0.3 minus a 0.05 margin)",
            **OPEN_FRACTION,
            expected="a fraction 0 < value < 1 (0.25 = 25 %)",
        ),
        "zigzag_pitch_mm": Key(
            "num",
            4.0,
            "zig-zag pitch of the sewn yarn (mm): the warnings' "
            "amplitude and the length of the local stretch",
            **POSITIVE_LENGTH,
            expected="> 0 (mm)",
        ),
        "file": Key(
            "path",
            None,
            "track centre lines given directly (track,axis,index,point,"
            "x_mm,y_mm,z_mm; default: make-tracks' tracks.csv)",
        ),
    },
    "grid": {
        "spacing_x_mm": Key(
            "num", 16.0, "distance between x = const planes (mm)", **POSITIVE_LENGTH
        ),
        "spacing_y_mm": Key(
            "num", 12.0, "distance between y = const planes (mm)", **POSITIVE_LENGTH
        ),
        "origin_mm": Key(
            "vec2", None, "[x0, y0] of plane (0, 0) (mm; default: centred)", **COORDINATE
        ),
        "count": Key(
            "list",
            None,
            "[nx, ny] taxels on a flat pad",
            valid=_two_positive_ints,
            expected=f"two positive integers [nx, ny], each at most {MAX_GRID_LINES:,}",
            max_items=2,
        ),
        "taxels": Key("path", None, "taxel CSV given directly (id,i,j,x_mm,y_mm,z_mm)"),
    },
    "mold": {
        "wall_mm": Key(
            "num",
            4.0,
            "mold wall thickness (mm, at least 1)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "clearance_mm": Key(
            "num",
            0.3,
            "gap between keys and sockets, pins and holes (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "key_radius_mm": Key(
            "num",
            3.0,
            "radius of the registration keys (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "pour_diameter_mm": Key(
            "num",
            8.0,
            "pour hole diameter (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "vent_diameter_mm": Key(
            "num",
            2.0,
            "vent diameter (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "pin_diameter_mm": Key(
            "num",
            3.0,
            "diameter of the pins holding chamber cores (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "vents": Key(
            "int",
            4,
            "vents at the cavity's highest points besides the pour hole",
            max=16,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
    },
    "mesh": {
        "size_mm": Key("num", 3.0, "target tetrahedron edge length (mm)", **POSITIVE_LENGTH),
        "min_size_mm": Key(
            "num", None, "smallest edge near chambers and taxels (mm)", **POSITIVE_LENGTH
        ),
        "time_limit_s": Key(
            "num",
            120.0,
            "gmsh is killed after this many seconds",
            **POSITIVE,
            max=MAX_SECONDS,
            expected="a time limit > 0 s",
        ),
        "min_quality": Key(
            "num",
            0.05,
            "refuse meshes whose worst SICN is below this",
            min=-1.0,
            max=1.0,
            expected="a SICN -1 <= value <= 1",
        ),
    },
    "fem": {
        "element": Key(
            "str",
            "p2",
            "p2 (quadratic tets, P2/P0 mean dilatation: no locking), "
            "p2-pure (quadratic, displacement only) or p1 (linear tets, the "
            "paper's SOFA element)",
            choices=tuple(ELEMENT_FAMILIES),
        ),
    },
    "material": {
        "model": Key(
            "str",
            "neo-hookean",
            "neo-hookean (from E and nu), yeoh (c10_kpa, "
            "c20_kpa, c30_kpa) or corotational (the paper's SOFA Hooke, p1 only)",
            choices=tuple(MATERIAL_MODELS),
        ),
        "c10_kpa": Key(
            "num",
            None,
            "yeoh: C10 (kPa; the shear modulus is 2 C10)",
            max=MODULUS_KPA,
            unbounded="its lower bound is the material's (materials.build.from_scene)",
        ),
        "c20_kpa": Key("num", 0.0, "yeoh: C20 (kPa)", min=-MODULUS_KPA, max=MODULUS_KPA),
        "c30_kpa": Key("num", 0.0, "yeoh: C30 (kPa)", min=-MODULUS_KPA, max=MODULUS_KPA),
        "bulk_modulus_kpa": Key(
            "num",
            None,
            "bulk modulus kappa (kPa; default from E, nu)",
            max=MODULUS_KPA,
            unbounded="its lower bound is the material's (materials.build.from_scene)",
        ),
        "young_modulus_kpa": Key(
            "num", 100.0, "Young's modulus E (kPa)", **POSITIVE, max=MODULUS_KPA
        ),
        "poisson_ratio": Key(
            "num",
            0.45,
            "Poisson's ratio nu (-1 < nu < 0.5)",
            min=-1.0,
            max=0.5,
            min_exclusive=True,
            max_exclusive=True,
            expected="-1 < nu < 0.5",
        ),
        "density_kg_m3": Key("num", 1070.0, "density (kg/m^3)", min=0.0, max=1e5),
    },
    "gravity": {
        "vector_m_s2": Key(
            "vec3",
            [0.0, 0.0, -9.81],
            "gravity acceleration (m/s^2); an empty [gravity] means this default",
            min=-1e4,
            max=1e4,
        ),
    },
    "fixed": {},  # array of tables, see ARRAY_SCHEMA
    "jig": {},
    "actuation": {
        "pressure_kpa": Key(
            "table",
            None,
            "per chamber: one pressure per state (kPa)",
            min=-PRESSURE_KPA,
            max=PRESSURE_KPA,
            expected=f"pressures -{PRESSURE_KPA:g} <= p <= {PRESSURE_KPA:g} kPa, one per state",
            max_items=MAX_ITEMS,
        ),
        "volume_growth_mm3": Key(
            "table",
            None,
            "per chamber: one volume growth per state (mm^3)",
            min=-(MAX_EXTENT_MM**3),
            max=MAX_EXTENT_MM**3,
            expected=f"volume growths of at most {MAX_EXTENT_MM**3:g} mm^3 either way, one per "
            "state",
            max_items=MAX_ITEMS,
        ),
        "period_s": Key(
            "num",
            None,
            "duration of one cycle of the states (s), for animations",
            **POSITIVE,
            max=MAX_SECONDS,
        ),
    },
    "solver": {
        "tolerance": Key(
            "num",
            1e-6,
            "Newton stops when |residual| <= tolerance * |load|",
            **OPEN_FRACTION,
            expected="0 < tolerance < 1 (a residual relative to the load)",
        ),
        "displacement_tolerance_mm": Key(
            "num",
            1e-4,
            "... or when the kept factor estimates "
            "the correction left within half this (mm; 0 = "
            "off)",
            **LENGTH,
        ),
        "max_iterations": Key("int", 25, "Newton iterations per load step", min=1, max=1000),
        "max_subdivisions": Key("int", 6, "times a failing load step may be halved", min=0, max=30),
        "linear_solver": Key(
            "str",
            "pcg",
            "pcg (CG on a kept Cholesky), direct or jacobi",
            choices=tuple(LINEAR_SOLVERS),
        ),
        "jig_steps": Key("int", 1, "load steps to apply the jig rotation", min=1, max=10_000),
        "first_steps": Key(
            "int",
            4,
            "load steps of the state solved from rest (hyperelastic models)",
            min=1,
            max=10_000,
        ),
        "max_seconds": Key(
            "num",
            300.0,
            "time budget of one state (s); past it the state fails, saying how far its load got",
            **POSITIVE,
            max=MAX_SECONDS,
            expected="a time budget > 0 s",
        ),
    },
    "reduced": {  # the reduced model of the live loop (fruitcli.fem.reduced.build)
        "pressure_range_kpa": Key(
            "vec2",
            None,
            "[lo, hi] kPa for every chamber (default: "
            "each chamber's [actuation] pressures plus the margin)",
            valid=_increasing_pair,
            min=-PRESSURE_KPA,
            max=PRESSURE_KPA,
            expected=f"[lo, hi] with -{PRESSURE_KPA:g} <= lo < hi <= {PRESSURE_KPA:g}",
        ),
        "margin": Key(
            "num",
            0.1,
            "fraction of each chamber's [actuation] span added on either side",
            min=0.0,
            max=10.0,
        ),
        "points_per_axis": Key(
            "int", 5, "Chebyshev-Lobatto full solves per chamber", min=2, max=64
        ),
        "max_degree": Key(
            "int", 4, "highest total degree tried (chosen by leave-one-out)", min=1, max=32
        ),
        "validation": Key(
            "int", 50, "held-out random pressure vectors solved in full", min=1, max=100_000
        ),
        "seed": Key("int", 0, "seed of the held-out pressure vectors", **SEED),
    },
    "board": {
        "rows": Key(
            "int",
            BOARD_ROWS,
            "frame rows (Tx lines of the FocalTech FT5316, MuCa)",
            min=1,
            max=1024,
        ),
        "cols": Key("int", BOARD_COLS, "frame columns (Rx lines)", min=1, max=1024),
        "offset_i": Key("int", 0, "frame row of taxel i = 0", min=0, max=1023),
        "offset_j": Key("int", 0, "frame column of taxel j = 0", min=0, max=1023),
        "flip_i": Key("bool", False, "taxel i counts down the frame rows"),
        "flip_j": Key("bool", False, "taxel j counts down the frame columns"),
        "transpose": Key("bool", False, "taxel i runs along frame columns"),
        "format": Key(
            "str",
            "auto",
            "frames on the port and in raw captures: auto, ascii "
            "(stock Muca_Raw) or binary (stock SendRawByte packets)",
            choices=("auto", *BOARD_FORMATS),
        ),
    },
    "frames": {
        "recording": Key("path", None, "recorded frames (.npz or MuCa ASCII log)"),
        "model": Key(
            "str",
            "reduced",
            "a recording with chamber pressures: reduced (taxels "
            "from the reduced model at each frame's pressures) or full (along the "
            "simulated states)",
            choices=("reduced", "full"),
        ),
    },
    "detection": {
        "threshold_counts": Key(
            "num",
            20.0,
            "touch threshold on v = C - C0 (counts)",
            **POSITIVE,
            max=MAX_COUNTS,
        ),
        "baseline_frames": Key(
            "int", 10, "frames averaged into the baseline C0", min=1, max=MAX_FRAMES
        ),
        "method": Key(
            "str",
            "n9",
            "how touches are found and placed: " + method_help(),
            choices=tuple(DETECTION_METHODS),
        ),
        "model_frames": Key(
            "int",
            1,
            "frames whose mean activation the model method fits: a touch's frame and "
            "those just before it (1: the frame alone); a still touch's noise falls by "
            "its square root, a moving one lags by half as many frames",
            min=1,
            max=MAX_MODEL_FRAMES,
            expected="frames >= 1",
        ),
        "noise_floor_counts": Key(
            "num",
            0.0,
            "subtracted from v before weighting (n9_floor)",
            **COUNTS,
            expected="counts >= 0",
        ),
        "hysteresis_counts": Key(
            "num",
            0.0,
            "touch ends below threshold - hysteresis",
            **COUNTS,
            expected="counts >= 0",
        ),
        "debounce_frames": Key(
            "int",
            0,
            "frames above threshold before a touch starts",
            min=0,
            max=MAX_FRAMES,
            expected="frames >= 0",
        ),
        "drift_rate": Key(
            "num",
            0.0,
            "baseline tracking rate per untouched frame (0: off)",
            min=0.0,
            max=1.0,
            expected="a rate per frame 0 <= rate <= 1",
        ),
        "track_gate_mm": Key(
            "num",
            0.0,
            "touch IDs across frames within this distance (0: off)",
            **LENGTH,
            expected="a distance >= 0 mm",
        ),
        "project": Key(
            "str",
            "none",
            "none (the N9 average of the 3D taxels, the paper) or "
            "surface (moved to the nearest point of the body)",
            choices=("none", "surface"),
        ),
        "divide_by_gain": Key(
            "bool",
            False,
            "divide each taxel's activation by its gain in "
            "[skin].taxel_gain before detection (threshold, maxima and N9 "
            "weights on the divided v; off: the paper)",
        ),
        "hovers": Key("bool", False, "report hovers (below the touch threshold) as kind hover"),
        "hover_threshold_counts": Key(
            "num",
            None,
            "hover threshold (counts; default 8 x the [skin] noise std); below threshold_counts",
            **POSITIVE,
            max=MAX_COUNTS,
        ),
        "hover_hysteresis_counts": Key(
            "num",
            None,
            "a hover ends below its threshold minus "
            "this (counts; default 3 x the [skin] noise std)",
            **COUNTS,
        ),
        "footprint": Key(
            "str",
            None,
            "[skin].footprint_sigma_mm entry heights and strengths "
            "assume (default: the only one, else small)",
        ),
    },
    "bench": {
        "indenters": Key(
            "list",
            ["small", "medium"],
            "indenters to replay: small, medium",
            max_items=MAX_INDENTERS,
        ),
        "samples": Key("str", "quarter", "quarter (a quarter taxel off the grid) or a CSV path"),
        "state": Key("int", 0, "FEM state the bench runs on", min=0, max=MAX_STATES - 1),
        "step_mm": Key(
            "num",
            0.1,
            "indenter descent step (mm; its frames are sized by `memory` first)",
            **POSITIVE,
            max=7.0,
        ),
        "seed": Key("int", 0, "seed of the noise", **SEED),
        "baseline_frames": Key(
            "int", 10, "idle frames recorded before each descent", min=1, max=MAX_FRAMES
        ),
        "reference_length_mm": Key(
            "num", None, "for % errors (default: largest truth span)", **POSITIVE_LENGTH
        ),
        "register": Key(
            "str",
            "none",
            "registration of the bench rows: none, translation, "
            "rigid or similarity (see [[evaluate]].register)",
            choices=tuple(REGISTRATIONS),
        ),
    },
    "skin": {  # the skin's forward model (fruitcli.sensing.skin.forward); defaults: its assumptions
        "footprint_sigma_mm": Key(
            "table",
            None,
            "per indenter: lateral Gaussian width (mm); default small 6.18, medium 7.21",
            **POSITIVE_LENGTH,
            expected="a width > 0 mm",
            max_items=MAX_INDENTERS,
        ),
        "contact_counts": Key(
            "num",
            60.0,
            "activation of the taxel under the indenter at contact (counts)",
            **POSITIVE,
            max=MAX_COUNTS,
        ),
        "gap_decay_mm": Key(
            "num", 2.0, "activation falls as exp(-gap / gap_decay_mm) (mm)", **POSITIVE_LENGTH
        ),
        "gain_spread": Key(
            "num",
            0.0,
            "taxel gains drawn uniformly in 1 +- spread (seeded)",
            min=0.0,
            max=1.0,
            max_exclusive=True,
            expected="0 <= spread < 1",
        ),
        "noise_std_counts": Key(
            "range",
            [0.5, 1.85],
            "noise std (counts): one value, or [lo, hi] drawn per taxel (seeded)",
            max=MAX_COUNTS,
            expected=f"a std 0 <= value <= {MAX_COUNTS} counts, or [lo, hi] within it",
            unbounded="its lower bound 0 is its kind's (`range`)",
        ),
        "taxel_gain": Key(
            "path",
            None,
            "CSV (id, gain) of measured taxel gains, e.g. fruit "
            "calibrate's gains.csv (with gain_spread = 0)",
        ),
        # the electrostatic crossing (fruitcli.electrostatics.crossing, `fruit skin`)
        "model": Key(
            "str",
            "gaussian",
            "gaussian (the assumed footprint, gap decay and strain "
            "gain above) or electrostatic (the crossing's field)",
            choices=tuple(SKIN_MODELS),
        ),
        "permittivity": Key(
            "num",
            2.8,
            "relative permittivity of the silicone (Ecoflex: about "
            "2.8, as quoted for platinum-cure silicones at low "
            "frequency, 2.5-3)",
            min=1.0,
            max=1e4,
            expected="a relative permittivity >= 1 (Ecoflex: about 2.8)",
        ),
        "yarn_radius_mm": Key(
            "num",
            None,
            "radius of the conductive yarn (mm; default [tracks].track_radius_mm)",
            **POSITIVE_LENGTH,
            expected="> 0 (mm)",
        ),
        "insulation_mm": Key(
            "num",
            0.1,
            "insulating layer between Tx and Rx where they cross (mm)",
            **POSITIVE_LENGTH,
            expected="> 0 (mm; the yarns must not touch)",
        ),
        "counts_per_ff": Key(
            "num",
            None,
            "CDC counts per fF of the electrostatic skin (default: fitted so the crossing "
            "bent as the paper's pad shifts 10 counts; fruit calibrate fits it to a "
            "bench recording)",
            **POSITIVE,
            max=1e6,
            expected="> 0 (counts per fF)",
        ),
        "gaps_mm": Key(
            "list",
            [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0],
            "object gaps of the crossing's table (mm, increasing from 0: contact)",
            valid=_gap_table,
            expected=f"at least two gaps in mm, increasing, starting at 0 (contact), "
            f"at most {MAX_EXTENT_MM:g}",
            max_items=MAX_ITEMS,
        ),
    },
    "printer": {  # the real bench: a Marlin printer with an indenter (fruit bench --printer)
        "model_origin_mm": Key(
            "vec3",
            None,
            "where the model's origin is, printer coordinates (mm; required with [printer])",
            **COORDINATE,
        ),
        "rotate_z_deg": Key("num", 0.0, "model rotated about z on the bed (degrees)", **ANGLE),
        "safe_height_mm": Key(
            "num",
            20.0,
            "tip height above the model's highest point between samples (mm)",
            **POSITIVE_LENGTH,
            expected="> 0 (mm above the model's highest point; lower "
            "would drag the tip through the model)",
        ),
        "step_mm": Key(
            "num",
            0.1,
            "descent step (mm, 0 < step <= 1)",
            **POSITIVE,
            max=1.0,
            expected="0 < step <= 1 mm",
        ),
        "feed_mm_min": Key(
            "num",
            600.0,
            "feed rate of every move (mm/min)",
            **POSITIVE,
            max=1e6,
            expected="> 0 mm/min",
        ),
        "max_press_mm": Key(
            "num",
            1.5,
            "deepest press below the expected surface before the sample is an error (mm)",
            **POSITIVE_LENGTH,
            expected="> 0 mm",
        ),
        "bed_mm": Key(
            "box",
            [0.0, 0.0, 0.0, 220.0, 220.0, 250.0],
            "reachable volume [xmin, ymin, zmin, xmax, ymax, zmax], printer coordinates (mm)",
            valid=_nonempty_box,
            **COORDINATE,
            expected=f"[xmin, ymin, zmin, xmax, ymax, zmax] with min < max, within +-{FAR_MM:g} mm",
        ),
        "baud": Key("int", 115200, "the printer's serial baud rate", **POSITIVE, max=10**8),
        "home": Key("bool", False, "send G28 (home all axes) first"),
        "timeout_s": Key(
            "num",
            30.0,
            "longest wait for an 'ok' (s; busy lines extend it)",
            **POSITIVE,
            max=MAX_SECONDS,
            expected="> 0 s",
        ),
    },
    "sensitivity": {
        "noise_frames": Key(
            "int",
            300,
            "frames at rest for the per-taxel noise std",
            min=2,
            max=MAX_FRAMES,
            expected="frames >= 2 (a standard deviation needs two)",
        ),
        "animation_frames": Key(
            "int",
            60,
            "frames over one animation cycle",
            min=1,
            max=100_000,
            expected="frames >= 1",
        ),
    },
    "report": {
        "paper_rows": Key(
            "list", [], "paper Table I rows to show next to ours", max_items=MAX_ITEMS
        ),
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
        "box_mm": Key(
            "box",
            None,
            "[xmin, ymin, zmin, xmax, ymax, zmax] (mm)",
            required=True,
            **COORDINATE,
        ),
        "displacement_mm": Key(
            "vec3",
            None,
            "the clamp moved by [dx, dy, dz] (mm), ramped "
            "with the load steps (default: held at rest)",
            min=-MAX_EXTENT_MM,
            max=MAX_EXTENT_MM,
        ),
    },
    "jig": {
        "region_box_mm": Key(
            "box", None, "nodes pulled by the springs (mm)", required=True, **COORDINATE
        ),
        "rotate_deg": Key("num", 0.0, "rotation of the target about `axis` (degrees)", **ANGLE),
        "axis": Key(
            "vec3",
            [0.0, 0.0, 1.0],
            "rotation axis",
            valid=_nonzero_vector,
            **COORDINATE,
            expected=f"a non-zero vector, each component within +-{FAR_MM:g}",
        ),
        "pivot_mm": Key("vec3", [0.0, 0.0, 0.0], "point on the rotation axis (mm)", **COORDINATE),
        "translate_mm": Key(
            "vec3", [0.0, 0.0, 0.0], "translation after the rotation (mm)", **COORDINATE
        ),
        "stiffness_n_per_mm": Key(
            "num", 10.0, "spring stiffness per node (N/mm)", **POSITIVE, max=1e9
        ),
    },
    "evaluate": {
        "label": Key("str", None, "row label, e.g. 'Rest, small'", required=True),
        "truth": Key("path", None, "ground-truth CSV (sample,x_mm,y_mm[,z_mm])", required=True),
        "measured": Key("path", None, "measured CSV (same samples)", required=True),
        "reference_length_mm": Key(
            "num", None, "for % errors (default: largest truth span)", **POSITIVE_LENGTH
        ),
        "register": Key(
            "str",
            "none",
            "none, translation (the paper's protocol), rigid or "
            "similarity: measurement mapped onto the truth first",
            choices=tuple(REGISTRATIONS),
        ),
    },
}
ARRAY_SECTIONS = {"fixed", "jig", "evaluate"}
SUBTABLES = {
    "ellipsoid": {
        "center_mm": Key("vec3", required=True, **COORDINATE),
        "radii_mm": Key(
            "vec3",
            required=True,
            **POSITIVE_LENGTH,
            expected="positive radii",
        ),
    }
}
ITEM_LABELS = {"geometry.chamber": "name", "evaluate": "label"}
"""Arrays whose items' value errors name them by this key ('c1') rather than by number."""

_KIND_TYPES = {
    "str": "str",
    "path": "Path",
    "num": "float",
    "int": "int",
    "bool": "bool",
    "vec2": "list[float]",
    "vec3": "list[float]",
    "box": "list[float]",
    "list": "list",
    "table": "dict",
    "range": "float | list[float]",
}


class Record:
    """Base of the typed scene tables: reading a key the schema lacks fails loudly,
    naming the closest key."""

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        keys = [f.name for f in fields(self)]
        raise AttributeError(f"{type(self).__name__} has no key '{name}'{_closest(name, keys)}")


def _record_type(name: str, spec: dict[str, Key], nested: dict[str, str]) -> type:
    """A frozen dataclass with one field per key of `spec`, defaulting as the schema
    says; `nested`: keys holding typed records (annotation given)."""

    def default(value):
        if isinstance(value, (list, dict)):
            return field(default_factory=lambda: _copy_plain(value))
        return field(default=value)

    cls = make_dataclass(
        name,
        [
            (
                key,
                nested.get(key) or _KIND_TYPES[k.kind] + (" | None" if k.default is None else ""),
                default(() if key in nested and k.default == [] else k.default),
            )
            for key, k in spec.items()
        ],
        bases=(Record,),
        frozen=True,
    )
    cls.__module__, cls.__qualname__ = __name__, name
    cls.__doc__ = f"Typed scene table ({', '.join(spec) or 'no keys'})."
    globals()[name] = cls  # importable and picklable as fruitcli.scene.<name>
    return cls


def _copy_plain(value):
    if isinstance(value, list):
        return [_copy_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _copy_plain(v) for k, v in value.items()}
    return value


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.replace(".", "_").split("_"))


SUBTABLE_TYPES = {
    key: _record_type(f"{_camel(key)}Table", spec, {}) for key, spec in SUBTABLES.items()
}
ITEM_TYPES = {
    name: _record_type(
        f"{_camel(name.split('.')[-1])}Table",
        spec,
        {k: f"{SUBTABLE_TYPES[k].__name__} | None" for k in spec if k in SUBTABLES},
    )
    for name, spec in ARRAY_SCHEMA.items()
}
"""The typed record of one item of each array of tables ([[fixed]], [[geometry.chamber]])."""
SECTION_TYPES = {
    name: _record_type(
        f"{_camel(name)}Section",
        spec,
        {"chamber": "tuple[ChamberTable, ...]"} if name == "geometry" else {},
    )
    for name, spec in SCHEMA.items()
    if name not in ARRAY_SECTIONS
}
"""The typed record of each table section ([fem] -> FemSection)."""


def _plain(value):
    """Typed records back to the plain dicts and lists the TOML gave (for hashing)."""
    if is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


@dataclass(frozen=True)
class Scene:
    """A validated scene: each section a typed record with defaults filled in
    (`scene.fem.element`), each array of tables a tuple of records (`scene.fixed`,
    `scene.chambers`)."""

    path: Path
    sections: dict[str, Any]
    declared: frozenset[str] = frozenset()  # sections present in the file

    def __getattr__(self, name: str):
        sections = self.__dict__.get("sections")
        if sections is not None and name in sections:
            return sections[name]
        if name.startswith("__") or sections is None:
            raise AttributeError(name)
        raise AttributeError(f"a scene has no section [{name}]{_closest(name, sections)}")

    @property
    def name(self) -> str:
        return self.sections["scene"].name or self.path.stem

    def has(self, section: str) -> bool:
        """True when the file declares `section` (or a non-empty array of it)."""
        return section in self.declared

    @property
    def chambers(self) -> tuple:
        """The [[geometry.chamber]] records."""
        return self.sections["geometry"].chamber

    def values(self, section: str) -> Any:
        """A section's values as plain data, as the TOML gave them with defaults filled
        in: a dict for a table, a list of dicts for an array of tables (stage hashes)."""
        if section not in self.sections:
            raise SceneError(
                f"{self.path.name}: unknown section [{section}]{_closest(section, self.sections)}"
            )
        return _plain(self.sections[section])

    def with_values(self, changes: dict[str, Any]) -> Scene:
        """A copy with `{"section.key": value}` changed (the value as the typed table
        holds it) or `{"section": record}` replaced; each value is checked against the
        schema's choices and ranges, then the checks across keys run again."""
        where = self.path.name
        sections = dict(self.sections)
        for dotted, value in changes.items():
            section, _, key = dotted.partition(".")
            if section not in SECTION_TYPES:
                raise SceneError(
                    f"{where}: cannot set [{section}]{_closest(section, SECTION_TYPES)}"
                )
            if not key:
                if not isinstance(value, SECTION_TYPES[section]):
                    raise SceneError(
                        f"{where}: [{section}]: expected a "
                        f"{SECTION_TYPES[section].__name__}, got {echo(value)}"
                    )
                sections[section] = value
                continue
            spec = SCHEMA[section]
            if key not in spec or key == "chamber":
                raise SceneError(f"{where}: [{section}]: unknown key '{key}'{_closest(key, spec)}")
            _check_value(f"{where}: [{section}]", key, spec[key], value)
            sections[section] = replace(sections[section], **{key: value})
        scene = replace(self, sections=sections)
        _cross_checks(scene, where, must_exist=False)
        return scene


@functools.cache
def default_scene() -> Scene:
    """A scene declaring nothing: every section at the schema's defaults."""
    return parse_scene("", Path("defaults.toml"), must_exist=False)


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
        raise SceneError(f"{where}.{key}: expected {expected}, got {echo(value)}")

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
        if (
            isinstance(value, NUM)
            and not isinstance(value, bool)
            and math.isfinite(value)
            and value >= 0
        ):
            return float(value)
        ok = (
            isinstance(value, list)
            and len(value) == 2
            and all(
                isinstance(v, NUM) and not isinstance(v, bool) and math.isfinite(v) for v in value
            )
        )
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
        _check_items(where, key, spec, value)
        return value
    if k == "table":
        if not isinstance(value, dict):
            fail("a table {key = value}")
        _check_items(where, key, spec, value)
        return value
    raise AssertionError(k)


def _check_items(where: str, key: str, spec: Key, value: list | dict) -> None:
    if spec.max_items is not None and len(value) > spec.max_items:
        raise SceneError(
            f"{where}.{key}: expected at most {spec.max_items:,} entries, got {len(value):,}"
        )


def _number(v: Any) -> bool:
    return isinstance(v, NUM) and not isinstance(v, bool) and math.isfinite(v)


def _check_value(where: str, key: str, spec: Key, value: Any) -> None:
    """The declared choices, range and condition of a typed value (None: unset, fine)."""
    if value is None:
        return

    def fail(name: str = key, got: Any = value, hint: str = "", number: Any = None):
        expected = spec.expectation(got if number is None else number)
        raise SceneError(f"{where}.{name}: expected {expected}, got {echo(got)}{hint}")

    if spec.choices is not None and value not in spec.choices:
        fail(hint=_closest(str(value), spec.choices))
    if spec.min is not None or spec.max is not None:
        if isinstance(value, dict):
            for entry, v in value.items():
                # a table's entry: a number, or a list of numbers (one per state)
                if isinstance(v, list) and spec.kind == "table" and spec.valid is None:
                    bad = [x for x in v if _number(x) and not spec.in_range(x)]
                    if bad:
                        fail(f"{key}.{entry}", bad[0])
                elif not _number(v) or not spec.in_range(v):
                    fail(f"{key}.{entry}", v)
        elif isinstance(value, list):
            # numbers out of range (anything else is the `valid` condition's to refuse)
            out = [v for v in value if _number(v) and not spec.in_range(v)]
            if out:
                fail(number=out[0])
        elif not spec.in_range(value):
            fail()
    if spec.valid is not None and not spec.valid(value):
        fail()


def _check_values(where: str, values: dict, spec: dict[str, Key]) -> None:
    for key, kspec in spec.items():
        if key in SUBTABLES and isinstance(values[key], dict):
            _check_values(f"{where}.{key}", values[key], SUBTABLES[key])
        else:
            _check_value(where, key, kspec, values[key])


def _validate_table(where, table, spec, scene_path, must_exist):
    if not isinstance(table, dict):
        raise SceneError(f"{where}: expected a table, got {type(table).__name__}")
    out = {}
    for key, value in table.items():
        if key not in spec:
            raise SceneError(f"{where}: unknown key '{key}'{_closest(key, spec)}")
        if key in SUBTABLES:
            sub = _check(where, key, spec[key], value, scene_path, must_exist)
            out[key] = _validate_table(
                f"{where}.{key}", sub, SUBTABLES[key], scene_path, must_exist
            )
            for sk, sspec in SUBTABLES[key].items():
                if sspec.required and sk not in out[key]:
                    raise SceneError(f"{where}.{key}: missing key '{sk}'")
            continue
        out[key] = _check(where, key, spec[key], value, scene_path, must_exist)
    for key, kspec in spec.items():
        if key not in out:
            if kspec.required:
                raise SceneError(f"{where}: missing key '{key}' ({kspec.doc})")
            out[key] = _copy_plain(kspec.default)
    return out


def _items(where0: str, array: str, items: list, scene_path: Path, must_exist: bool) -> tuple:
    """Validate an array of tables into a tuple of typed records."""
    spec, label = ARRAY_SCHEMA[array], ITEM_LABELS.get(array)
    if len(items) > MAX_ITEMS:
        raise SceneError(
            f"{where0}: [[{array}]]: expected at most {MAX_ITEMS:,} tables, got {len(items):,}"
        )
    records = []
    for n, item in enumerate(items):
        out = _validate_table(f"{where0}: [[{array}]] #{n + 1}", item, spec, scene_path, must_exist)
        named = f"'{out[label]}'" if label else f"#{n + 1}"
        _check_values(f"{where0}: [[{array}]] {named}", out, spec)
        for key in SUBTABLES:
            if key in out and out[key] is not None:
                out[key] = SUBTABLE_TYPES[key](**out[key])
        records.append(ITEM_TYPES[array](**out))
    return tuple(records)


def parse_scene(text: str, path: Path, must_exist: bool = True) -> Scene:
    """Validate TOML `text` (from `path`) into a `Scene`; raise `SceneError` naming the field."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    where0 = path.name
    sections: dict[str, Any] = {}
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
            sections[section] = _items(where0, section, items, path, must_exist)
            continue
        table = dict(value or {})
        chambers = table.pop("chamber", []) if section == "geometry" else None
        # the artist mesh may be generated by the make-artist stage: checked below
        values = _validate_table(where, table, spec, path, must_exist and section != "geometry")
        if (
            section == "geometry"
            and values["solid"] is not None
            and must_exist
            and not values["solid"].exists()
        ):
            raise SceneError(f"{where}.solid: file not found: {table['solid']}")
        _check_values(where, values, spec)
        if section == "geometry":
            if isinstance(chambers, dict):
                chambers = [chambers]
            if not isinstance(chambers, list):
                raise SceneError(f"{where}.chamber: expected [[geometry.chamber]] tables")
            values["chamber"] = _items(where0, "geometry.chamber", chambers, path, must_exist)
        sections[section] = SECTION_TYPES[section](**values)
    scene = Scene(
        path=path,
        sections=sections,
        # an empty table declares its section at its defaults; an empty array declares none
        declared=frozenset(s for s, v in raw.items() if v != []),
    )
    _cross_checks(scene, where0, must_exist)
    return scene


def _one_folder_per_row(scene: Scene, where: str) -> None:
    """Each bench indenter once, and each evaluation row (an [[evaluate]] label, or
    "<configuration>, <indenter>" of the bench) with a folder name of its own."""
    rows = [(ev.label, "[[evaluate]].label") for ev in scene.evaluate]
    if scene.has("bench"):
        names = list(scene.bench.indenters)
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:
            raise SceneError(
                f"{where}: [bench].indenters: {twice[0]!r} is given twice; expected each "
                "indenter once (it names its folders)"
            )
        config = scene.scene.configuration
        rows += [
            (f"{config}, {name}", "[scene].configuration with [bench].indenters") for name in names
        ]
    seen = {}
    for label, key in rows:
        first = seen.setdefault(slug(label), (label, key))
        if first != (label, key):
            raise SceneError(
                f"{where}: {key} {label!r} and {first[1]} {first[0]!r} both name the folder "
                f"evaluate/{slug(label)}; expected row labels that differ in more than case "
                "and punctuation"
            )


def _cross_checks(scene: Scene, where: str, must_exist: bool) -> None:
    """The checks that involve several keys (one key's choices and range are the schema's)."""
    labels = [ev.label for ev in scene.evaluate]
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise SceneError(
            f"{where}: [[evaluate]].label: {twice[0]!r} is given twice; expected "
            "one label per row (it names the row's folder and table line)"
        )
    _one_folder_per_row(scene, where)
    geo = scene.geometry
    given = {"artist": geo.artist, "solid": geo.solid, "pad_size_mm": geo.pad_size_mm}
    sources = [k for k, v in given.items() if v is not None]
    if len(sources) > 1:
        raise SceneError(
            f"{where}: [geometry] give one of artist, solid, pad_size_mm, not {sources}"
        )
    if geo.artist is not None and geo.generate_artist:
        pass  # the make-artist stage writes it
    elif geo.artist is not None and must_exist and not Path(geo.artist).exists():
        raise SceneError(f"{where}: [geometry].artist: file not found: {geo.artist}")
    names = []
    for n, ch in enumerate(scene.chambers):
        if (ch.ellipsoid is None) == (ch.surface is None):
            raise SceneError(
                f"{where}: [[geometry.chamber]] #{n + 1} '{ch.name}': give exactly one of "
                "ellipsoid or surface"
            )
        if ch.name in names:
            raise SceneError(f"{where}: [[geometry.chamber]]: duplicate name '{ch.name}'")
        names.append(ch.name)
    try:
        material = from_scene(scene.material)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    element = scene.fem.element
    if not MATERIAL_MODELS[material.model].runs_on(element):
        raise SceneError(
            f'{where}: [material].model = "corotational" is the paper\'s SOFA '
            f'model on linear tets: set [fem].element = "p1" (got '
            f'{element!r}), or use model = "neo-hookean"'
        )
    act = scene.actuation
    lengths = set()
    for key, table in (
        ("pressure_kpa", act.pressure_kpa),
        ("volume_growth_mm3", act.volume_growth_mm3),
    ):
        if table is None:
            continue
        for cname, values in table.items():
            if cname not in names:
                hint = _closest(cname, names) if names else " (the scene has no chambers)"
                raise SceneError(f"{where}: [actuation].{key}.{cname}: no such chamber{hint}")
            ok = (
                isinstance(values, list)
                and values
                and all(
                    isinstance(v, NUM) and not isinstance(v, bool) and math.isfinite(v)
                    for v in values
                )
            )
            if not ok:
                raise SceneError(
                    f"{where}: [actuation].{key}.{cname}: expected a non-empty "
                    "list of numbers, one per state"
                )
            if len(values) > MAX_STATES:
                raise SceneError(
                    f"{where}: [actuation].{key}.{cname}: expected at most {MAX_STATES:,} "
                    f"states, got {len(values):,}"
                )
            lengths.add(len(values))
    if len(lengths) > 1:
        raise SceneError(
            f"{where}: [actuation]: every chamber needs the same number of states, "
            f"got {sorted(lengths)}"
        )
    if act.pressure_kpa and act.volume_growth_mm3:
        both = set(act.pressure_kpa) & set(act.volume_growth_mm3)
        if both:
            raise SceneError(
                f"{where}: [actuation]: chamber {sorted(both)[0]} is controlled by "
                "both pressure_kpa and volume_growth_mm3"
            )
    skin = scene.skin
    if skin.taxel_gain is not None and skin.gain_spread > 0:
        raise SceneError(
            f"{where}: [skin].gain_spread: expected 0 with taxel_gain (the gains "
            f"are measured, not drawn), got {skin.gain_spread}"
        )
    if scene.has("bench"):
        bench = scene.bench
        # the paper's indenters (fruitcli.sensing.skin.forward) and those [skin] gives a width
        known = tuple(dict.fromkeys(["small", "medium", *(skin.footprint_sigma_mm or {})]))
        if not bench.indenters or any(i not in known for i in bench.indenters):
            raise SceneError(
                f"{where}: [bench].indenters: expected a non-empty list of "
                f"{', '.join(known)}, got {bench.indenters}"
            )
    if scene.has("printer") and scene.printer.model_origin_mm is None:
        raise SceneError(
            f"{where}: [printer]: missing key 'model_origin_mm' (where the "
            "model's origin is, printer coordinates, mm)"
        )
    if scene.detection.divide_by_gain and skin.taxel_gain is None:
        raise SceneError(
            f"{where}: [detection].divide_by_gain: needs the gains, [skin]."
            'taxel_gain = "gains.csv" (written by fruit calibrate)'
        )


def load_skin_table(path: str | Path) -> Any:
    """The validated [skin] table (a `SkinSection`) of a file that holds only one (`fruit
    calibrate`'s skin.toml); its paths are resolved against that file's folder."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read: {exc}") from None
    skin = parse_scene(text, path)
    other = sorted(skin.declared - {"skin"})
    if "skin" not in skin.declared or other:
        raise SceneError(
            f"{path.name}: expected only a [skin] table"
            + (f", found [{'], ['.join(other)}]" if other else ", found none")
        )
    return skin.skin


def n_states(scene: Scene) -> int:
    """Number of actuation states (1 when the scene has no [actuation])."""
    act = scene.actuation
    for table in (act.pressure_kpa, act.volume_growth_mm3):
        if table:
            return len(next(iter(table.values())))
    return 1


def has_gravity(scene: Scene) -> bool:
    """True when gravity loads the body: [gravity] declared with a non-zero vector, a
    body with mass, held by a [[fixed]] region or a [[jig]] (a free body under gravity
    would only fall)."""
    return (
        scene.has("gravity")
        and any(scene.gravity.vector_m_s2)
        and scene.material.density_kg_m3 > 0
        and bool(scene.fixed or scene.jig)
    )


def gravity_left_out(scene: Scene) -> str | None:
    """Why a declared [gravity] loads nothing (None when it applies or is not declared):
    a weightless body, or no [[fixed]] region nor [[jig]] holding it."""
    if not scene.has("gravity") or not any(scene.gravity.vector_m_s2):
        return None
    if scene.material.density_kg_m3 == 0:
        return "[gravity] left out: [material].density_kg_m3 = 0 (a weightless body)"
    if not (scene.fixed or scene.jig):
        return (
            "[gravity] left out: no [[fixed]] region or [[jig]] holds the body "
            "(a free body would only fall)"
        )
    return None


def has_deformation(scene: Scene) -> bool:
    """True when something moves the body: non-zero actuation, a jig, a moved clamp or
    gravity on a held body."""
    act = scene.actuation
    for table in (act.pressure_kpa, act.volume_growth_mm3):
        if table and any(v != 0 for vals in table.values() for v in vals):
            return True
    moved = any(f.displacement_mm is not None and any(f.displacement_mm) for f in scene.fixed)
    return bool(scene.jig) or moved or has_gravity(scene)


def _bundled_hint(path: Path) -> str:
    """For a missing scene given by a bundled scene's name (`fruit run fruit-rest`): how
    to get an editable copy of it; else ""."""
    from fruitcli.bundled_files import scene_names

    name = path.name.removesuffix(".toml")
    try:
        known = len(path.parts) == 1 and name in scene_names()
    except FruitError:  # no bundled scenes (a broken install)
        known = False
    if not known:
        return ""
    return (
        f"; {name!r} is a bundled scene: copy it with `fruit scenes copy {name} DIR`, "
        f"then run DIR/{name}.toml"
    )


def load_scene(path: str | Path, must_exist: bool = True) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    if not path.exists():
        raise SceneError(f"{path}: scene file not found{_bundled_hint(path)}")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read scene: {exc}") from None
    scene = parse_scene(text, path.resolve(), must_exist=must_exist)
    if not scene.declared:
        raise SceneError(
            f"{path.name}: the scene declares no section; expected at least "
            "[scene] and what to run ([geometry], [[evaluate]], ...)"
        )
    return scene
