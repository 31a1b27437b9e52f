"""`fruit study`: the error-against-run-time and stability studies."""

from __future__ import annotations

from pathlib import Path

import click

from fruitcli.cli.options import fruit_errors, quiet


def _bar(label):
    silent = quiet()

    def progress(done, total):
        if not silent:
            click.echo(f"\r{label}: {done}/{total} cases", err=True, nl=done == total)

    return progress


@click.group()
def study():
    """Studies over many independent cases, run in parallel worker processes."""


@study.command()
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="out/study-stability",
              show_default=True, help="Output folder: stability.md, .csv, .json.")
@click.option("--jobs", type=int, default=None,
              help="Worker processes. [default: all cores]")
def stability(out_dir, jobs):
    """Stiff and extreme FEM cases: E 1 kPa..1 GPa, nu 0..0.499, pressure until elements
    would invert, jig stiffness 1e-3..1e6 N/mm, a sliver tet, an unsupported body.

    Each row: converged or the named failure, Newton iterations, load-step subdivisions,
    final residual, max displacement (mm), min det F, time (s).
    """
    from fruitcli.fsutil import staged_dir, write_csv, write_json, write_text
    from fruitcli.studies.parallel import run_cases
    from fruitcli.studies.stability import (
        HEADER,
        add_scaling_columns,
        default_cases,
        run_case,
        table_markdown,
    )

    with fruit_errors():
        cases = default_cases()
        rows = run_cases(run_case, cases, jobs, _bar("stability"))
        add_scaling_columns(rows)
        text = table_markdown(rows)
        with staged_dir(out_dir) as tmp:
            write_text(tmp / "stability.md", "# Stability study\n\n" + text)
            write_csv(tmp / "stability.csv", HEADER, [[r.get(h) for h in HEADER] for r in rows],
                      comments=["units: max_disp_mm in mm, seconds in s"])
            write_json(tmp / "stability.json", rows)
    click.echo(text, nl=False)
    click.echo(f"written to {Path(out_dir)}/")
