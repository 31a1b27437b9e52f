"""The electrostatic skin as a design tool: the bench's registered error and the bending
false-touch margin against the cover thickness and the pitch, through `fruit sweep`.

Units: mm, counts. The scene is ``pipelines/fruit-rest.toml`` (the default Fruit at
rest, both indenters, Table I translation-registered) with ``[skin] model =
"electrostatic"``, swept over ``[tracks].cover_mm`` (the yarns' depth) and the pitch
(``[grid].spacing_x_mm = spacing_y_mm``). Every variant builds its own crossing table.
``[skin].counts_per_ff`` is held at the default design's value (cover 2 mm, pitch 16 x 12
mm, fitted to the bent pad) so the counts compare across designs: the board's counts per
femtofarad do not change with the skin.

Per variant (sweep.csv): ``rest-small_mean_mm`` and ``rest-medium_mean_mm`` (Table I,
translation-registered) and ``bend_margin_counts``: the threshold (20 counts) less the
largest baseline shift of the crossing bent as the paper's 4 x 4 pad (Fig. 9: 180 deg
over 48 mm, the neutral plane 1.5 mm under the surface) along either yarn; below 0 a bend
alone makes a false touch.

    python tests/performance/skin_design_study.py --out DIR [--covers 1.5,2,3,4]
        [--pitches 10,12,16,20] [--jobs N | --scheduler ADDR] [--plot-only]

Writes DIR/skin-design.toml, DIR/sweep/ (the sweep's folder), DIR/skin_design.png and
prints the table (Markdown) with the date, commit and machine.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # tests.performance
PIPELINES = ROOT / "pipelines"
ERROR_COLUMNS = ("rest-small_mean_mm", "rest-medium_mean_mm")


def default_counts_per_ff(out: Path) -> float:
    """The default Fruit's counts per fF (its crossing fitted to the bent pad)."""
    import json

    from fruitcli.scene import load_scene
    from fruitcli.workflow.planner import Context, run
    from tests.performance.compare_skins import variant

    path = variant("fruit-rest", "electrostatic", out)
    root = out / path.stem
    run(load_scene(path), root, until="skin", shared=out)
    return float(
        json.loads((Context(root).dir("skin") / "summary.json").read_text())["counts_per_ff"]
    )


def study_scene(out: Path, counts_per_ff: float) -> Path:
    """fruit-rest, translation-registered, with the electrostatic skin at `counts_per_ff`."""
    from tests.performance.compare_skins import variant

    base = variant("fruit-rest", "electrostatic", out, '\nregister = "translation"\n')
    text = base.read_text().replace('name = "fruit-rest"', 'name = "skin-design"')
    text += f"counts_per_ff = {counts_per_ff:.6g}   # the default design's, on the bent pad\n"
    path = out / "skin-design.toml"
    path.write_text(text)
    return path


def run_sweep(scene: Path, out: Path, covers, pitches, pool_args) -> None:
    cover = ",".join(str(c) for c in covers for _ in pitches)
    pitch = ",".join(str(p) for _ in covers for p in pitches)
    cmd = [
        str(Path(sys.executable).with_name("fruit")), "sweep", str(scene), "--zip",
        "--set", f"tracks.cover_mm={cover}",
        "--set", f"grid.spacing_x_mm={pitch}",
        "--set", f"grid.spacing_y_mm={pitch}",
        "--out", str(out / "sweep"), *pool_args,
    ]  # fmt: skip
    subprocess.run(cmd, cwd=ROOT, check=False)


def read_rows(sweep_csv: Path) -> list[dict]:
    lines = [ln for ln in sweep_csv.read_text().splitlines() if not ln.startswith("#")]
    return [r for r in csv.DictReader(lines) if r["status"] == "ok"]


def stamp() -> str:
    from tests.performance.run_all import commit, processor

    date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return f"{date}, commit {commit()[:12]}, {processor()} ({platform.machine()})"


def plot(rows: list[dict], path: Path, note: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    covers = sorted({float(r["tracks.cover_mm"]) for r in rows})
    fig, (err, margin) = plt.subplots(1, 2, figsize=(11, 4.6), constrained_layout=True)
    colours = plt.cm.viridis([k / max(len(covers) - 1, 1) * 0.85 for k in range(len(covers))])
    for colour, c in zip(colours, covers, strict=True):
        mine = sorted(
            (r for r in rows if float(r["tracks.cover_mm"]) == c),
            key=lambda r: float(r["grid.spacing_x_mm"]),
        )
        pitch = [float(r["grid.spacing_x_mm"]) for r in mine]
        for column, style in zip(ERROR_COLUMNS, ("-", "--"), strict=True):
            label = f"cover {c:g} mm, {column.split('_')[0].removeprefix('rest-')}"
            err.plot(pitch, [float(r[column]) for r in mine], style, marker="o",
                     color=colour, label=label)  # fmt: skip
        margins = [float(r["bend_margin_counts"]) for r in mine]
        margin.plot(pitch, margins, "-", marker="o", color=colour)
        margin.annotate(f"cover {c:g} mm", (pitch[-1], margins[-1]), xytext=(6, 0),
                        textcoords="offset points", va="center", fontsize=8,
                        color=colour)  # fmt: skip
    err.set(xlabel="pitch (mm)", ylabel="registered mean error (mm)",
            title="Bench error (Table I, translation-registered)")  # fmt: skip
    err.legend(fontsize=7, ncol=2)
    margin.axhline(0.0, color="0.3", lw=1)
    margin.text(margin.get_xlim()[0], 0.3, " below 0: bending alone is a touch", fontsize=8,
                va="bottom", color="0.3")  # fmt: skip
    margin.set(xlabel="pitch (mm)", ylabel="threshold - largest bend shift (counts)",
               title="Bending false-touch margin (pad bent 180 deg)")  # fmt: skip
    margin.set_xlim(right=margin.get_xlim()[1] + 2.5)  # room for the labels
    for ax in (err, margin):
        ax.grid(alpha=0.3)
    fig.suptitle(f"Electrostatic skin on the Fruit at rest. {note}", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def table(rows: list[dict]) -> str:
    head = (
        "| cover (mm) | pitch (mm) | taxels | small: n, mean (mm) | medium: n, mean (mm) | "
        "C0 (fF) | small at contact (counts) | bend shift (counts) | margin (counts) |"
    )
    lines = [head, "|" + "---|" * 9]
    key = lambda r: (float(r["tracks.cover_mm"]), float(r["grid.spacing_x_mm"]))  # noqa: E731
    for r in sorted(rows, key=key):
        lines.append(
            f"| {float(r['tracks.cover_mm']):g} | {float(r['grid.spacing_x_mm']):g} | "
            f"{r['taxels']} | {r['rest-small_n']}, {float(r['rest-small_mean_mm']):.2f} | "
            f"{r['rest-medium_n']}, {float(r['rest-medium_mean_mm']):.2f} | "
            f"{float(r['c0_ff']):.0f} | {float(r['contact_counts_small']):.1f} | "
            f"{float(r['bend_shift_max_counts']):.1f} | {float(r['bend_margin_counts']):.1f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--covers", default="1.5,2,3,4")
    ap.add_argument("--pitches", default="10,12,16,20")
    ap.add_argument("--jobs", default=None)
    ap.add_argument("--scheduler", default=None)
    ap.add_argument("--plot-only", action="store_true", help="only plot DIR/sweep/sweep.csv")
    args = ap.parse_args(argv)
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    if not args.plot_only:
        scene = study_scene(out, default_counts_per_ff(out))
        pool = ["--jobs", args.jobs] if args.jobs else []
        pool += ["--scheduler", args.scheduler] if args.scheduler else []
        covers = [float(c) for c in args.covers.split(",")]
        pitches = [float(p) for p in args.pitches.split(",")]
        run_sweep(scene, out, covers, pitches, pool)
    rows = read_rows(out / "sweep" / "sweep.csv")
    note = stamp()
    plot(rows, out / "skin_design.png", note)
    print(f"{len(rows)} designs; {note}\n")
    print(table(rows))


if __name__ == "__main__":
    main()
