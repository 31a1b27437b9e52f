"""Evaluation outputs: errors.csv, table.md, table.csv, summary.json and the view plots."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from fruitcli.evaluation.metrics import match, read_points, summarize
from fruitcli.evaluation.plots import save_pair_views
from fruitcli.fsutil import slug, staged_dir, write_csv, write_json, write_text

TABLE_HEADER = [
    "label",
    "n",
    "dims",
    "register",
    "mean_mm",
    "std_mm",
    "mean_pct",
    "std_pct",
    "rmse_mm",
    "median_mm",
    "p95_mm",
    "max_mm",
    "ci95_low_mm",
    "ci95_high_mm",
    "bias_x_mm",
    "bias_y_mm",
    "bias_z_mm",
    "unregistered_mean_mm",
    "translation_mean_mm",
    "reference_length_mm",
]
SUMMARY_KEYS = [
    "n",
    "dims",
    "register",
    "mean_mm",
    "std_mm",
    "mean_pct",
    "std_pct",
    "rmse_mm",
    "median_mm",
    "p95_mm",
    "max_mm",
    "ci95_mean_mm",
    "ci95_method",
    "bias_mm",
    "reference_length_mm",
    "transform",
    "transform_text",
    "compare",
]


def evaluate_pair(
    truth_path: str | Path,
    measured_path: str | Path,
    reference_length_mm: float | None = None,
    label: str = "result",
    register: str = "none",
) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """Match and summarize one truth/measured pair, the measurement registered by
    `register` (see `fruitcli.evaluation.register`). Returns (summary, sample, truth,
    measured as read)."""
    truth, measured = read_points(truth_path), read_points(measured_path)
    sample, t, m = match(truth, measured)
    summary = summarize(t, m, reference_length_mm, register, str(measured_path))
    summary = {"label": label, **summary}
    return summary, sample, t, m


def _view(r: dict) -> str:
    return "3D" if r["dims"] == 3 else "top view (x, y)"


def table_markdown(rows: list[dict]) -> str:
    """Table I layout (one row per label: mean and std in mm and %), then the other
    statistics, then per row the registration and what it changed."""
    lines = [
        "| Configuration | n | data | registration | Avg. error | Error std |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['label']} | {r['n']} | {_view(r)} | {r['register']} | "
            f"{r['mean_mm']:.2f} mm ({r['mean_pct']:.1f} %) | {r['std_mm']:.2f} mm "
            f"({r['std_pct']:.1f} %) |"
        )
    lines += [
        "",
        "| Configuration | RMSE | median | 95th pct. | max | 95 % CI of the mean "
        "| mean error vector (mm) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lo, hi = r["ci95_mean_mm"]
        bias = ", ".join(f"{round(v, 2) + 0.0:+.2f}" for v in r["bias_mm"])
        lines.append(
            f"| {r['label']} | {r['rmse_mm']:.2f} mm | {r['median_mm']:.2f} mm | "
            f"{r['p95_mm']:.2f} mm | {r['max_mm']:.2f} mm | {lo:.2f}-{hi:.2f} mm | "
            f"({bias}) |"
        )
    ref = {round(r["reference_length_mm"], 1) for r in rows}
    lines.append("")
    lines.append(
        f"Percentages relative to the reference length ({', '.join(map(str, ref))} mm); "
        "std is the population standard deviation; the interval is a seeded "
        "percentile bootstrap of the mean (10,000 resamples; the normal interval above "
        "2,000 samples); the mean error vector is measured - truth after the "
        "registration."
    )
    for r in rows:
        c = r["compare"]
        lines.append(
            f"- {r['label']}: {r['transform_text']}; mean error unregistered "
            f"{c['none']['mean_mm']:.2f} mm, translation-registered "
            f"{c['translation']['mean_mm']:.2f} mm."
        )
    return "\n".join(lines) + "\n"


def _table_rows(rows: Iterable[dict]):
    out = []
    for r in rows:
        bias = list(r["bias_mm"]) + [""] * (3 - len(r["bias_mm"]))
        values = [
            r["mean_mm"],
            r["std_mm"],
            r["mean_pct"],
            r["std_pct"],
            r["rmse_mm"],
            r["median_mm"],
            r["p95_mm"],
            r["max_mm"],
            *r["ci95_mean_mm"],
        ]
        out.append(
            [
                r["label"],
                r["n"],
                r["dims"],
                r["register"],
                *(round(v, 4) for v in values),
                *(round(v, 4) if v != "" else "" for v in bias),
                round(r["compare"]["none"]["mean_mm"], 4),
                round(r["compare"]["translation"]["mean_mm"], 4),
                round(r["reference_length_mm"], 4),
            ]
        )
    return out


def write_single(
    out_dir: str | Path, summary: dict, sample: np.ndarray, truth: np.ndarray, measured: np.ndarray
) -> None:
    """Write every output of one evaluation into `out_dir` (all or nothing)."""
    with staged_dir(out_dir) as tmp:
        _write_files(tmp, summary, sample, truth, measured)
        write_text(tmp / "table.md", table_markdown([summary]))
        write_csv(tmp / "table.csv", TABLE_HEADER, _table_rows([summary]))


def _write_files(
    folder: Path, summary: dict, sample: np.ndarray, truth: np.ndarray, measured: np.ndarray
):
    d = truth.shape[1]
    axes = ["x", "y", "z"][:d]
    err = measured - truth
    header = (
        ["sample"]
        + [f"truth_{a}_mm" for a in axes]
        + [f"measured_{a}_mm" for a in axes]
        + [f"error_{a}_mm" for a in axes]
        + ["error_mm"]
    )
    columns = [sample[:, None], truth, measured, err, np.linalg.norm(err, axis=1)[:, None]]
    comments = [
        f"{summary['label']}: {view_text(d)}",
        "units: mm",
        "measured and error (measured - truth) as read, not registered",
    ]
    if summary["register"] != "none":
        moved = _transform(summary).apply(measured)
        header += [f"registered_{a}_mm" for a in axes] + ["registered_error_mm"]
        columns += [moved, np.linalg.norm(moved - truth, axis=1)[:, None]]
        comments.append(f"registered: the measurement after the {summary['transform_text']}")
    table = np.hstack([np.asarray(c, dtype=float) for c in columns])
    rows = [[int(row[0]), *map(float, row[1:])] for row in table]
    write_csv(folder / "errors.csv", header, rows, comments=comments)
    write_json(folder / "summary.json", {k: summary[k] for k in ["label", *SUMMARY_KEYS]})
    shown = _transform(summary).apply(measured)
    save_pair_views(
        folder,
        truth,
        shown,
        summary["label"] + ("" if summary["register"] == "none" else f" ({summary['register']})"),
    )


def view_text(d: int) -> str:
    return "3D (x, y, z)" if d == 3 else "top view (x, y) only: no z in the data"


def _transform(summary: dict):
    from fruitcli.evaluation.register import Transform

    t = summary["transform"]
    return Transform(
        t["method"], np.asarray(t["rotation"]), np.asarray(t["translation_mm"]), t["scale"]
    )


def write_many(out_dir: str | Path, results: list[tuple]) -> list[dict]:
    """Several labelled rows: one sub-folder per label plus a combined table."""
    summaries = [r[0] for r in results]
    with staged_dir(out_dir) as tmp:
        for summary, sample, truth, measured in results:
            sub = tmp / slug(summary["label"])
            sub.mkdir()
            _write_files(sub, summary, sample, truth, measured)
        write_text(tmp / "table.md", table_markdown(summaries))
        write_csv(tmp / "table.csv", TABLE_HEADER, _table_rows(summaries))
        write_json(tmp / "summary.json", {slug(s["label"]): s for s in summaries})
    return summaries
