"""The demo's model rows of Table I: the bench's frames located by ``[detection] method =
"model"`` with a skin calibrated on another run (stage ``model-rows``, `fruit demo`).

Units: mm, counts. A fit handed the bench's own law and parameters would be scored on the
model that made its frames, so the locator here is not given the scene's [skin]: `fruit
calibrate` fits it (footprint width, counts at contact, gap decay, noise, gains) to a
second bench run of the same board at other sample points, half a pitch off each taxel
for the law and right over each taxel for its gain, with the small indenter
(`fruitcli.studies.locator_skins.calibrated_skin`), and the model method locates the
very frames the N9 rows were scored on. How many frames' mean it fits
(``[detection].model_frames``: the bench's indenter is still in x and y while it
descends) is chosen on the same calibration run's samples inside the taxels' outline
(`fruitcli.studies.model_frames`); the rows come with that setting and with the frame at
the threshold alone. The bench's law
family is still the locator's (a Gaussian board gets a Gaussian fit; an electrostatic board gets
the Gaussian law fitted to it): `fruit study locate` has the boards whose law differs.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.workflow.stage_types import Stage

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.workflow.stage_types import Context

MODEL_METHOD = "model"


def _needed(scene: Scene):
    if not scene.has("bench"):
        return False, "no [bench]: no frames to place by the model"
    return True, "bench frames located by the model with a skin calibrated on another run"


def _run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.evaluation.report import evaluate_pair, write_many
    from fruitcli.fsutil import write_json
    from fruitcli.sensing.stages import LocateFiles, locate_inputs, run_locate
    from fruitcli.studies import model_frames
    from fruitcli.studies.locator_skins import CALIBRATION_INDENTER, BenchBody, calibrated_skin
    from fruitcli.workflow import stage_paths as st

    out_dir = Path(out_dir)
    taxels, states = st.taxels_path(scene, ctx), st.states_path(scene, ctx)
    assert taxels is not None, "a scene with a bench has its taxels (the scene's checks)"
    surface = st.solid_path(scene, ctx)
    unit = scene.geometry.unit if st.geometry_kind(scene) == "solid" else "mm"
    board_table = st.crossing_dir(scene, ctx)
    ctx.progress("model-rows: calibrating the skin on another bench run")
    body = BenchBody(taxels, states, surface, unit)
    skin = calibrated_skin(scene, body, out_dir / "calibration", board_table)

    def locate(frames: int, bench: Path, folder: Path) -> None:
        run = replace(
            scene,
            sections={
                **scene.sections,
                "detection": replace(scene.detection, model_frames=frames),
            },
        )
        inputs = locate_inputs(run, method=MODEL_METHOD, skin_table=skin, crossing_dir=board_table)
        run_locate(inputs, LocateFiles(bench, taxels, states, folder, surface, unit))

    choice = model_frames.choose(
        locate,
        out_dir / "calibration" / "bench" / CALIBRATION_INDENTER,
        out_dir / "frames",
        lambda msg: ctx.progress(f"model-rows: {msg}"),
        outline_mm=body.taxels_mm(scene.bench.state),
    )
    chosen = choice.frames
    rows = {}
    for frames in sorted({1, chosen}):
        results = []
        for ind in st.indenters(scene):
            ctx.progress(f"model-rows: locating {ind} with the model, {frames} frame(s)")
            folder = out_dir / _folder(frames) / ind
            locate(frames, ctx.dir("bench") / ind / "frames.npz", folder)
            results.append(
                evaluate_pair(
                    ctx.dir("bench") / ind / "truth.csv",
                    folder / "measured.csv",
                    scene.bench.reference_length_mm,
                    f"{scene.scene.configuration}, {ind}",
                    scene.bench.register,
                )
            )
        summaries = write_many(out_dir / _folder(frames, "evaluate"), results)
        inds = st.indenters(scene)
        rows[str(frames)] = {
            s["label"]: {
                "model_share": model_share(out_dir / _folder(frames) / ind / "touches.csv")
            }
            | {k: v for k, v in s.items() if k != "label"}
            for s, ind in zip(summaries, inds, strict=True)
        }
    summary = {
        "calibration": {
            "board": scene.skin.model,
            "indenter": CALIBRATION_INDENTER,
            "samples": "half a pitch off each taxel and right over each taxel",
            "footprint_sigma_mm": _plain(skin.footprint_sigma_mm),
            "contact_counts": _plain(skin.contact_counts),
            "gap_decay_mm": _plain(skin.gap_decay_mm),
            "height_as_distance": _plain(skin.height_as_distance),
            "height_as_gap": _plain(skin.height_as_gap),
            "widening_per_mm": _plain(skin.widening_per_mm),
        },
        "model_frames": {
            "chosen": chosen,
            "calibration_error_mm": {str(k): round(v, 3) for k, v in choice.error_mm.items()},
            "calibration_samples": choice.samples_text(),
        },
        "rows": rows[str(chosen)],
        "rows_by_frames": rows,
    }
    write_json(out_dir / "summary.json", summary)
    return {"rows": len(rows[str(chosen)]), "model_frames": chosen}


def _folder(frames: int, what: str = "locate") -> str:
    """The folder of the rows located with the mean of `frames` frames."""
    return what if frames == 1 else f"{what}-{frames}-frames"


def _plain(value: object):
    """A calibrated [skin] value as JSON: numbers rounded, tables as dicts."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return round(float(value), 3) if isinstance(value, (int, float)) else value


def model_share(touches_csv: Path) -> float | None:
    """Share of the touches the model placed (its ``fit`` column says model); None when
    there are none."""
    import numpy as np

    from fruitcli.studies.locate_methods import model_fits

    share, _ = model_fits(touches_csv)
    return None if np.isnan(share) else round(share, 4)


def _reads():
    from fruitcli.workflow.stage_paths import DEFORMS

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
