"""The demo's model rows of Table I: the bench's frames located by ``[detection] method =
"model"`` with a skin calibrated on another run (stage ``model-rows``, `fruit demo`).

Units: mm, counts. A fit handed the bench's own law and parameters would be scored on the
model that made its frames, so the locator here is not given the scene's [skin]: `fruit
calibrate` fits it (footprint width, counts at contact, gap decay, noise, gains) to a
second bench run of the same board at other sample points, half a pitch off each taxel
with the small indenter (`fruitcli.studies.locate_methods.calibrated_skin`), and the
model method locates the very frames the N9 rows were scored on. The bench's law family
is still the locator's (a Gaussian board gets a Gaussian fit; an electrostatic board gets
the Gaussian law fitted to it): `fruit study locate` has the boards whose law differs.
"""

from __future__ import annotations

from pathlib import Path

from fruitcli.workflow.stage_types import Stage

MODEL_METHOD = "model"


def _needed(scene):
    if not scene.has("bench"):
        return False, "no [bench]: no frames to place by the model"
    return True, "bench frames located by the model with a skin calibrated on another run"


def _run(scene, ctx, out_dir):
    from fruitcli.evaluation.report import evaluate_pair, write_many
    from fruitcli.fsutil import write_json
    from fruitcli.sensing.stages import run_locate
    from fruitcli.studies.locate_methods import CALIBRATION_INDENTER, calibrated_skin
    from fruitcli.workflow import stages as st

    out_dir = Path(out_dir)
    taxels, states = st.taxels_path(scene, ctx), st.states_path(scene, ctx)
    surface = st.solid_path(scene, ctx)
    unit = scene.geometry.unit if st._geometry_kind(scene) == "solid" else "mm"
    board_table = st.crossing_dir(scene, ctx)
    ctx.progress("model-rows: calibrating the skin on another bench run")
    skin = calibrated_skin(
        scene, taxels, states, surface, unit, out_dir / "calibration", board_table
    )
    results = []
    for ind in st.indenters(scene):
        ctx.progress(f"model-rows: locating {ind} with the model")
        run_locate(
            scene,
            ctx.dir("bench") / ind / "frames.npz",
            taxels,
            states,
            out_dir / "locate" / ind,
            method=MODEL_METHOD,
            surface_path=surface,
            surface_unit=unit,
            skin_table=skin,
            crossing_dir=board_table,
        )
        results.append(
            evaluate_pair(
                ctx.dir("bench") / ind / "truth.csv",
                out_dir / "locate" / ind / "measured.csv",
                scene.bench.reference_length_mm,
                f"{scene.scene.configuration}, {ind}",
                scene.bench.register,
            )
        )
    summaries = write_many(out_dir / "evaluate", results)
    inds = st.indenters(scene)
    shares = {ind: model_share(out_dir / "locate" / ind / "touches.csv") for ind in inds}
    summary = {
        "calibration": {
            "board": scene.skin.model,
            "indenter": CALIBRATION_INDENTER,
            "samples": "half a pitch off each taxel",
            "footprint_sigma_mm": _plain(skin.footprint_sigma_mm),
            "contact_counts": _plain(skin.contact_counts),
            "gap_decay_mm": _plain(skin.gap_decay_mm),
        },
        "rows": {
            s["label"]: {"model_share": shares[ind]} | {k: v for k, v in s.items() if k != "label"}
            for s, ind in zip(summaries, inds, strict=True)
        },
    }
    write_json(out_dir / "summary.json", summary)
    return {"rows": len(summaries)}


def _plain(value):
    """A calibrated [skin] value as JSON: numbers rounded, tables as dicts."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return round(float(value), 3) if isinstance(value, (int, float)) else value


def model_share(touches_csv: Path) -> float | None:
    """Share of the touches the model placed (its ``fit`` column says model); None when
    there are none."""
    import numpy as np

    from fruitcli.studies.locate_methods import _model_share

    share = _model_share(touches_csv)
    return None if np.isnan(share) else round(share, 4)


def _reads():
    from fruitcli.workflow.stages import DEFORMS

    return (*DEFORMS, "bench", "board", "detection", "skin", "grid", "geometry") + (
        "scene.configuration",
        "scene.name",
    )


MODEL_ROWS = Stage(
    "model-rows",
    ["bench", "simulate", "skin", "make-tracks", "pad-grid"],
    "fruitcli.workflow.model_rows",
    _needed,
    lambda s, c: {},
    _run,
    lambda s: ["summary.json"],
    reads=_reads(),
)
