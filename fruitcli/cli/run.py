"""`fruit run SCENE`: run exactly the stages a scene needs, reusing unchanged ones."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import TYPE_CHECKING

import click

from fruitcli.cli.options import Progress, claim_out, fruit_errors, out_option
from fruitcli.workflow.scene_outputs import shared_outputs

if TYPE_CHECKING:
    from fruitcli.scene import Scene


def default_out(scene: Scene) -> Path:
    return Path("out") / scene.name


@click.command()
@click.argument("scene_file", metavar="SCENE", type=click.Path(dir_okay=False))
@out_option("Output folder; one sub-folder per stage. [default: out/<scene name>]", required=False)
@click.option(
    "--dry-run",
    is_flag=True,
    help="Print each stage as run, reuse or not needed, with the reason; run nothing.",
)
@click.option("--until", default=None, help="Stop after this stage (and what it needs).")
@click.option("--force", is_flag=True, help="Rerun every needed stage even if unchanged.")
def run(scene_file, out_dir, dry_run, until, force) -> None:
    """Run every stage SCENE needs, in dependency order.

    A stage is reused while its inputs and parameters are unchanged (its folder holds a
    manifest.json with a content hash of what went in). Stages a scene does not need
    (no chambers, no deformation, no artist mesh, ...) are left out and the plan says why.
    """
    from fruitcli.scene import gravity_left_out, load_scene
    from fruitcli.workflow import planner

    with fruit_errors():
        scene = load_scene(scene_file)
        dropped = gravity_left_out(scene)
        if dropped:
            click.echo(f"warning: {dropped}", err=True)
    out = Path(out_dir) if out_dir else default_out(scene)
    # a given --out is claimed before the command runs; the default one here
    with claim_out(out) if out_dir is None else contextlib.nullcontext(), fruit_errors():
        if dry_run:
            steps = planner.plan(scene, out, until=until, shared=shared_outputs(out))
            click.echo(f"plan for {scene_file} -> {out}/")
            click.echo(planner.format_plan(steps))
            return
        progress = Progress()
        steps = planner.run(
            scene, out, until=until, progress=progress, force=force, shared=shared_outputs(out)
        )
        click.echo(f"{scene.name}: done -> {out}/")
        click.echo(planner.format_plan(steps))
