"""The assumed (Gaussian) and the electrostatic skin side by side, against the paper.

Units: mm, counts. Prints, for both ``[skin].model`` values:

- Table I's rows (translation-registered) of the bench on ``pipelines/fruit-rest.toml``;
- the bent pad's largest baseline shift (Fig. 9: 10 counts): the 80 x 80 x 3 mm pad's
  mesh bent 180 deg over its 48 mm active length (`forward.bend_nodes`, the Gaussian
  model's own calibration case) on the cell of ``pipelines/touchpad-4x4.toml``;
- with ``--breathing``, the breathing animation's shifts (Fig. 11: mean 5, max 16
  counts) of ``pipelines/fruit-breathing.toml`` (13 FEM states: slow);
- the gap at which each object crosses the threshold of 20 counts (Sec. V-B: "very
  light touch or even pre-touch").

Each scene runs through the planner in OUT/<scene>-<model> with OUT as the shared
folder, so the stages the two models have in common run once.

    python tests/bench/compare_skins.py --out OUT [--breathing]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np

MODELS = ("gaussian", "electrostatic")
PIPELINES = Path(__file__).resolve().parents[2] / "pipelines"


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


def bent_pad_shift(model: str) -> float:
    """Largest baseline shift (counts) of the pad bent 180 deg (fabrication factor 1)."""
    from fruitcli.fem.elements.barycentric import locate
    from fruitcli.fem.meshing.topology import boundary_faces
    from fruitcli.sensing.skin import forward

    if model == "gaussian":
        return float(forward.calibrate_strain_gain() * forward.bent_pad_taxel_strain().max())
    from fruitcli.scene import load_scene
    from fruitcli.sensing.skin.crossing_skin import crossing_skin, shift_counts

    nodes, tets = forward.pad_mesh()
    taxels = forward.pad_taxels_mm(z_mm=forward.PAD_SIZE_MM[2] - 1e-6)
    k, bary, _ = locate(nodes, tets, taxels)
    bent = forward.bend_nodes(nodes, forward.PAD_ACTIVE_MM / np.pi, forward.PAD_SIZE_MM[2])
    states = SimpleNamespace(
        rest_nodes=nodes,
        tets=tets,
        displacement_mm=(bent - nodes)[None],
        surface_tris=boundary_faces(nodes, tets),
        taxel_tet=k,
        taxel_bary=bary,
    )
    response = crossing_skin(load_scene(PIPELINES / "touchpad-4x4.toml"))
    shift = shift_counts(states, response, np.ones(len(taxels)), 0)
    return float(shift[np.argmax(np.abs(shift))])


def threshold_gaps(skin_dir: Path | None) -> dict:
    """Gap (mm) at which each object's activation under the crossing is 20 counts."""
    from fruitcli.sensing.skin import forward

    if skin_dir is None:
        gap = forward.GAP_DECAY_MM * math.log(forward.CONTACT_COUNTS / forward.THRESHOLD_COUNTS)
        return {name: gap for name in forward.INDENTER_RADIUS_MM}
    summary = json.loads((skin_dir / "summary.json").read_text())
    return {name: o["threshold_gap_mm"] for name, o in summary["objects"].items()}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--breathing", action="store_true", help="also the breathing animation")
    args = ap.parse_args(argv)
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    report = {}
    for model in MODELS:
        rest = run_scene(variant("fruit-rest", model, out, '\nregister = "translation"\n'), out)
        entry = {
            "table_i": [
                {
                    k: r.get(k)
                    for k in ("label", "n", "register", "mean_mm", "std_mm", "mean_pct", "std_pct")
                }
                for r in _rows(rest)
            ],
            "bent_pad_max_shift": bent_pad_shift(model),
            "threshold_gap_mm": threshold_gaps(rest / "skin" if model != "gaussian" else None),
        }
        if args.breathing:
            root = run_scene(variant("fruit-breathing", model, out), out)
            sens = json.loads((root / "sensitivity" / "sensitivity.json").read_text())
            model_shift = np.array([t["max_shift_model"] for t in sens["taxels"]])
            entry["breathing"] = {
                "played_max_shift": sens["summary"]["max_shift"],
                "model_max_shift": sens["summary"]["max_shift_model"],
                "model_max_abs_shift": {
                    "max": float(np.abs(model_shift).max()),
                    "mean": float(np.abs(model_shift).mean()),
                },
            }
        report[model] = entry
    (out / "comparison.json").write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


def _rows(root: Path) -> list[dict]:
    summary = json.loads((root / "evaluate" / "summary.json").read_text())
    return [{"label": label, **row} for label, row in summary.items()]


if __name__ == "__main__":
    main()
