"""`fruit demo`: the default experiments end to end, and `out/report.md`."""

from __future__ import annotations

import time
from pathlib import Path

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option

DEMO_SCENES = ["paper-table", "fruit-rest", "fruit-deformed", "fruit-breathing", "touchpad-4x4"]


def _pipelines_dir() -> Path:
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "pipelines").is_dir():
            return parent / "pipelines"
    return Path("pipelines")


@click.command()
@out_option("Output folder: one sub-folder per scene, report.md.", required=False, default="out")
@click.option("--scenes", default=",".join(DEMO_SCENES), show_default=True,
              help="Comma-separated scene names from pipelines/.")
def demo(out_dir, scenes):
    """Run the default experiments (the paper's Table I, the Fruit at rest, in its jig,
    breathing, and the bent 4x4 pad) and write OUT/report.md.

    Unchanged stages are reused, so a second run finishes in seconds.
    """
    from fruitcli.scene import load_scene
    from fruitcli.workflow import planner
    from fruitcli.workflow.report import write_report

    out = Path(out_dir)
    plans, seconds = {}, {}
    with fruit_errors():
        names = [s.strip() for s in scenes.split(",") if s.strip()]
        if not names:
            raise click.UsageError("--scenes: expected at least one scene name from pipelines/")
        loaded = [load_scene(_pipelines_dir() / f"{name}.toml") for name in names]  # all first
        for name, scene in zip(names, loaded, strict=True):
            click.echo(f"== {name} ==", err=True)
            t0 = time.perf_counter()
            steps = planner.run(scene, out / scene.name, progress=Progress("   "), shared=out)
            plans[scene.name] = planner.format_plan(steps)
            seconds[scene.name] = (time.perf_counter() - t0,
                                   sum(s.action == "run" for s in steps),
                                   sum(s.action == "reuse" for s in steps))
        report = write_report(out, plans, seconds)
    click.echo(f"report: {report}")
