"""`fruit demo`: the default experiments end to end, and `out/report.md`."""

from __future__ import annotations

import time
from pathlib import Path

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option

DEMO_SCENES = ["paper-table", "fruit-rest", "fruit-deformed", "fruit-breathing", "touchpad-4x4"]


@click.command()
@out_option("Output folder: one sub-folder per scene, report.md.", required=False, default="out")
@click.option(
    "--scenes",
    default=",".join(DEMO_SCENES),
    show_default=True,
    help="Comma-separated names of bundled scenes (see `fruit scenes`).",
)
def demo(out_dir, scenes) -> None:
    """Run the default experiments (the paper's Table I, the Fruit at rest, in its jig,
    breathing, and the bent 4x4 pad) and write OUT/report.md.

    Table I also gets, under each bench scene's N9 rows, rows located by the model
    method with a skin `fruit calibrate` fitted to a second bench run at other sample
    points (stage model-rows, OUT/<scene>/model-rows/).

    The scenes run from copies written to OUT/scenes/ (with the data they read), so
    the demo works from any folder; they are rewritten on every run (start an
    experiment of your own with `fruit scenes copy`). Unchanged stages are reused, so a
    second run finishes in seconds.
    """
    from fruitcli import bundled
    from fruitcli.scene import load_scene
    from fruitcli.workflow import planner
    from fruitcli.workflow.model_rows import MODEL_ROWS
    from fruitcli.workflow.report import write_report
    from fruitcli.workflow.stages import STAGES

    out = Path(out_dir)
    plans, seconds = {}, {}
    with fruit_errors():
        names = [s.strip() for s in scenes.split(",") if s.strip()]
        if not names:
            raise click.UsageError(
                "--scenes: expected at least one scene name (see `fruit scenes`)"
            )
        for name in names:  # every name checked before anything is written
            bundled.scene_path(name)
        loaded = [load_scene(bundled.export_scene(name, out / "scenes")) for name in names]
        for name, scene in zip(names, loaded, strict=True):
            click.echo(f"== {name} ==", err=True)
            t0 = time.perf_counter()
            steps = planner.run(
                scene,
                out / scene.name,
                progress=Progress("   "),
                stages=[*STAGES, MODEL_ROWS],
                shared=out,
            )
            plans[scene.name] = planner.format_plan(steps)
            seconds[scene.name] = (
                time.perf_counter() - t0,
                sum(s.action == "run" for s in steps),
                sum(s.action == "reuse" for s in steps),
            )
        report = write_report(out, plans, seconds)
    click.echo(f"report: {report}")
