"""A sweep's tables and plot: sweep.csv, sweep.md (one row per variant: its values, the
figures of its stages, its status) and sweep.png (a figure against one or two swept
keys)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from fruitcli.studies.sweep import fmt_value

FIGURE_ORDER = ["taxels", "tets", "states", "newton_its", "max_disp_mm", "state_ms"]
TAIL = [
    "noise_std_max_counts",
    "shift_max_counts",
    "shift_mean_counts",
    "variant_s",
    "status",
    "error",
]
UNITS = (
    "units: *_mm in mm, state_ms in ms (median time per FEM state), variant_s in s "
    "(wall time of the variant's own stages), *_counts in CDC counts; "
    "*_n: Table I sample count"
)


def columns(rows: Sequence[dict | None], keys: list[str]) -> list[str]:
    """variant, the swept keys, the figures present in some row (a stable order), status."""
    present = list(dict.fromkeys(c for r in rows if r for c in r))  # first seen first
    known = set(keys) | set(FIGURE_ORDER) | set(TAIL) | {"variant"}
    extra = [c for c in present if c not in known]  # Table I: <row>_n, _mean_mm, _std_mm
    return (
        ["variant", *keys]
        + [c for c in FIGURE_ORDER if c in present]
        + extra
        + [c for c in TAIL if c in present or c in ("status", "error")]
    )


def cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return (
            f"{value:.6g}"
            if not math.isfinite(value) or abs(value) >= 1e6
            else f"{value:.6f}".rstrip("0").rstrip(".") or "0"
        )
    if isinstance(value, (list, dict, bool)) or not isinstance(value, (int, str)):
        return fmt_value(value)
    return str(value)


def write_csv(path: Path, rows: Sequence[dict | None], keys: list[str], comment: str) -> None:
    from fruitcli.fsutil import write_csv as write

    cols = columns(rows, keys)
    write(
        path, cols, ([cell(r.get(c)) for c in cols] for r in rows if r), comments=[comment, UNITS]
    )


def markdown(rows: Sequence[dict | None], keys: list[str], head: list[str]) -> str:
    cols = columns(rows, keys)
    lines = [*head, "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        if r is None:
            continue
        cells = [cell(r.get(c)).replace("|", "/") for c in cols]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def default_figure(rows: list[dict]) -> str | None:
    """The figure sweep.png shows unless told: the first Table I mean error, else the
    largest baseline shift, else the largest displacement, else the time per state."""
    present = [c for r in rows if r for c in r]
    for want in ("_mean_mm", "shift_max_counts", "max_disp_mm", "state_ms", "taxels"):
        hit = next((c for c in present if c.endswith(want)), None)
        if hit:
            return hit
    return None


def plot(path: Path, rows: list[dict], keys: list[str], figure: str) -> str:
    """sweep.png: `figure` against the first swept key, one line per value of the second.
    Returns a one-line note of what was drawn (or why nothing was)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    if len(keys) > 2:
        return f"sweep.png: not drawn (it shows one or two swept keys; this sweep has {len(keys)})"
    ok = [r for r in rows if r and r.get("status") == "ok" and _number(r.get(figure))]
    if not ok:
        return f"sweep.png: not drawn (no finished variant has {figure})"
    xkey = keys[0]
    xs_all = [r[xkey] for r in rows if r]
    numeric = all(_number(x) for x in xs_all)
    order = sorted(
        {fmt_value(x) for x in xs_all},
        key=lambda s: float(s) if numeric else [fmt_value(x) for x in xs_all].index(s),
    )
    pos = {s: n for n, s in enumerate(order)}
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    groups: dict[str, list[dict]] = {}
    for r in ok:
        label = f"{keys[1]} = {fmt_value(r[keys[1]])}" if len(keys) == 2 else figure
        groups.setdefault(label, []).append(r)
    for label, group in groups.items():
        pts = sorted(
            ((float(r[xkey]) if numeric else pos[fmt_value(r[xkey])]), r[figure]) for r in group
        )
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=label)
    failed = [r for r in rows if r and r.get("status") != "ok"]
    if not numeric:
        ax.set_xticks(range(len(order)), order, rotation=20)
    ax.set_xlabel(xkey)
    ax.set_ylabel(axis_label(figure))
    title = f"{axis_label(figure)} against {xkey}"
    if failed:
        title += f" ({len(failed)} failed variant(s) not shown)"
    ax.set_title(title, fontsize=10)
    ax.grid(True, color="0.85")
    if len(groups) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return f"sweep.png: {figure} against {xkey}" + (
        f", one line per {keys[1]}" if len(keys) == 2 else ""
    )


LABELS = {
    "taxels": "taxels",
    "tets": "tetrahedra",
    "states": "FEM states",
    "newton_its": "Newton iterations per state, mean",
    "max_disp_mm": "largest displacement (mm)",
    "state_ms": "time per FEM state (ms)",
    "noise_std_max_counts": "noise std, largest (counts)",
    "shift_max_counts": "baseline shift, largest (counts)",
    "shift_mean_counts": "baseline shift, mean over taxels (counts)",
    "variant_s": "time per variant (s)",
}


def axis_label(figure: str) -> str:
    """`bent-small_mean_mm` -> `bent-small: localization error, mean (mm)`."""
    for suffix, text in (
        ("_mean_mm", "localization error, mean (mm)"),
        ("_std_mm", "localization error, std (mm)"),
        ("_n", "sample points"),
    ):
        if figure.endswith(suffix) and figure not in LABELS:
            return f"{figure[: -len(suffix)]}: {text}"
    return LABELS.get(figure, figure)


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
