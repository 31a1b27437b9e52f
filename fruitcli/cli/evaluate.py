"""`fruit evaluate`: error tables and plots of measured points against ground truth."""

from __future__ import annotations

import click

from fruitcli.cli.options import FiniteFloat, fruit_errors, out_option
from fruitcli.evaluation.registrations import REGISTRATIONS


@click.command()
@click.option(
    "--truth",
    required=True,
    type=click.Path(dir_okay=False),
    help="Ground-truth CSV: sample,x_mm,y_mm[,z_mm].",
)
@click.option(
    "--measured",
    required=True,
    type=click.Path(dir_okay=False),
    help="Measured CSV with the same samples: sample,x_mm,y_mm[,z_mm].",
)
@out_option("Output folder (errors.csv, table.md, table.csv, summary.json, plots).")
@click.option(
    "--reference-length-mm",
    type=FiniteFloat(),
    default=None,
    help="Length for % errors in mm. [default: largest distance between two "
    "truth samples; the paper uses 152]",
)
@click.option("--label", default="result", show_default=True, help="Row label, e.g. 'Rest, small'.")
@click.option(
    "--register",
    type=click.Choice(list(REGISTRATIONS)),
    default="none",
    show_default=True,
    help="Map the measurement onto the truth before the errors are taken: "
    "translation removes the mean error vector (the paper's protocol), rigid "
    "is the least-squares rotation and translation, similarity adds one scale. "
    "Top-view (x, y) data: none or translation.",
)
def evaluate(truth, measured, out_dir, reference_length_mm, label, register) -> None:
    """Compare measured touch positions with ground truth, as in the paper's Table I.

    Samples are matched by their `sample` column. With z in both files the error is 3D;
    otherwise it is the top-view (x, y) error, and the outputs say so. The mean and the
    population standard deviation are given in mm and in % of the reference length, with
    the RMSE, median, 95th percentile, max, a bootstrap 95 % interval of the mean and the
    mean error vector; the transform found by --register is in summary.json and the table.
    """
    from fruitcli.errors import EvaluationError
    from fruitcli.evaluation.report import evaluate_pair, table_markdown, write_single

    with fruit_errors():
        if reference_length_mm is not None and not reference_length_mm > 0:
            raise EvaluationError(
                f"--reference-length-mm: expected a length > 0 mm, got {reference_length_mm}"
            )
        summary, sample, t, m = evaluate_pair(truth, measured, reference_length_mm, label, register)
        write_single(out_dir, summary, sample, t, m)
    view = "3D" if summary["dims"] == 3 else "top view (x, y) only"
    click.echo(f"{summary['n']} samples, {view}; written to {out_dir}/")
    click.echo(table_markdown([summary]), nl=False)
