"""The sensing stages: skin (the crossing's table of an electrostatic skin), bench (the
virtual 3D-printer bench's frames and truth), locate (touches in 3D), evaluate (located
against true points) and sensitivity (noise and baseline shift per taxel). The heavy
modules are imported only when a stage runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.workflow.fem_stages import locate_uses_reduced
from fruitcli.workflow.stage_paths import (
    DEFORMS,
    crossing_dir,
    electrostatic,
    geometry_kind,
    indenters,
    no_inputs,
    reduced_path,
    required_taxels_path,
    solid_path,
    states_path,
    taxels_path,
)
from fruitcli.workflow.stage_types import Stage

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.workflow.stage_types import Context


# ----------------------------------------------------------------------------- skin
def _skin_needed(scene: Scene):
    if not electrostatic(scene):
        return False, f"[skin].model = {scene.skin.model!r}: no crossing table"
    users = [s for s in ("bench", "sensitivity") if scene.has(s)]
    if not users:
        return False, "no [bench] or [sensitivity] to use the crossing's table"
    return True, f"electrostatic skin for the {' and '.join(users)}: the crossing's table"


def _skin_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.electrostatics import design

    table, summary = design.run_crossing(design.crossing_inputs(scene), progress=ctx.progress)
    design.write_outputs(out_dir, table, summary)
    return {
        "c0_ff": summary["c0_ff"],
        "counts_per_ff": summary["counts_per_ff"],
        "contact_counts": {k: v["contact_counts"] for k, v in summary["objects"].items()},
    }


# ----------------------------------------------------------------------------- sensing
def _bench_needed(scene: Scene):
    if not scene.has("bench"):
        return False, "no [bench]: no virtual 3D-printer bench"
    return True, f"virtual bench, indenters: {', '.join(indenters(scene))}"


def _bench_inputs(scene: Scene, ctx: Context):
    from fruitcli.scene import resolve_path

    # [bench].samples is a string key ("quarter" or a CSV path): the CSV by its content
    spec = scene.bench.samples
    return {} if spec == "quarter" else {"samples": Path(resolve_path(scene.path, spec))}


def _bench_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.sensing.stages import run_bench

    solid = solid_path(scene, ctx)
    unit = scene.geometry.unit if geometry_kind(scene) == "solid" else "mm"
    return run_bench(
        scene,
        required_taxels_path(scene, ctx),
        states_path(scene, ctx),
        out_dir,
        progress=ctx.progress,
        surface_path=solid,
        surface_unit=unit,
        crossing_dir=crossing_dir(scene, ctx),
    )


def _frame_sources(scene: Scene, ctx: Context) -> dict[str, Path]:
    if scene.has("bench"):
        return {ind: ctx.dir("bench") / ind / "frames.npz" for ind in indenters(scene)}
    if scene.frames.recording is not None:
        return {"recording": scene.frames.recording}
    return {}


def _locate_needed(scene: Scene):
    if scene.has("bench"):
        return True, "detect touches in the bench frames, map them to 3D"
    if scene.frames.recording is not None:
        return True, "detect touches in the recording, map them to 3D"
    return False, "no frames: no recording and no bench"


def _locate_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.sensing.stages import LocateFiles, locate_inputs, run_locate

    out = {}
    unit = scene.geometry.unit if geometry_kind(scene) == "solid" else "mm"
    reduced = None
    if locate_uses_reduced(scene):
        from fruitcli.fem.reduced.model import load

        reduced = load(reduced_path(scene, ctx))
    for name, frames in _frame_sources(scene, ctx).items():
        taxels = taxels_path(scene, ctx)
        assert taxels is not None, "a scene with frames has its taxels (the scene's checks)"
        inputs = locate_inputs(scene, crossing_dir=crossing_dir(scene, ctx), reduced=reduced)
        files = LocateFiles(
            frames,
            taxels,
            states_path(scene, ctx),
            out_dir / name,
            solid_path(scene, ctx),
            unit,
        )
        out[name] = run_locate(inputs, files, ctx.progress)
    return out


def _locate_outputs(scene: Scene):
    if scene.has("bench"):
        return [f"{ind}/touches.csv" for ind in indenters(scene)]
    return ["recording/touches.csv"]


# ----------------------------------------------------------------------------- evaluate
def _eval_rows(scene: Scene, ctx: Context) -> list[dict]:
    rows = scene.values("evaluate")
    if scene.has("bench"):
        config = scene.scene.configuration
        for ind in indenters(scene):
            rows.append(
                {
                    "label": f"{config}, {ind}",
                    "truth": ctx.dir("bench") / ind / "truth.csv",
                    "measured": ctx.dir("locate") / ind / "measured.csv",
                    "reference_length_mm": scene.bench.reference_length_mm,
                    "register": scene.bench.register,
                }
            )
    return rows


def _eval_needed(scene: Scene):
    if scene.has("bench"):
        return True, "bench ground truth against located touches"
    if scene.evaluate:
        return True, "evaluation only: measured points given"
    return False, "no ground truth"


def _eval_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.evaluation.report import evaluate_pair, write_many

    results = [
        evaluate_pair(
            r["truth"], r["measured"], r["reference_length_mm"], r["label"], r["register"]
        )
        for r in _eval_rows(scene, ctx)
    ]
    summaries = write_many(out_dir, results)
    return {
        s["label"]: {
            k: round(v, 4) if isinstance(v, float) else v for k, v in s.items() if k != "label"
        }
        for s in summaries
    }


# ----------------------------------------------------------------------------- sensitivity
def _sens_needed(scene: Scene):
    if not scene.has("sensitivity"):
        return False, "no [sensitivity]"
    return True, "noise std at rest and baseline shift over the states"


def _sens_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.sensing.stages import run_sensitivity

    return run_sensitivity(
        scene,
        required_taxels_path(scene, ctx),
        states_path(scene, ctx),
        out_dir,
        progress=ctx.progress,
        crossing_dir=crossing_dir(scene, ctx),
    )


# ----------------------------------------------------------------------------- the table's entries
SKIN_STAGE = Stage(
    "skin",
    [],
    "fruitcli.electrostatics",
    _skin_needed,
    no_inputs,
    _skin_run,
    lambda s: ["crossing.npz", "summary.json"],
    reads=(  # design.crossing_inputs
        "skin.model",
        "skin.yarn_radius_mm",
        "skin.insulation_mm",
        "skin.permittivity",
        "skin.gaps_mm",
        "tracks.cover_mm",
        "tracks.track_radius_mm",
        "grid.spacing_x_mm",
        "grid.spacing_y_mm",
        "mesh.time_limit_s",
    ),
    decides=("bench", "sensitivity"),
)


BENCH_STAGE = Stage(
    "bench",
    ["simulate", "make-tracks", "pad-grid", "skin"],
    "fruitcli.sensing.stages",
    _bench_needed,
    _bench_inputs,
    _bench_run,
    lambda s: [f"{i}/frames.npz" for i in indenters(s)] + [f"{i}/truth.csv" for i in indenters(s)],
    reads=(*DEFORMS, "bench", "board", "skin", "grid", "geometry")
    + ("detection.threshold_counts", "scene.name"),
)


LOCATE_STAGE = Stage(
    "locate",
    ["bench", "simulate", "reduce", "skin", "make-tracks", "pad-grid"],
    "fruitcli.sensing.stages",
    _locate_needed,
    no_inputs,
    _locate_run,
    _locate_outputs,
    reads=(*DEFORMS, "frames", "bench", "board", "detection", "skin", "grid", "geometry"),
)


EVALUATE_STAGE = Stage(
    "evaluate",
    ["locate", "bench"],
    "fruitcli.evaluation.report",
    _eval_needed,
    no_inputs,
    _eval_run,
    lambda s: ["table.md", "table.csv", "summary.json"],
    reads=("evaluate", "bench", "scene.configuration"),
)


SENSITIVITY_STAGE = Stage(
    "sensitivity",
    ["simulate", "make-tracks", "pad-grid", "skin"],
    "fruitcli.sensing.stages",
    _sens_needed,
    no_inputs,
    _sens_run,
    lambda s: ["sensitivity.json"],
    reads=(*DEFORMS, "sensitivity", "bench", "skin", "detection", "grid", "geometry"),
)
