"""The paper's observations of its skin (Sec. V-A, Table I) and a run's numbers for them,
read from the files the run's stages wrote: no solve of its own.

Units: mm, counts. A run's folder is a scene's output folder (``evaluate/``,
``sensitivity/``, ``skin/``, ``make-tracks/``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.scene import Scene

THRESHOLD_COUNTS = 20.0
"""The paper's touch threshold (Sec. V-A)."""

PAPER = {
    "pretouch": 'the threshold is "very light touch or even pre-touch" (Sec. V-A): '
    "crossed at contact or a little above it",
    "bent_pad": "at most 10 counts, below the threshold (Sec. V-A, Fig. 9); "
    "the yarn it was bent along is not given",
    "finger_back": "a finger behind the bent 3 mm pad triggers a touch (Sec. V-A, Fig. 8 (c))",
    "breathing": "max 16, mean 5.0 counts (the mean over taxels of each one's largest "
    "shift); the largest at the tip, put down to fabrication (Sec. V-A, Fig. 11)",
    "noise": "std at most 1.9 counts over 300 frames at rest (Sec. V-A, Fig. 10)",
}

PAPER_TABLE_I = {
    "Rest, small": (2.6, 1.7, 1.3, 0.8),
    "Rest, medium": (3.3, 2.2, 1.7, 1.1),
    "Deformed, small": (4.4, 2.8, 1.8, 1.1),
}
"""The paper's Table I (published values, for comparison only), after a translation
registration: mean mm, mean %, std mm, std %."""


def _load(path: Path):
    try:
        return json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return None


def table_i(root: Path) -> dict[str, dict]:
    """Table I's rows of a run (label -> n, mean_mm, std_mm), translation-registered as
    the paper's; {} when the run has no evaluation."""
    summary = _load(Path(root) / "evaluate" / "summary.json") or {}
    rows = {}
    for row in summary.values():
        reg = (row.get("compare") or {}).get("translation")
        if reg is None and row.get("register") == "translation":
            reg = row
        if reg is not None:
            rows[row["label"]] = {
                "n": row["n"],
                "mean_mm": reg["mean_mm"],
                "std_mm": reg["std_mm"],
            }
    return rows


def sensitivity(root: Path) -> dict | None:
    """The noise and the baseline shifts of a run's sensitivity stage: the largest and
    mean noise std, the largest and mean per-taxel shift as played with noise (what a
    recording gives, as the paper's) and of the model alone (its largest positive
    shift), and the taxel with the largest played shift (i, j, its fabrication factor,
    its position in mm when the run's taxels are there)."""
    data = _load(Path(root) / "sensitivity" / "sensitivity.json")
    if not data:
        return None
    summ = data["summary"]
    taxels = data["taxels"]
    top = max(taxels, key=lambda t: t["max_shift"])
    where = {"i": top["i"], "j": top["j"], "fab": top["fab"]}
    csvs = [Path(root) / stage / "taxels.csv" for stage in ("make-tracks", "pad-grid")]
    csv = next((c for c in csvs if c.exists()), None)
    if csv is not None:
        from fruitcli.tables import read_taxels

        tax = read_taxels(csv)
        k = np.flatnonzero(tax.ids == top["id"])
        if k.size:
            where["xyz_mm"] = [float(v) for v in tax.xyz_mm[k[0]]]
    return {
        "noise_max": summ["std"]["max"],
        "noise_mean": summ["std"]["mean"],
        "played_max": summ["max_shift"]["max"],
        "played_mean": summ["max_shift"]["mean"],
        "model_max": summ["max_shift_model"]["max"],
        "model_mean": summ["max_shift_model"]["mean"],
        "where": where,
    }


def gaussian_pretouch_mm(contact_counts: float, gap_decay_mm: float) -> float:
    """Gap (mm) at which the assumed skin's taxel under the indenter reads the threshold:
    contact_counts exp(-gap / gap_decay) = 20 (0 when contact is already below it)."""
    if contact_counts <= THRESHOLD_COUNTS:
        return 0.0
    return gap_decay_mm * math.log(contact_counts / THRESHOLD_COUNTS)


def pretouch(root: Path, scene: Scene | None = None) -> dict | None:
    """Per object: (gap mm at which it crosses the threshold, counts at contact) under
    the crossing: from the run's crossing table (``skin/summary.json``) for the
    electrostatic skin, else from the scene's ``[skin]`` (the same for every indenter)."""
    summary = _load(Path(root) / "skin" / "summary.json")
    if summary:
        return {
            name: (o["threshold_gap_mm"], o["contact_counts"])
            for name, o in summary["objects"].items()
        }
    if scene is None:
        return None
    skin = scene.skin
    gap = gaussian_pretouch_mm(skin.contact_counts, skin.gap_decay_mm)
    return {name: (gap, skin.contact_counts) for name in scene.bench.indenters}


def fmt_table_i(rows: dict, label: str) -> str:
    """'mean +- std mm (n)' of a Table I row, or 'not run'."""
    r = rows.get(label)
    return f"{r['mean_mm']:.2f} ± {r['std_mm']:.2f} mm (n = {r['n']})" if r else "not run"


def fmt_pretouch(values: dict | None) -> tuple[str, str]:
    """('small 0.30, medium 3.66 mm', 'small 22.9, medium 88.1 counts') or dashes."""
    if not values:
        return "-", "-"
    gaps = ", ".join(f"{k} {g:.2f}" for k, (g, _) in values.items()) + " mm"
    counts = ", ".join(f"{k} {c:.1f}" for k, (_, c) in values.items()) + " counts"
    return gaps, counts


def fmt_where(where: dict) -> str:
    """'taxel (i, j) at (x, y, z) mm, fabrication factor f'."""
    at = ""
    if "xyz_mm" in where:
        at = " at (" + ", ".join(f"{v:.0f}" for v in where["xyz_mm"]) + ") mm"
    return f"taxel ({where['i']}, {where['j']}){at}, fabrication factor {where['fab']:.2f}"


def scene_of(out: Path, name: str) -> Scene | None:
    """The scene a run of `name` ran from (``OUT/scenes/NAME.toml``, as `fruit demo`
    writes it), or None."""
    from fruitcli.errors import FruitError
    from fruitcli.scene import load_scene

    path = Path(out) / "scenes" / f"{name}.toml"
    try:
        return load_scene(path) if path.exists() else None
    except FruitError:
        return None


def run_rows(out: Path, names: list[str]) -> list[tuple[str, str, str]]:
    """(observation, paper, this run) for the scenes `names` run into `out` (the demo's
    fruit-rest, fruit-deformed, fruit-breathing and touchpad-4x4), from their outputs;
    an observation whose scene did not run says so."""
    out = Path(out)
    have = set(names)
    rows = []
    rest = out / "fruit-rest"
    if "fruit-rest" in have:
        gaps, counts = fmt_pretouch(pretouch(rest, scene_of(out, "fruit-rest")))
        rows.append(
            (
                "pre-touch: gap at which the crossing under the indenter reads 20 counts "
                f"(counts at contact: {counts})",
                PAPER["pretouch"],
                gaps,
            )
        )
    else:
        rows.append(("pre-touch", PAPER["pretouch"], "not run (fruit-rest)"))
    pad = sensitivity(out / "touchpad-4x4") if "touchpad-4x4" in have else None
    rows.append(
        (
            "4 x 4 pad bent 180 deg (the jig bends it along x): largest shift",
            PAPER["bent_pad"],
            f"{pad['played_max']:.1f} counts with noise, {pad['model_max']:.1f} the model "
            "alone's largest rise; along y: `python tests/performance/compare_skins.py`"
            if pad
            else "not run (touchpad-4x4)",
        )
    )
    rows.append(
        (
            "finger behind the bent pad",
            PAPER["finger_back"],
            "not part of the demo: the electrostatic crossing is solved with a finger on "
            "the back and on the front of the 3 mm pad by `python "
            "tests/performance/compare_skins.py` (the skin model page's observations)",
        )
    )
    breath = sensitivity(out / "fruit-breathing") if "fruit-breathing" in have else None
    rows.append(
        (
            "the Fruit breathing: each taxel's largest shift, max and mean over taxels",
            PAPER["breathing"],
            f"max {breath['played_max']:.1f}, mean {breath['played_mean']:.1f} counts "
            f"with noise (the model alone, its largest rise: max {breath['model_max']:.1f}, mean "
            f"{breath['model_mean']:.1f}); the largest at {fmt_where(breath['where'])}"
            if breath
            else "not run (fruit-breathing)",
        )
    )
    rows.append(
        (
            "noise: std of each taxel at rest",
            PAPER["noise"],
            f"max {breath['noise_max']:.2f}, mean {breath['noise_mean']:.2f} counts "
            "(an input: `[skin].noise_std_counts`)"
            if breath
            else "not run (fruit-breathing)",
        )
    )
    table = {}
    for name in ("fruit-rest", "fruit-deformed"):
        if name in have:
            table.update(table_i(out / name))
    for label, (mean, _, std, _) in PAPER_TABLE_I.items():
        rows.append(
            (
                f"Table I, {label}: translation-registered error",
                f"{mean:.1f} ± {std:.1f} mm",
                fmt_table_i(table, label),
            )
        )
    return rows
