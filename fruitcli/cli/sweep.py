"""`fruit sweep SCENE --set KEY=V1,V2,...`: a scene run for many values of its keys."""

from __future__ import annotations

import contextlib
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from fruitcli.cli.options import (
    FiniteFloat,
    claim_out,
    fruit_errors,
    jobs_option,
    out_option,
    quiet,
    scheduler_option,
)

if TYPE_CHECKING:
    from fruitcli.studies.sweep import Variant

FIGURES = (
    "taxels",
    "tets",
    "states",
    "newton_its",
    "max_disp_mm",
    "state_ms",
    "noise_std_max_counts",
    "shift_max_counts",
    "shift_mean_counts",
    "variant_s",
    "c0_ff",
    "counts_per_ff",
    "bend_shift_max_counts",
    "bend_margin_counts",
)
TABLE_I = re.compile(r".+_(n|mean_mm|std_mm)$|contact_counts_.+")


@click.command()
@click.argument("scene_file", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option(
    "--set",
    "sets",
    multiple=True,
    metavar="KEY=V1,V2,...",
    help="A scene key and its values, e.g. mesh.size_mm=3,5 or "
    "geometry.chamber.c1.radii_mm=[10,10,4],[12,10,4]. Repeat for more keys.",
)
@click.option(
    "--grid/--zip",
    "grid",
    default=True,
    help="Every combination of the lists (default), or the i-th value of each "
    "list together (lists of one length).",
)
@out_option(
    "Output folder: sweep.csv, sweep.md, sweep.png, variants/<name>/. [default: "
    "out/sweep-<scene name>]",
    required=False,
)
@jobs_option("Local worker processes")
@scheduler_option("the variants")
@click.option(
    "--connect-timeout",
    type=FiniteFloat(min=0.1),
    default=10.0,
    show_default=True,
    help="Seconds to wait for the scheduler and a worker.",
)
@click.option(
    "--plot",
    "figure",
    default=None,
    help="The figure sweep.png shows against the swept keys, a sweep.csv column "
    "(tets, max_disp_mm, state_ms, shift_max_counts, bend_margin_counts, "
    "<row>_mean_mm, ...). "
    "[default: the first Table I mean error, else the largest baseline "
    "shift, else the largest displacement]",
)
@click.option(
    "--dry-run",
    is_flag=True,
    help="List the variants and the stages they would share; run nothing.",
)
def sweep(
    scene_file, sets, grid, out_dir, jobs, scheduler, connect_timeout, figure, dry_run
) -> None:
    """Run SCENE for every combination (--grid) or zipped lists (--zip) of scene values.

    Each variant is validated like a scene file before anything runs; a bad key or value
    stops the sweep at once, naming it. Keys are written as in the scene file
    (section.key; geometry.chamber.<name>.<key>; jig.1.rotate_deg); values are TOML
    values, a bare word or path is a string. Each variant's stages go to OUT/variants/<name>/;
    stages that variants share (same inputs) run once. A variant that fails is a row with
    its error and the sweep goes on; running the same sweep again reuses every finished
    variant.
    """
    from fruitcli.scene import load_scene
    from fruitcli.studies.sweep import SweepError, build_variants, parse_set

    if jobs is not None and scheduler:
        raise click.UsageError("give --jobs or --scheduler, not both")
    if figure is not None and figure not in FIGURES and not TABLE_I.match(figure):
        raise click.BadParameter(
            f"{figure!r}: expected one of {', '.join(FIGURES)} or a "
            "Table I column <row>_n, <row>_mean_mm, <row>_std_mm or contact_counts_<object>",
            param_hint="--plot",
        )
    with fruit_errors():
        scene = load_scene(scene_file)
        try:
            specs = [parse_set(s) for s in sets]
            variants = build_variants(scene.path, specs, "grid" if grid else "zip")
        except SweepError as exc:
            raise click.BadParameter(str(exc).removeprefix("--set "), param_hint="--set") from None
        out = Path(out_dir) if out_dir else Path("out") / f"sweep-{scene.name}"
    # a given --out is claimed before the command runs; the default one here
    with claim_out(out) if out_dir is None else contextlib.nullcontext(), fruit_errors():
        if dry_run:
            _dry_run(variants, out)
            return
        _run(
            scene_file,
            variants,
            [s.key for s in specs],
            out,
            jobs,
            scheduler,
            connect_timeout,
            figure,
            "grid" if grid else "zip",
        )


def _dry_run(variants: list[Variant], out: Path) -> None:
    from fruitcli.studies.sweep_run import build_tasks, finished_row

    vdir = out.resolve() / "variants"
    todo = [k for k, v in enumerate(variants) if finished_row(v, vdir / v.name) is None]
    tasks = build_tasks(variants, vdir, todo)
    click.echo(f"{len(variants)} variants -> {out}/variants/")
    for k, v in enumerate(variants):
        click.echo(f"  {v.name}: {'run' if k in todo else 'reuse (finished before)'}")
    shared = [key for key in tasks if key[0] == "stage"]
    for key in shared:
        users = sum(
            1
            for t in tasks.values()
            if ("stage", *key[1:]) in t.deps and t.func.__name__ == "run_variant_task"
        )
        click.echo(f"  shared: {key[1]} (run once, used by {users} variants)")


def _run(
    scene_file: str | Path,
    variants: list[Variant],
    keys: list[str],
    out: Path,
    jobs: int | None,
    scheduler: str | None,
    timeout: float,
    figure: str | None,
    mode: str,
):
    from fruitcli.fsutil import write_text
    from fruitcli.studies import sweep_report as report
    from fruitcli.studies.executors import open_executor
    from fruitcli.studies.sweep_run import run_sweep

    silent = quiet()
    pool = open_executor(jobs, scheduler, out if scheduler else None, timeout)
    comment = (
        f"fruit sweep of {Path(scene_file).name}: {len(variants)} variants "
        f"({'every combination' if mode == 'grid' else 'zipped lists'} of "
        f"{', '.join(keys)})"
    )

    def write_tables(rows: Sequence[dict | None], head: list[str]):
        report.write_csv(out / "sweep.csv", rows, keys, comment)
        write_text(out / "sweep.md", report.markdown(rows, keys, head))

    def progress(done: int, total: int, row: dict | None):
        if silent:
            return
        if row is not None and "stage" in row:  # a stage several variants share
            state = f"failed ({row['error']})" if row["error"] else "done"
            click.echo(
                f"sweep: {done}/{total} variants, shared {row['stage']} {state} "
                f"(in {row['variant']})",
                err=True,
            )
            return
        last = (
            ""
            if row is None
            else (
                f", last: {row['variant']} "
                + ("ok" if row["status"] == "ok" else f"failed ({row['error']})")
            )
        )
        click.echo(f"sweep: {done}/{total} variants{last}", err=True)

    head = [f"# Sweep of {Path(scene_file).name}", "", f"{comment}; on {pool.name}."]
    try:
        if not silent:
            click.echo(f"sweep: {len(variants)} variants on {pool.name} -> {out}/", err=True)
        rows, stats = run_sweep(
            variants,
            out,
            pool,
            progress,
            on_row=lambda rows: write_tables(rows, head + ["(running)"]),
        )
    finally:
        pool.close()
    figure = figure or report.default_figure(rows)
    note = (
        report.plot(out / "sweep.png", rows, keys, figure)
        if figure
        else "sweep.png: not drawn (no figure in any row)"
    )
    if "not drawn" in note:
        (out / "sweep.png").unlink(missing_ok=True)  # a previous run's plot would mislead
    head += [
        "",
        f"{stats['run']} variant(s) ran, {stats['reused']} reused from a previous run "
        f"of this sweep, {stats['failed']} failed; {stats['shared_stages']} stage(s) "
        "shared between variants (run once, copied to the others).",
        f"Each variant's stages, log.txt and result.json: variants/<variant>/. {note}.",
    ]
    write_tables(rows, head)
    click.echo(report.markdown(rows, keys, []).lstrip("\n"), nl=False)
    click.echo(f"written to {out}/ ({stats['failed']} of {len(rows)} variants failed)")
    if stats["failed"] == len(rows):
        raise click.ClickException(
            f"every variant failed (first: {rows[0]['error']}); see {out}/sweep.md"
        )
