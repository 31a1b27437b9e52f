"""The assumed (Gaussian) and the electrostatic skin against the paper's observations.

Units: mm, counts. For both ``[skin].model`` values:

- pre-touch: the gap at which each object under a crossing reads the threshold of 20
  counts (Sec. V-A: "very light touch or even pre-touch"), and its counts at contact;
- the 80 x 80 x 3 mm pad (Fig. 9: at most 10 counts) bent 180 deg over its 48 mm active
  length (`forward.bend_nodes`) along x and along y, the crossing of
  ``pipelines/touchpad-4x4.toml``: its largest baseline shift each way;
- a finger behind that bent pad (Fig. 8 (c): it triggers a touch), solved on the 3 mm
  pad with air on both sides (`fruitcli.electrostatics.back_touch`) for three depths of
  its crossing, the front touch of the same pad beside it;
- the Fruit's breathing (Fig. 11: max 16, mean 5.0 counts) over the 13 FEM states of
  ``pipelines/fruit-breathing.toml``: each taxel's largest |shift|, model alone and as
  played with noise, and where the largest is; the noise (Fig. 10: std up to 1.9);
- Table I (translation-registered) at rest (``pipelines/fruit-rest.toml``) and deformed
  (``pipelines/fruit-deformed.toml``);
- what the rows depend on: the electrostatic skin under the other bend's calibration,
  the Gaussian skin's pre-touch over its contact counts and gap decay, and with
  ``--assumptions`` the crossing's own numbers with the yarn radius, the insulation and
  the permittivity moved off their assumed values (a table each, about a minute), the
  objects' radii (the touch cell over the crossing), the glued radius and the neutral
  plane (the one-crossing cell's stretch and bend).

Each scene runs through the planner in OUT/<scene>-<model> with OUT as the shared
folder, so the stages the two models have in common run once and a second run reuses
them. ``--markdown PATH`` writes the table with the run's date, commit and machine.

    python tests/performance/compare_skins.py --out OUT [--assumptions] [--markdown PATH]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

MODELS = ("gaussian", "electrostatic")
PIPELINES = Path(__file__).resolve().parents[2] / "pipelines"
PAD_CROSSING = "touchpad-4x4-crossing"
"""OUT's folder of the pad's crossing table (built once)."""

VARIANTS = (
    ("yarn_radius_mm", 0.5),
    ("yarn_radius_mm", 0.7),
    ("insulation_mm", 0.05),
    ("insulation_mm", 0.3),
    ("permittivity", 2.5),
    ("permittivity", 3.0),
)
"""The crossing's assumed inputs moved one at a time (defaults 0.6 mm, 0.1 mm, 2.8): a
table each."""

RADII_VARIANTS = (
    {"small": 1.0, "medium": 3.0, "finger": 6.0},
    {"small": 2.0, "medium": 5.0, "finger": 10.0},
)
"""The objects' radii (mm) moved off their assumed 1.5, 4 and 8 mm: the touch cell solved
over the crossing at the table's gaps."""

DEFORMATION_VARIANTS = (
    ("glue_mm", 0.65),
    ("glue_mm", 2.6),
    ("neutral_mm", 1.0),
    ("neutral_mm", 2.0),
)
"""The glued radius (default two yarn radii and the insulation, 1.3 mm) halved and
doubled, and the bent pad's neutral plane (default 1.5 mm under the surface) moved by
0.5 mm: the one-crossing cell's stretch and bend solved again."""


def variant(name: str, model: str, out: Path, extra_bench: str = "") -> Path:
    """The pipeline scene `name` with ``[skin].model = model`` (and lines appended to its
    last table, [bench] or [sensitivity]), written into `out`; its paths made absolute."""
    from fruitcli.scene import load_scene

    src = PIPELINES / f"{name}.toml"
    artist = load_scene(src).geometry.artist
    text = src.read_text()
    if artist is not None:
        local = out / "data" / Path(artist).name
        if not local.exists() and Path(artist).exists():
            local.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(artist, local)
        text = text.replace(f'"data/generated/{Path(artist).name}"', f'"{local}"')
    text += extra_bench + f'\n[skin]\nmodel = "{model}"\n'
    path = out / f"{name}-{model}.toml"
    path.write_text(text)
    return path


def run_scene(path: Path, out: Path) -> Path:
    """`fruit run` of the scene into OUT/<stem>, borrowing from its siblings."""
    from fruitcli.scene import load_scene
    from fruitcli.workflow.planner import run

    root = out / path.stem
    run(load_scene(path), root, progress=lambda msg: print(f"  {path.stem}: {msg}"), shared=out)
    return root


# ------------------------------------------------------------------------------ the pad
def pad_crossing(out: Path):
    """The crossing of ``pipelines/touchpad-4x4.toml`` (pitch 16 x 16 mm, cover 2 mm) in
    counts, its counts per fF fitted to its own bend; built once into OUT."""
    from fruitcli.electrostatics import design
    from fruitcli.scene import load_scene
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

    folder = out / PAD_CROSSING
    if not (folder / "summary.json").exists():
        scene = load_scene(PIPELINES / "touchpad-4x4.toml")
        table, summary = design.run_crossing(design.crossing_inputs(scene))
        design.write_outputs(folder, table, summary)
    return CrossingSkin.load(folder)


def _bent(nodes: np.ndarray, along: str) -> np.ndarray:
    """The pad's nodes bent 180 deg over its active length along x or along y."""
    from fruitcli.sensing.skin import forward

    swap = [1, 0, 2] if along == "y" else [0, 1, 2]
    radius = forward.PAD_ACTIVE_MM / np.pi
    return forward.bend_nodes(nodes[:, swap], radius, forward.PAD_SIZE_MM[2])[:, swap]


def bent_pad_shifts(model: str, response=None) -> dict[str, float]:
    """Per bending direction (x, y): the signed largest baseline shift (counts) of the
    pad's 16 taxels, fabrication factor 1."""
    from fruitcli.fem.elements.barycentric import locate
    from fruitcli.fem.meshing.topology import boundary_faces
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.crossing_skin import shift_counts

    nodes, tets = forward.pad_mesh()
    tris = boundary_faces(nodes, tets)
    taxels = forward.pad_taxels_mm(z_mm=forward.PAD_SIZE_MM[2] - 1e-6)
    out: dict[str, Any] = {}
    for along in ("x", "y"):
        bent = _bent(nodes, along)
        if model == "gaussian":
            w = forward.taxel_surface_weights(nodes, tris, forward.pad_taxels_mm())
            strain = forward.surface_green_strain(nodes, bent, tris) @ w.T
            shift = forward.calibrate_strain_gain() * strain
        else:
            k, bary, _ = locate(nodes, tets, taxels)
            states = SimpleNamespace(
                rest_nodes=nodes,
                tets=tets,
                displacement_mm=(bent - nodes)[None],
                surface_tris=tris,
                taxel_tet=k,
                taxel_bary=bary,
            )
            shift = shift_counts(states, response, np.ones(len(taxels)), 0)
        out[along] = float(shift[np.argmax(np.abs(shift))])
    return out


FINGER_DEPTHS_MM = (1.35, 1.5, 1.65)
"""Depths of the pad's crossing under its front face for the finger behind it: the
middle of the 3 mm pad and 0.15 mm either side (the yarns of 0.6 mm radius and the
insulation reach 1.25 mm either side of the crossing, so it fits 1.25 to 1.75 mm deep;
the pad scene's 2 mm cover would put the lower yarn out of the back)."""


def finger_behind(model: str, response=None) -> dict:
    """Per depth of the pad's crossing (`FINGER_DEPTHS_MM`): counts of the crossing with a
    finger touching the 3 mm pad's back face over it (Fig. 8 (c)), and touching its
    front. Electrostatic: solved on the pad with air on both sides
    (`fruitcli.electrostatics.back_touch`), the pad's crossing's inputs (pitch 16 x 16
    mm, yarn radius, insulation, permittivity) and counts per fF (`response`). Gaussian:
    it has no back; its contact counts and gap decay at the distance through the pad
    less the depth in front (front gap = thickness - 2 depth)."""
    from fruitcli.electrostatics import back_touch, design
    from fruitcli.scene import load_scene
    from fruitcli.sensing.skin import forward

    thick = forward.PAD_SIZE_MM[2]
    out: dict[str, Any] = {}
    for depth in FINGER_DEPTHS_MM:
        if model == "gaussian":
            gap = thick - 2 * depth
            counts = forward.CONTACT_COUNTS * math.exp(-gap / forward.GAP_DECAY_MM)
            out[f"{depth:g}"] = {"depth_mm": depth, "back": counts, "front_gap_mm": gap}
            continue
        inputs = design.crossing_inputs(load_scene(PIPELINES / "touchpad-4x4.toml"))
        pad = back_touch.Pad(
            inputs.pitch_x_mm,
            inputs.pitch_y_mm,
            thick,
            depth,
            inputs.yarn_radius_mm,
            inputs.insulation_mm,
            inputs.permittivity,
        )
        drops = back_touch.contact_drops_ff(pad, "finger", inputs.time_limit_s)
        cpf = response.counts_per_ff
        own_cpf, own_bend = back_touch.bend_counts_per_ff(pad, inputs.time_limit_s)
        out[f"{depth:g}"] = {
            "depth_mm": depth,
            "back": float(-cpf * drops["back"]["dc"]),
            "front": float(-cpf * drops["front"]["dc"]),
            "drops_ff": drops,
            "own_counts_per_ff": own_cpf,
            "own_bend_ff": own_bend,
            "back_own": float(-own_cpf * drops["back"]["dc"]),
            "symmetric_assumption": float(response.drop("finger", 0.0, 0.0, thick - 2 * depth)),
        }
    return out


# ------------------------------------------------------------------------- the Fruit
def electrostatic_pretouch(folder: Path, counts_per_ff: float | None = None) -> dict:
    """Per object of the table in `folder`: (gap mm at which the crossing under it reads
    20 counts, counts at contact), in `counts_per_ff` (default: the table's)."""
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

    response = CrossingSkin.load(folder, counts_per_ff)
    gaps = np.linspace(0.0, float(response.gap_mm[-1]), 8001)
    out: dict[str, Any] = {}
    for name in response.objects:
        counts = response.drop(name, 0.0, 0.0, gaps)
        above = np.flatnonzero(counts >= 20.0)
        gap = float(gaps[above[-1]]) if above.size else 0.0
        out[name] = (math.inf if gap >= gaps[-1] else gap, float(counts[0]))
    return out


def breathing_shifts(root: Path, model: str, response=None) -> dict:
    """Each taxel's largest |baseline shift| (counts) over the breathing states, from the
    run's states and its skin (fabrication factors as the sensitivity stage draws them;
    the electrostatic skin's `response`, default the run's table): max and mean over
    taxels, and the taxel of the largest."""
    from fruitcli.scene import load_scene
    from fruitcli.sensing.detection.locate import load_states
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin, shift_counts
    from fruitcli.tables import read_taxels

    scene = load_scene(root.parent / f"{root.name}.toml")
    taxels = read_taxels(root / "make-tracks" / "taxels.csv")
    states = load_states(root / "simulate" / "states.npz", len(taxels))
    params = forward.SkinParams.from_table(scene.skin)
    skin = forward.make_skin(len(taxels), scene.bench.seed, params, taxels.ids)
    if model == "gaussian":
        shift = forward.strain_shift_counts(forward.taxel_strain(states), skin)
    else:
        response = response or CrossingSkin.load(root / "skin")
        shift = shift_counts(states, response, skin.fab)
    per_taxel = np.abs(shift).max(axis=0)
    strain = forward.taxel_strain(states).max(axis=0)  # each taxel's largest
    k = int(np.argmax(per_taxel))
    centres = {}
    for c in scene.chambers:  # the study's scenes give every chamber as an ellipsoid
        assert c.ellipsoid is not None, f"chamber {c.name}: no ellipsoid, so no centre"
        centres[c.name] = np.asarray(c.ellipsoid.center_mm)
    near = min(centres, key=lambda n: np.hypot(*(centres[n][:2] - taxels.xyz_mm[k, :2])))
    far = np.hypot(*(centres[near][:2] - taxels.xyz_mm[k, :2]))
    signed = shift[:, k][np.argmax(np.abs(shift[:, k]))]
    return {
        "max": float(per_taxel.max()),
        "mean": float(per_taxel.mean()),
        "negative_share": float(np.mean(np.abs(shift.min(axis=0)) > shift.max(axis=0))),
        "where": {
            "i": int(taxels.i[k]),
            "j": int(taxels.j[k]),
            "fab": float(skin.fab[k]),
            "xyz_mm": [float(v) for v in taxels.xyz_mm[k]],
            "signed": float(signed),
            "chamber": f"{far:.0f} mm from chamber {near}'s centre in x, y",
        },
        "without_defects_max": float((per_taxel / skin.fab).max()),
        "strain_max": float(strain.max()),
        "strain_mean": float(strain.mean()),
        "top_z_mm": float(taxels.xyz_mm[:, 2].max()),
        "span_mm": [float(v) for v in np.ptp(taxels.xyz_mm, axis=0)],
    }


def assumption_variants(scene_path: Path, out: Path, breathing: Path) -> list[dict]:
    """The Fruit's crossing with each of `VARIANTS` moved off its assumed value: counts
    per fF (fitted to the bend), counts at contact, pre-touch gaps (as
    `electrostatic_pretouch` gives them for the default), both bends, a 10 % stretch
    along each yarn and the breathing run's shifts (`breathing_shifts`). Each table is
    built once into OUT/crossing-KEY-VALUE."""
    from fruitcli.electrostatics import design
    from fruitcli.errors import FruitError
    from fruitcli.scene import load_scene
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

    scene = load_scene(scene_path)
    base = design.crossing_inputs(scene)
    rows = []
    for key, value in VARIANTS:
        folder = out / f"crossing-{key}-{value:g}"
        if not (folder / "summary.json").exists():
            print(f"  crossing with {key} = {value}")
            try:
                changed: dict[str, Any] = {key: value}
                table, summary = design.run_crossing(replace(base, **changed))
            except FruitError as exc:  # e.g. gmsh fails on the cell: a row saying so
                rows.append({"key": key, "value": value, "error": str(exc)})
                continue
            design.write_outputs(folder, table, summary)
        summary = json.loads((folder / "summary.json").read_text())
        shifts = summary["deformation_shift_counts"]
        at = shifts["strain"].index(0.1)
        rows.append(
            {
                "key": key,
                "value": value,
                "counts_per_ff": summary["counts_per_ff"],
                "pretouch": electrostatic_pretouch(folder),
                "bend_counts": {a: shifts[f"bend_{a}"][-1] for a in "xy"},
                "stretch_10pct_counts": {a: shifts[f"stretch_{a}"][at] for a in "xy"},
                "breathing": _max_mean(breathing, CrossingSkin.load(folder)),
            }
        )
    return rows


def _max_mean(breathing: Path, response) -> tuple[float, float]:
    """(max, mean) of the breathing run's per-taxel largest |shift| under `response`."""
    b = breathing_shifts(breathing, "electrostatic", response)
    return b["max"], b["mean"]


def _threshold_gap(gaps: np.ndarray, counts: np.ndarray) -> float:
    """Gap (mm) at which `counts` (g,), linear between the gaps as `CrossingSkin.drop`
    is, falls to 20; inf beyond the last gap."""
    above = np.flatnonzero(counts >= 20.0)
    if not above.size:
        return 0.0
    j = int(above[-1])
    if j == len(gaps) - 1:
        return math.inf
    return float(np.interp(20.0, counts[[j + 1, j]], gaps[[j + 1, j]]))


def radius_variants(inputs, counts_per_ff: float) -> list[dict]:
    """Per radii of `RADII_VARIANTS` (and the default's, a check against the table):
    each object over the crossing at the table's gaps on the default touch cell, in the
    default's counts per fF (the deformation cell has no object): pre-touch gap and
    counts at contact."""
    from fruitcli.electrostatics import crossing, design
    from fruitcli.electrostatics.cell_mesh import mesh_cell
    from fruitcli.electrostatics.touch_objects import OBJECTS

    mesh = mesh_cell(design.cell_spec(inputs), 1, inputs.time_limit_s)
    gaps = np.asarray(inputs.gaps_mm, float)
    rows = []
    default = {k: o.radius_mm for k, o in OBJECTS.items()}
    for radii in (default, *RADII_VARIANTS):
        objects = {k: replace(o, radius_mm=radii[k]) for k, o in OBJECTS.items()}
        solver = crossing.CellSolver(mesh, inputs.permittivity, objects)
        c0 = solver.capacitance()
        pretouch = {}
        for name in objects:
            dc = [solver.object_crossings(name, 0.0, 0.0, g)[solver.centre] - c0 for g in gaps]
            counts = -counts_per_ff * np.array(dc)
            pretouch[name] = (_threshold_gap(gaps, counts), float(counts[0]))
        print(f"  radii {radii}: {pretouch}")
        rows.append({"radii": radii, "pretouch": pretouch, "default": radii is default})
    return rows


def deformation_variants(inputs, table: Path, breathing: Path) -> list[dict]:
    """Per input of `DEFORMATION_VARIANTS` (and the default, a check against the table):
    the one-crossing cell stretched and bent, its counts per fF fitted to the larger of
    the two bends as the pad (as `equivalents.counts_per_ff` does), both bends and a 10 %
    stretch along each yarn in those counts, and the breathing run's shifts with the
    crossing `table` (a `fruit skin` folder) given these stretches and bends (and the
    neutral plane)."""
    from fruitcli.electrostatics import crossing, design
    from fruitcli.electrostatics.cell_mesh import mesh_cell
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

    with np.load(table / "crossing.npz") as data:
        arrays = {k: data[k] for k in data.files}
    summary = json.loads((table / "summary.json").read_text())

    spec = crossing.deformation_spec(design.cell_spec(inputs))
    solver = crossing.CellSolver(mesh_cell(spec, 1, inputs.time_limit_s), inputs.permittivity)
    c0 = solver.capacitance()
    rows = []
    for key, value in (("default", None), *DEFORMATION_VARIANTS):
        kwargs: dict[str, Any] = {} if value is None else {key: value}
        strains, c_s, curvatures, c_b = crossing.deformation_table(solver, spec, c0, **kwargs)
        i = int(np.argmin(np.abs(curvatures - crossing.PAD_BEND_CURVATURE_PER_MM)))
        bend = c_b[:, i] - c0
        cpf = crossing.BEND_SHIFT_COUNTS / float(np.abs(bend).max())
        at = int(np.argmin(np.abs(strains - 0.1)))
        row: dict[str, Any] = {
            "key": key,
            "value": value,
            "counts_per_ff": cpf,
            "fitted_to": "xy"[int(np.argmax(np.abs(bend)))],
            "bend_counts": {a: float(-cpf * bend[n]) for n, a in enumerate("xy")},
            "stretch_10pct_counts": {
                a: float(-cpf * (c_s[n, at] - c0)) for n, a in enumerate("xy")
            },
        }
        moved = {**arrays, "c_stretch_ff": c_s - c0 + arrays["c0_ff"]}
        moved["c_bend_ff"] = c_b - c0 + arrays["c0_ff"]
        response = CrossingSkin.from_table(moved, summary, cpf)
        if key == "neutral_mm" and value is not None:
            response = replace(response, neutral_mm=value)
        row["breathing"] = _max_mean(breathing, response)
        print(f"  {key} = {value}: {row}")
        rows.append(row)
    return rows


def observe(out: Path, assumptions: bool) -> dict:
    """Every observation for both skins (runs the scenes that are not yet in OUT)."""
    from fruitcli.electrostatics import design
    from fruitcli.scene import load_scene
    from fruitcli.workflow import observations as obs

    report = {}
    pad = pad_crossing(out)
    for model in MODELS:
        reg = '\nregister = "translation"\n'
        rest = run_scene(variant("fruit-rest", model, out, reg), out)
        deformed = run_scene(variant("fruit-deformed", model, out, reg), out)
        breathing = run_scene(variant("fruit-breathing", model, out), out)
        response = pad if model == "electrostatic" else None
        entry: dict[str, Any] = {
            "table_i": {**obs.table_i(rest), **obs.table_i(deformed)},
            "bent_pad": bent_pad_shifts(model, response),
            "finger_behind": finger_behind(model, response),
            "breathing": breathing_shifts(breathing, model),
            "sensitivity": obs.sensitivity(breathing),
        }
        if model == "gaussian":
            from fruitcli.sensing.skin import forward

            gap = obs.gaussian_pretouch_mm(forward.CONTACT_COUNTS, forward.GAP_DECAY_MM)
            entry["pretouch"] = {n: (gap, forward.CONTACT_COUNTS) for n in ("small", "medium")}
            entry["pretouch_range"] = {
                f"{c:g} counts, decay {d:g} mm": obs.gaussian_pretouch_mm(c, d)
                for c in (40.0, 60.0, 80.0)
                for d in (1.0, 2.0, 3.0)
            }
        else:
            summary = json.loads((rest / "skin" / "summary.json").read_text())
            other_ff = abs(summary["counts_fit"]["other_bend_shift_ff"])
            entry["counts_per_ff"] = summary["counts_per_ff"]
            shifts = summary["deformation_shift_counts"]
            at = shifts["strain"].index(0.1)
            entry["crossing_shifts"] = {
                "bend": {a: shifts[f"bend_{a}"][-1] for a in "xy"},
                "stretch_10pct": {a: shifts[f"stretch_{a}"][at] for a in "xy"},
            }
            entry["counts_per_ff_other_bend"] = 10.0 / other_ff
            entry["pretouch"] = electrostatic_pretouch(rest / "skin")
            entry["pretouch_other_bend"] = electrostatic_pretouch(
                rest / "skin", entry["counts_per_ff_other_bend"]
            )
            entry["pad_counts_per_ff"] = pad.counts_per_ff
            entry["pretouch_pad_calibration"] = electrostatic_pretouch(
                rest / "skin", pad.counts_per_ff
            )
            if assumptions:
                scene_path = rest.parent / f"{rest.name}.toml"
                entry["variants"] = assumption_variants(scene_path, out, breathing)
                inputs = design.crossing_inputs(load_scene(scene_path))
                entry["radius_variants"] = radius_variants(inputs, entry["counts_per_ff"])
                entry["deformation_variants"] = deformation_variants(
                    inputs, rest / "skin", breathing
                )
                for row in entry["deformation_variants"][1:]:
                    row["pretouch"] = electrostatic_pretouch(rest / "skin", row["counts_per_ff"])
        report[model] = entry
    return report


# --------------------------------------------------------------------------- the table
def _pair(d: dict, unit: str, digits: int = 1) -> str:
    """'small 0.30, medium 3.69 mm' (inf: beyond the table's last gap)."""
    return (
        ", ".join(
            f"{k} {v:.{digits}f}" if math.isfinite(v) else f"{k} beyond the table"
            for k, v in d.items()
        )
        + f" {unit}"
    )


def _bends(b: dict) -> str:
    return f"bent along x {b['x']:+.1f}, along y {b['y']:+.1f} counts"


def _finger(f: dict, bends: dict) -> str:
    def one(c: float) -> str:
        return f"{c:.0f} ({c + bends['x']:.0f} / {c + bends['y']:.0f} bent along x / y)"

    parts = []
    for row in f.values():
        front = f", front {row['front']:.0f}" if "front" in row else ""
        parts.append(f"crossing {row['depth_mm']:g} mm deep: back {one(row['back'])}{front}")
    return "; ".join(parts) + " counts"


def _breathing(b: dict, sens: dict) -> str:
    w = b["where"]
    at = ", ".join(f"{v:.0f}" for v in w["xyz_mm"])
    return (
        f"model: max {b['max']:.1f}, mean {b['mean']:.2f} counts; the largest at taxel "
        f"({w['i']}, {w['j']}), ({at}) mm, {w['chamber']}, {w['signed']:+.1f} counts, "
        f"fabrication factor {w['fab']:.2f} (largest without the factor "
        f"{b['without_defects_max']:.1f}); {100 * b['negative_share']:.0f} % of taxels "
        f"shift mostly negative. Played with noise: max {sens['played_max']:.1f}, mean "
        f"{sens['played_mean']:.1f} counts"
    )


def _variant_row(
    label: str, cpf: float, pretouch: dict, bend: dict, stretch: dict, breathing
) -> str:
    """One row of the assumed inputs' table."""
    return (
        f"| {label} | {cpf:.3f} | "
        + _pair({k: p[0] for k, p in pretouch.items()}, "", 2).strip()
        + " | "
        + _pair({k: p[1] for k, p in pretouch.items()}, "", 1).strip()
        + f" | {bend['x']:+.1f} / {bend['y']:+.1f} | "
        f"{stretch['x']:+.1f} / {stretch['y']:+.1f} | {breathing[0]:.1f} / {breathing[1]:.2f} |"
    )


def markdown(report: dict) -> str:
    """The observations table (and what its rows depend on) as Markdown, stamped with
    the run's date, commit and machine."""
    from fruitcli.studies.machine import machine_line
    from fruitcli.workflow import observations as obs

    g, e = report["gaussian"], report["electrostatic"]
    rows = [
        (
            "pre-touch: gap (mm) at which the crossing under the object reads 20 counts",
            obs.PAPER["pretouch"],
            _pair({k: v[0] for k, v in g["pretouch"].items()}, "mm", 2),
            _pair({k: v[0] for k, v in e["pretouch"].items()}, "mm", 2),
            "Gaussian: contact counts and gap decay (assumed; see below). Electrostatic: "
            "counts per fF (calibrated, bent pad), indenter radii (assumed), yarn radius, "
            "insulation, permittivity (assumed; see below), cover 2 mm (design)",
        ),
        (
            "counts at contact, object over the crossing",
            "not given",
            _pair({k: v[1] for k, v in g["pretouch"].items()}, "counts"),
            _pair({k: v[1] for k, v in e["pretouch"].items()}, "counts"),
            "as above",
        ),
        (
            "4 x 4 pad, 3 mm, bent 180 deg over 48 mm: largest taxel shift",
            obs.PAPER["bent_pad"],
            _bends(g["bent_pad"]),
            _bends(e["bent_pad"]),
            "Gaussian: strain gain (fitted to 10 counts on this pad; the strain norm "
            "does not tell the directions apart). Electrostatic: counts per fF (fitted so "
            "the pad's crossing bent along y shifts +10), glue radius and neutral plane "
            "1.5 mm (assumed)",
        ),
        (
            "finger behind the bent pad: counts at the crossing under it",
            obs.PAPER["finger_back"],
            _finger(g["finger_behind"], g["bent_pad"]),
            _finger(e["finger_behind"], e["bent_pad"]),
            "where the crossing sits in the pad (not given; 0.6 mm yarns fit the 3 mm pad "
            "only 1.25 to 1.75 mm deep), the finger (a grounded rounded rod 16 mm wide, "
            "assumed), air on both sides of the pad (no ground plane, assumed), the "
            "counts per fF of the pad's crossing, the bend direction (its shift added). "
            "Electrostatic: solved on the pad, both faces; Gaussian: its gap law through "
            "the pad (it has no back)",
        ),
        (
            "the Fruit breathing (13 states, 0-12 kPa): each taxel's largest absolute shift",
            obs.PAPER["breathing"],
            _breathing(g["breathing"], g["sensitivity"]),
            _breathing(e["breathing"], e["sensitivity"]),
            "the FEM (E = 100 kPa, nu = 0.49, 5 mm P2 mesh: design and assumed; the "
            "surface's Green strain norm around a taxel, each taxel's largest: max "
            f"{g['breathing']['strain_max']:.3f}, mean {g['breathing']['strain_mean']:.3f}), "
            "5 % of crossings deforming 1.5-2.5 times more (assumed); Gaussian: the strain "
            "gain; electrostatic: the crossing's stretch and bend, counts per fF",
        ),
        (
            "noise: std of each taxel over 300 frames at rest",
            obs.PAPER["noise"],
            f"max {g['sensitivity']['noise_max']:.2f}, mean "
            f"{g['sensitivity']['noise_mean']:.2f} counts",
            f"max {e['sensitivity']['noise_max']:.2f}, mean "
            f"{e['sensitivity']['noise_mean']:.2f} counts",
            "an input of both skins: `noise_std_counts`, per-taxel std drawn in [0.5, "
            "1.85] (assumed, set so the largest is near the paper's)",
        ),
    ]
    for label, (mean, _, std, _) in obs.PAPER_TABLE_I.items():
        rows.append(
            (
                f"Table I, {label}: N9, translation-registered error",
                f"{mean:.1f} ± {std:.1f} mm",
                obs.fmt_table_i(g["table_i"], label),
                obs.fmt_table_i(e["table_i"], label),
                "everything above; no parameter fitted to Table I",
            )
        )
    lines = [
        machine_line(),
        "",
        "| observation | paper | Gaussian skin (assumed) | electrostatic skin (design "
        "values, counts per fF from the bent pad) | depends on |",
        "|---|---|---|---|---|",
    ]
    lines += ["| " + " | ".join(c.replace("|", r"\|") for c in r) + " |" for r in rows]
    lines += [
        "",
        "What the rows depend on, one parameter at a time:",
        "",
        "- Gaussian pre-touch gap over contact counts and gap decay: "
        + "; ".join(f"{k}: {v:.2f} mm" for k, v in g["pretouch_range"].items())
        + ".",
        f"- Electrostatic, counts per fF fitted to the bend along x instead of y "
        f"({e['counts_per_ff_other_bend']:.3f} instead of {e['counts_per_ff']:.3f}): "
        f"pre-touch {_pair({k: v[0] for k, v in e['pretouch_other_bend'].items()}, 'mm', 2)}"
        f", at contact {_pair({k: v[1] for k, v in e['pretouch_other_bend'].items()}, 'counts')}"
        f"; the Fruit's breathing (the shifts scale with it) max "
        f"{e['breathing']['max'] * e['counts_per_ff_other_bend'] / e['counts_per_ff']:.1f}, "
        f"mean {e['breathing']['mean'] * e['counts_per_ff_other_bend'] / e['counts_per_ff']:.2f}"
        f" counts; the pad bent along y then shifts "
        f"{e['bent_pad']['y'] * 10.0 / abs(e['bent_pad']['x']):+.1f} counts (the pad "
        f"fitted alike: bent along x to -10).",
        f"- Electrostatic, the counts per fF of the pad's own crossing (pitch 16 x 16 mm, "
        f"{e['pad_counts_per_ff']:.3f}: one number for the board, fitted on the pad the "
        f"paper bent) on the Fruit's crossing (whose own fit gives {e['counts_per_ff']:.3f}): "
        f"pre-touch "
        f"{_pair({k: v[0] for k, v in e['pretouch_pad_calibration'].items()}, 'mm', 2)}, "
        f"at contact "
        f"{_pair({k: v[1] for k, v in e['pretouch_pad_calibration'].items()}, 'counts')}; "
        f"the Fruit's breathing max "
        f"{e['breathing']['max'] * e['pad_counts_per_ff'] / e['counts_per_ff']:.1f}, mean "
        f"{e['breathing']['mean'] * e['pad_counts_per_ff'] / e['counts_per_ff']:.2f} counts.",
    ]
    own = [f for f in e["finger_behind"].values() if "own_counts_per_ff" in f]
    if own:
        lines.append(
            "- Electrostatic, the finger behind the pad in the counts per fF of the pad's "
            "crossing at each depth instead of the pad scene's (its one-crossing cell, "
            "3 mm thick with its back face insulating, bent as Fig. 9; the larger bend "
            "fitted to 10 counts): "
            + "; ".join(
                f"{f['depth_mm']:g} mm deep: {f['own_counts_per_ff']:.3f} counts per fF "
                f"(bend along x {f['own_bend_ff']['x']:+.2f}, along y "
                f"{f['own_bend_ff']['y']:+.2f} fF), back {f['back_own']:.0f} counts"
                for f in own
            )
            + "."
        )
    if e.get("variants"):
        lines += [
            "",
            "The Fruit's crossing with one assumed input moved (each fits its own counts "
            "per fF to the larger of its two bends as the pad, as the default does: the "
            "bend at 10 counts in the bend column):",
            "",
            "| input moved | counts per fF | pre-touch gap (mm) | counts at contact | "
            "crossing bent as the pad, along x / y (counts) | stretched 10 %, along x / y "
            "(counts) | the Fruit breathing, max / mean (counts) |",
            "|---|---|---|---|---|---|---|",
        ]
        c = e["crossing_shifts"]
        b = (e["breathing"]["max"], e["breathing"]["mean"])
        default = (e["counts_per_ff"], e["pretouch"], c["bend"], c["stretch_10pct"], b)
        lines.append(_variant_row("none (the default)", *default))
        for v in e["variants"]:
            if "error" in v:
                lines.append(f"| {v['key']} = {v['value']:g} | {v['error']} | | | | | |")
                continue
            lines.append(
                _variant_row(
                    f"{v['key']} = {v['value']:g}",
                    v["counts_per_ff"],
                    v["pretouch"],
                    v["bend_counts"],
                    v["stretch_10pct_counts"],
                    v["breathing"],
                )
            )
        for v in e.get("radius_variants", []):
            if v["default"]:
                continue
            label = "radii " + ", ".join(f"{k} {r:g}" for k, r in v["radii"].items()) + " mm"
            lines.append(_variant_row(label, e["counts_per_ff"], v["pretouch"], *default[2:]))
        names = {"glue_mm": "glued radius", "neutral_mm": "neutral plane"}
        for v in e.get("deformation_variants", [])[1:]:
            lines.append(
                _variant_row(
                    f"{names[v['key']]} {v['value']:g} mm",
                    v["counts_per_ff"],
                    v["pretouch"],
                    v["bend_counts"],
                    v["stretch_10pct_counts"],
                    v["breathing"],
                )
            )
        lines += [
            "",
            "Defaults: yarn radius 0.6 mm, insulation 0.1 mm, permittivity 2.8 (each row a "
            "table of its own); the objects' radii small 1.5, medium 4, finger 8 mm (their "
            "rows solve the default cell over the crossing at the table's gaps; the "
            "deformation cell holds no object, so their counts per fF and shifts are the "
            "default's, the breathing's too); the glued radius 1.3 mm (two yarn radii and "
            "the insulation) and the neutral plane 1.5 mm under the surface (their rows "
            "solve the one-crossing cell's stretch and bend again; the touch table does "
            "not change, so their pre-touch gaps and contact counts move with the counts "
            "per fF alone).",
        ]
        checks = [v for v in e.get("radius_variants", []) if v["default"]]
        checks += [v for v in e.get("deformation_variants", []) if v["key"] == "default"]
        if len(checks) == 2:
            r, d = checks
            lines += [
                "",
                "Check: the same solves with the default inputs give contact counts "
                + _pair({k: p[1] for k, p in r["pretouch"].items()}, "counts")
                + f" and counts per fF {d['counts_per_ff']:.3f}, breathing max "
                f"{d['breathing'][0]:.1f}, mean {d['breathing'][1]:.2f} counts, as the table.",
            ]
    lines += [
        "",
        "Made by `python tests/performance/compare_skins.py --out OUT --assumptions "
        "--markdown docs/data/skin-observations.md`.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--assumptions", action="store_true", help="also vary the crossing's inputs")
    ap.add_argument("--markdown", type=Path, help="write the table here (e.g. docs/data/)")
    args = ap.parse_args(argv)
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    report = observe(out, args.assumptions)
    (out / "comparison.json").write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))
    if args.markdown:
        from fruitcli.fsutil import write_text

        write_text(args.markdown, markdown(report))
        print(f"wrote {args.markdown}")


if __name__ == "__main__":
    main()
