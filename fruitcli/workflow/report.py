"""`out/report.md`: the demo's summary across scenes, built only from files the run wrote."""

from __future__ import annotations

import json
from pathlib import Path

from fruitcli.fsutil import write_text
from fruitcli.workflow.observations import PAPER_TABLE_I


def _load(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _mm_pct(stats: dict, ref: float) -> str:
    return (
        f"{stats['mean_mm']:.2f} ({100 * stats['mean_mm'] / ref:.1f} %) / "
        f"{stats['std_mm']:.2f} ({100 * stats['std_mm'] / ref:.1f} %)"
    )


def table_section(out: Path, scenes: list[str]) -> list[str]:
    """Table I like for like: every row unregistered and translation-registered (the
    paper's protocol), the paper's published row next to the registered one."""
    lines = [
        "## Table I: localization error, this model's bench next to the paper",
        "",
        "Avg. error / std in mm (and % of the reference length). The paper's published "
        "measurements were registered by a translation before its errors were taken "
        "(their mean error vector is zero to 1e-6 mm), so the paper's Table I is to be "
        "compared with the translation-registered column.",
        "",
        "| Configuration, indenter (source) | n | unregistered | translation-registered "
        "(paper's protocol) | paper's Table I | mean error vector, unregistered (mm) |",
        "|---|---|---|---|---|---|",
    ]
    seen, stats_rows, calibrations = set(), [], []
    for name in scenes:
        summary = _load(out / name / "evaluate" / "summary.json")
        if not summary:
            continue
        for row in summary.values():
            label = row["label"]
            compare = row.get("compare")
            if not compare:
                continue
            seen.add(label)
            ref = row["reference_length_mm"]
            paper = PAPER_TABLE_I.get(label)
            ptxt = (
                f"{paper[0]:.1f} ({paper[1]:.1f} %) / {paper[2]:.1f} ({paper[3]:.1f} %)"
                if paper
                else "-"
            )
            figure_data = name == "paper-table"
            source = "the paper's figure data" if figure_data else f"ours: {name}"
            none = ("already registered: " if figure_data else "") + _mm_pct(compare["none"], ref)
            bias = ", ".join(f"{round(v, 2) + 0.0:+.2f}" for v in compare["none"]["bias_mm"])
            lines.append(
                f"| {label} ({source}) | {row['n']} | {none} | "
                f"{_mm_pct(compare['translation'], ref)} | {ptxt} | ({bias}) |"
            )
            stats_rows.append((f"{label} ({source})", compare["translation"]))
        model_lines, how = model_rows(out, name, stats_rows)
        lines += model_lines
        calibrations += how
    for label, p in PAPER_TABLE_I.items():
        if label not in seen:
            lines.append(
                f"| {label} | - | not run | not run | {p[0]:.1f} ({p[1]:.1f} %) / "
                f"{p[2]:.1f} ({p[3]:.1f} %) | - |"
            )
    lines += [
        "",
        "Percentages are relative to the reference length of each row (152 mm as in "
        "the paper where set). The paper's deformed figure data are top view only; its "
        "table value is 3D. Translation registration removes the mean error vector; "
        "`fruit evaluate --register` also offers rigid and similarity.",
        "",
        *model_note(calibrations),
        "Translation-registered, more than mean and std (95 % CI: seeded bootstrap of "
        "the mean, n is small):",
        "",
        "| row | RMSE | median | 95th pct. | max | 95 % CI of the mean |",
        "|---|---|---|---|---|---|",
    ]
    for label, st in stats_rows:
        lo, hi = st["ci95_mean_mm"]
        lines.append(
            f"| {label} | {st['rmse_mm']:.2f} | {st['median_mm']:.2f} | "
            f"{st['p95_mm']:.2f} | {st['max_mm']:.2f} | {lo:.2f}-{hi:.2f} |"
        )
    return lines + [""]


def observations_section(out: Path, scenes: list[str]) -> list[str]:
    """The paper's observations next to this run's numbers for them (from the scenes'
    outputs; the other skin and what each depends on: docs, the skin model)."""
    from fruitcli.workflow.observations import run_rows, scene_of

    models = {s.skin.model for n in scenes if (s := scene_of(out, n)) is not None}
    skin = ", ".join(sorted(models)) or "as the scenes set it"
    lines = [
        "## The paper's observations against this run",
        "",
        f"Skin model: {skin} (`[skin].model`). Both skins against every observation, and "
        "the parameters each depends on: `python tests/performance/compare_skins.py` "
        "(the documentation's skin-model page).",
        "",
        "| observation | paper | this run |",
        "|---|---|---|",
    ]
    for row in run_rows(out, scenes):
        lines.append("| " + " | ".join(c.replace("|", r"\|") for c in row) + " |")
    return lines + [""]


def model_rows(out: Path, name: str, stats_rows: list) -> tuple[list[str], list[str]]:
    """Scene `name`'s Table I rows of the model method (stage ``model-rows``: the same
    bench frames, the skin calibrated on another run) and the line saying what the
    calibration gave; appends the registered statistics to `stats_rows`."""
    data = _load(out / name / "model-rows" / "summary.json")
    if not isinstance(data, dict) or not {"calibration", "rows"} <= data.keys():
        return [], []
    cal = data["calibration"]
    sigma = ", ".join(f"{k} {v:.2f}" for k, v in (cal["footprint_sigma_mm"] or {}).items())
    how = (
        f"- {name} (board's skin: {cal.get('board', '-')}; fitted: the Gaussian law): footprint "
        f"sigma (mm) {sigma or '-'}, {cal['contact_counts']:.1f} counts at contact, gap "
        f"decay {cal['gap_decay_mm']:.2f} mm"
    )
    if "height_as_gap" in cal:  # the height form (`fruit calibrate` keeps 1, 0 unless it pays)
        form = (cal["height_as_distance"], cal["height_as_gap"])
        how += (
            ", a crossing's height difference as 3D distance"
            if form == (1.0, 0.0)
            else f", a crossing's height difference as distance {form[0]:.2f} and as gap "
            f"{form[1]:.2f}"
        )
    if cal.get("widening_per_mm"):  # `fruit calibrate` keeps 0 unless it pays
        how += f", the footprint {100 * cal['widening_per_mm']:.1f} % wider per mm of gap"
    by_frames = data.get("rows_by_frames") or {"1": data["rows"]}
    chosen = str(data.get("model_frames", {}).get("chosen", 1))
    rows = []
    for frames in sorted(by_frames, key=int):
        for label, row in by_frames[frames].items():
            compare, ref = row["compare"], row["reference_length_mm"]
            share = row.get("model_share")
            placed = "" if share is None else f", {100 * share:.0f} % placed by the fit"
            mean_of = "the frame at the threshold" if frames == "1" else f"mean of {frames} frames"
            pick = (
                ", chosen on the calibration run" if len(by_frames) > 1 and frames == chosen else ""
            )
            source = f"ours: {name}, model, {mean_of}{pick}{placed}"
            bias = ", ".join(f"{round(v, 2) + 0.0:+.2f}" for v in compare["none"]["bias_mm"])
            rows.append(
                f"| {label} ({source}) | {row['n']} | {_mm_pct(compare['none'], ref)} | "
                f"{_mm_pct(compare['translation'], ref)} | - | ({bias}) |"
            )
            stats_rows.append((f"{label} ({source})", compare["translation"]))
    tried = data.get("model_frames", {}).get("calibration_error_mm")
    if tried:
        counted = data["model_frames"].get("calibration_samples")
        how += (
            "; the calibration run's touches placed by the mean of "
            + ", ".join(f"{k} frame(s) {v:.2f} mm" for k, v in tried.items())
            + " (translation-registered mean error"
            + (f" over {counted})" if counted else ")")
        )
    return rows, [how]


def model_note(calibrations: list[str]) -> list[str]:
    """How the model rows were made (none: nothing)."""
    if not calibrations:
        return []
    return [
        "Rows marked model: the same bench frames as the N9 rows of their scene, located "
        'by `[detection] method = "model"` (the skin\'s footprint fitted to the taxels '
        "around each peak; N9's point kept where the fit fails its tests). The locator is "
        "not handed the bench's skin: `fruit calibrate` fitted it to a second bench run of "
        "the same board at other sample points (half a pitch off each taxel for the law, "
        "right over each taxel for its gain; the small indenter). The indenter is still in "
        "x and y while it descends to the threshold, so the model may fit the mean "
        "activation of the frame at the threshold and the frames before it "
        "(`[detection].model_frames`); how many is chosen on the same calibration run "
        "(its samples inside the taxels' outline), and the rows with the frame alone stay "
        "for comparison. The "
        "calibration gave:",
        "",
        *calibrations,
        "",
        "On a Gaussian board only the law's parameters are fitted, its form is the "
        "bench's own: a favourable case for the model. `fruit study locate` scores the "
        "method on boards whose law the locator does not assume.",
        "",
    ]


def views_section(out: Path, scenes: list[str]) -> list[str]:
    lines = ["## Top and side views (Figs. 12-14)", ""]
    for name in scenes:
        ev = out / name / "evaluate"
        for png in sorted(ev.glob("*/top.png")) + sorted(ev.glob("*/side.png")):
            rel = png.relative_to(out)
            lines.append(f"![{name}: {png.parent.name} {png.stem}]({rel})")
    return lines + [""]


# the paper's sensitivity figures: (noise std max, baseline shift max, shift mean) counts
PAPER_SENSITIVITY = {
    "fruit-breathing": "noise std max 1.9 (Fig. 10); baseline shift max 16, mean 5.0 (Fig. 11)",
    "touchpad-4x4": "baseline shift max 10 when bent 180 deg (Fig. 9)",
}


def _pair(summary: dict, key: str) -> str:
    v = summary.get(key, {})
    return f"{v.get('max', float('nan')):.1f} / {v.get('mean', float('nan')):.1f}"


def sensitivity_section(out: Path, scenes: list[str]) -> list[str]:
    lines = [
        "## Sensitivity (Figs. 9-11)",
        "",
        "Noise: std of each taxel over the noise window at rest. Shift: the largest "
        "baseline change of each taxel over the scene's states, measured (with noise) and "
        "from the model alone. Counts; the touch threshold is 20.",
        "",
        "| scene | noise std max / mean | shift max / mean | model shift max / mean | paper |",
        "|---|---|---|---|---|",
    ]
    pics = []
    for name in scenes:
        sdir = out / name / "sensitivity"
        data = _load(sdir / "sensitivity.json")
        if not data:
            continue
        summ = data.get("summary", {})
        lines.append(
            f"| {name} | {_pair(summ, 'std')} | {_pair(summ, 'max_shift')} | "
            f"{_pair(summ, 'max_shift_model')} | {PAPER_SENSITIVITY.get(name, '-')} |"
        )
        pics += [
            f"![{name} {png.stem}]({png.relative_to(out)})" for png in sorted(sdir.glob("*.png"))
        ]
    return lines + [""] + pics + [""]


def fabrication_section(out: Path, scenes: list[str]) -> list[str]:
    lines = ["## Fabrication outputs", ""]
    for name in scenes:
        tr = out / name / "make-tracks"
        rep = _load(tr / "report.json")
        if rep:
            tri = rep.get("triangles", {})
            facts = (
                f"{rep.get('taxels')} taxels; triangles: artist {tri.get('artist')}, "
                f"reduced {tri.get('reduced')}, tracked top {tri.get('tracked_top')}; "
                f"offset Hausdorff {rep.get('offset_error', {}).get('hausdorff_mm', 0):.2f}"
                " mm"
            )
            preview = (tr / "preview.png").relative_to(out)
            lines += [f"**{name}**: {facts}", "", f"![tracked piece]({preview})", ""]
            break
    for name in scenes:
        q = _load(out / name / "tetra" / "quality.json")
        if q:
            lines.append(
                f"**{name} mesh quality**: "
                + ", ".join(
                    f"{k} = {v:.3g}" if isinstance(v, float) else f"{k} = {v}"
                    for k, v in q.items()
                    if not isinstance(v, (list, dict))
                )
            )
            lines.append("")
    return lines


def studies_section(out: Path) -> list[str]:
    """Links to the studies when `make studies` has written them under OUT."""
    lines = ["## Studies (`make studies`)", ""]
    found = False
    for name, md, png in (
        (
            "Error against run time, the Fruit in its jig (one hard state)",
            "study-runtime/runtime.md",
            "study-runtime/runtime.png",
        ),
        (
            "Error against run time, the Fruit breathing (13 states)",
            "study-runtime-breathing/runtime.md",
            "study-runtime-breathing/runtime.png",
        ),
        ("Stability", "study-stability/stability.md", None),
        (
            "What the bench's rows depend on: the skin model's assumed parameters",
            "study-bench/bench.md",
            "study-bench/bench.png",
        ),
    ):
        if (out / md).exists():
            found = True
            lines.append(
                f"- {name}: [{md}]({md})"
                + (f", ![plot]({png})" if png and (out / png).exists() else "")
            )
    if not found:
        lines.append("Not run yet: `make studies` writes them next to this report.")
    return lines + [""]


def plans_section(plans: dict[str, str]) -> list[str]:
    lines = ["## What ran, per scene", ""]
    for name, text in plans.items():
        lines += [f"### {name}", "", "```", text, "```", ""]
    return lines


def write_report(
    out: Path, plans: dict[str, str], timings: dict[str, tuple[float, int, int]]
) -> Path:
    """Assemble out/report.md from the scenes' outputs; `timings` per scene: (seconds of
    this run, stages run, stages reused)."""
    scenes = list(plans)
    lines = [
        "# fruit demo report",
        "",
        "Generated by `make demo` (`fruit demo`) from the scenes' outputs. A stage whose "
        "inputs did not change since an earlier run is reused, not run again (see the "
        "plans at the end); the seconds are this run's.",
        "",
        "| scene | seconds | stages run | stages reused |",
        "|---|---|---|---|",
    ]
    lines += [f"| {n} | {s:.1f} | {r} | {u} |" for n, (s, r, u) in timings.items()] + [""]
    lines += observations_section(out, scenes)
    lines += table_section(out, scenes)
    lines += views_section(out, scenes)
    lines += sensitivity_section(out, scenes)
    lines += fabrication_section(out, scenes)
    lines += studies_section(out)
    lines += plans_section(plans)
    path = out / "report.md"
    write_text(path, "\n".join(lines) + "\n")
    return path
