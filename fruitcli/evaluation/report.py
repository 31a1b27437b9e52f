"""Evaluation outputs: errors.csv, table.md, table.csv, summary.json and the view plots."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from fruitcli.evaluation.metrics import match, read_points, summarize
from fruitcli.evaluation.plots import save_pair_views
from fruitcli.fsutil import staged_dir, write_csv, write_json, write_text

TABLE_HEADER = ["label", "n", "dims", "mean_mm", "std_mm", "mean_pct", "std_pct",
                "reference_length_mm"]


def slug(label: str) -> str:
    """A file-system friendly version of a row label ('Rest, small' -> 'rest-small')."""
    return re.sub(r"[^a-z0-9]+", "-", label.lower()).strip("-") or "row"


def evaluate_pair(truth_path, measured_path, reference_length_mm: float | None = None,
                  label: str = "result") -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """Match and summarize one truth/measured pair. Returns (summary, sample, truth, meas)."""
    truth, measured = read_points(truth_path), read_points(measured_path)
    sample, t, m = match(truth, measured)
    summary = summarize(t, m, reference_length_mm)
    summary = {"label": label, **summary}
    return summary, sample, t, m


def table_markdown(rows: list[dict]) -> str:
    """Table I layout: one row per label, mean and std in mm and %."""
    lines = ["| Configuration | n | data | Avg. error | Error std |",
             "|---|---|---|---|---|"]
    for r in rows:
        view = "3D" if r["dims"] == 3 else "top view (x, y)"
        lines.append(f"| {r['label']} | {r['n']} | {view} | {r['mean_mm']:.2f} mm "
                     f"({r['mean_pct']:.1f} %) | {r['std_mm']:.2f} mm ({r['std_pct']:.1f} %) |")
    ref = {round(r["reference_length_mm"], 1) for r in rows}
    lines.append("")
    lines.append(f"Percentages relative to the reference length ({', '.join(map(str, ref))} mm); "
                 "std is the population standard deviation.")
    return "\n".join(lines) + "\n"


def _table_rows(rows):
    return [[r["label"], r["n"], r["dims"], *(round(r[k], 4) for k in TABLE_HEADER[3:])]
            for r in rows]


def write_single(out_dir: str | Path, summary: dict, sample, truth, measured) -> None:
    """Write every output of one evaluation into `out_dir` (all or nothing)."""
    with staged_dir(out_dir) as tmp:
        _write_files(tmp, summary, sample, truth, measured)
        write_text(tmp / "table.md", table_markdown([summary]))
        write_csv(tmp / "table.csv", TABLE_HEADER, _table_rows([summary]))


def _write_files(folder: Path, summary, sample, truth, measured):
    d = truth.shape[1]
    axes = ["x", "y", "z"][:d]
    err = measured - truth
    header = (["sample"] + [f"truth_{a}_mm" for a in axes] + [f"measured_{a}_mm" for a in axes]
              + [f"error_{a}_mm" for a in axes] + ["error_mm"])
    rows = [[int(s), *t, *m, *e, float(np.linalg.norm(e))]
            for s, t, m, e in zip(sample, truth, measured, err, strict=True)]
    view = "3D (x, y, z)" if d == 3 else "top view (x, y) only: no z in the data"
    write_csv(folder / "errors.csv", header, rows,
              comments=[f"{summary['label']}: {view}", "units: mm"])
    write_json(folder / "summary.json", {k: summary[k] for k in TABLE_HEADER[1:]})
    save_pair_views(folder, truth, measured, summary["label"])


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
