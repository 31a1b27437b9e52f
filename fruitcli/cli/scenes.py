"""`fruit scenes`: the bundled example scenes, and editable copies of them."""

from __future__ import annotations

import tempfile
from pathlib import Path

import click

from fruitcli.cli.options import fruit_errors


def needed_stages(scene_file: Path) -> list[str]:
    """The stages the planner would run for a scene, in order."""
    from fruitcli.scene import load_scene
    from fruitcli.workflow import planner

    scene = load_scene(scene_file, must_exist=False)
    with tempfile.TemporaryDirectory() as empty:  # planned against no earlier outputs
        steps = planner.plan(scene, Path(empty))
    return [s.stage for s in steps if s.action != "not needed"]


@click.group(invoke_without_command=True)
@click.pass_context
def scenes(ctx) -> None:
    """List the bundled example scenes: what each shows and the stages it needs.

    `fruit scenes copy NAME DIR` starts an experiment of your own from one of them.
    """
    if ctx.invoked_subcommand is not None:
        return
    from fruitcli import bundled

    with fruit_errors():
        names = bundled.scene_names()
        width = max(len(n) for n in names)
        for name in names:
            path = bundled.scene_path(name)
            stages = ", ".join(needed_stages(path))
            click.echo(f"{name:<{width}}  {bundled.describe(path)} [stages: {stages}]")


@scenes.command()
@click.argument("name")
@click.argument("folder", type=click.Path(file_okay=False))
def copy(name, folder) -> None:
    """Write bundled scene NAME, and the data files it reads, into FOLDER (new or empty);
    then `fruit run FOLDER/NAME.toml`."""
    from fruitcli import bundled

    with fruit_errors():
        target = bundled.copy_scene(name, Path(folder))
    click.echo(f"{target}  (run it: fruit run {target})")
