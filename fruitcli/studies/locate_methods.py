"""Error against run time of every detection method, on benches whose skin is not the
skin the locator assumes.

Units: mm, counts, microseconds. A method scored on frames made by the very law and
parameters it fits proves nothing, so each case replays the scene's virtual bench with
a board whose skin the locator does not know:

- ``calibrated``: the board's taxel gains spread +-20 % (seeded); the locator uses the
  skin `fruit calibrate` fitted to another run of the same board at other sample points
  (half a pitch off the taxels, the small indenter): its footprint width, counts at
  contact, gap decay, noise and gains;
- ``electrostatic``: the board is the crossing table's (``[skin] model =
  "electrostatic"``, gains +-20 %); the locator uses the Gaussian law calibrated on
  another run of it, as above;
- ``gaussian, table fitted``: the reverse, a Gaussian board located with the crossing
  table whose counts per fF and gains were calibrated on another run of it;
- ``wider``: a field sigma of 7 mm where the locator assumes the scene's 6, 75 counts at
  contact where it assumes 60, gains spread +-20 % that it does not know;
- ``narrower``: a field sigma of 5 mm, 50 counts at contact, gains spread +-20 %;
- the noise is the scene's (by default the per-taxel std of Fig. 10) in all, and every
  bench records ``IDLE_FRAMES`` idle frames before its first descent.

Every method of `fruitcli.sensing.detection.methods.METHODS` locates the same frames,
and so does the model method with other settings (`MODEL_SETTINGS`: a 3 x 3 window, the
N9 alone, instead of 5 x 5, and other iteration caps, `model_fit.tuned`); each row gives
the Table I figures per indenter (mean error unregistered and translation-registered,
the paper's protocol, and the registered median) and the time per frame of `fruit
locate`'s loop on them (reading, detecting, locating and writing, one thread; its
set-up, such as loading the body's surface, left out; the median of ``REPEATS`` runs).
The deformed and breathing states are the
scene's: run the study on ``pipelines/fruit-deformed.toml`` for them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from fruitcli.evaluation.outline import inside_outline, registered_mean
from fruitcli.studies.locator_skins import (
    CALIBRATION_INDENTER,
    BenchBody,
    calibrated_skin,
    touch_width_skin,
)
from fruitcli.studies.model_frames import MIN_INSIDE, MODEL_FRAMES

if TYPE_CHECKING:
    from types import ModuleType

    from fruitcli.scene import Scene

GAIN_SPREAD = 0.2
IDLE_FRAMES = 120
"""Idle frames every bench of the study records before its first descent (2 s at 60
frames/s; ``[bench].baseline_frames``), all of which `fruit locate` and `fruit calibrate`
take as the baseline: with the scene's default of 10 the baseline is off by the noise
over the square root of 10 on every taxel, an offset that averaging a touch's frames
does not remove."""


class BenchSkin(TypedDict):
    """A bench skin's [skin] keys: None keeps the scene's (the calibrated cases')."""

    field_sigma_mm: float | None
    contact_counts: float | None
    gain_spread: float


BENCH_SKINS: dict[str, BenchSkin] = {
    "calibrated": {"field_sigma_mm": None, "contact_counts": None, "gain_spread": GAIN_SPREAD},
    "electrostatic": {"field_sigma_mm": None, "contact_counts": None, "gain_spread": GAIN_SPREAD},
    "gaussian, table fitted": {
        "field_sigma_mm": None,
        "contact_counts": None,
        "gain_spread": GAIN_SPREAD,
    },
    "wider": {"field_sigma_mm": 7.0, "contact_counts": 75.0, "gain_spread": GAIN_SPREAD},
    "narrower": {"field_sigma_mm": 5.0, "contact_counts": 50.0, "gain_spread": GAIN_SPREAD},
}
# the cases whose locator is calibrated on another run, and the skin model of the board and
# of the locator's calibration
CALIBRATED = {
    "calibrated": ("gaussian", "gaussian"),
    "electrostatic": ("electrostatic", "gaussian"),
    "gaussian, table fitted": ("gaussian", "electrostatic"),
}
REPEATS = 3
# the calibrated cases' row of the model with `[detection].model_frames` chosen on their
# calibration run (`model_frames.choose`), as the demo's model rows
CHOSEN_LABEL = "model, frames chosen"
# the uncalibrated cases' row of the model (8 frames) with each indenter's footprint width
# from the touches of another run of the board alone (`locator_skins.touch_width_skin`)
WIDTH_LABEL = "model, 8 frames, width from touches"
# the model method's settings rows: label -> (window half-width in cells, iteration cap,
# `[detection].model_frames`); the plain "model" row is the defaults (5 x 5,
# `model_fit.ITERATIONS`, the frame alone)
MODEL_SETTINGS = {
    "model 3x3": (1, None, 1),
    "model 3x3, 4 it": (1, 4, 1),
    "model 5x5, 4 it": (2, 4, 1),
    "model 5x5, 30 it": (2, 30, 1),
    "model, 4 frames": (2, None, 4),
    "model, 8 frames": (2, None, 8),
}
HEADER = [
    "bench_skin",
    "method",
    "indenter",
    "n",
    "mean_mm",
    "reg_mean_mm",
    "reg_std_mm",
    "reg_median_mm",
    "us_per_frame",
    "model_share",
    "model_sigma_mm",
    "n_inside",
    "reg_mean_inside_mm",
    "model_frames",
]


def bench_skin_values(name: str, indenters: Iterable[str]) -> dict:
    """The [skin] keys of bench skin `name` for `indenters` (footprint hypot(field
    sigma, indenter radius), as `fruitcli.sensing.skin.forward` makes it), and the
    bench's ``IDLE_FRAMES``."""
    from fruitcli.sensing.skin import forward

    case = BENCH_SKINS[name]
    if name in CALIBRATED:
        board = CALIBRATED[name][0]
        return {
            "skin.gain_spread": case["gain_spread"],
            "skin.taxel_gain": None,
            "skin.model": board,
            "bench.baseline_frames": IDLE_FRAMES,
        }
    sigma = case["field_sigma_mm"]
    assert sigma is not None, f"bench skin {name!r}: a field sigma or a calibration"
    feet = {
        i: float(np.hypot(sigma, forward.INDENTER_RADIUS_MM[i]))
        for i in indenters
        if i in forward.INDENTER_RADIUS_MM
    }
    return {
        "skin.footprint_sigma_mm": feet,
        "skin.contact_counts": case["contact_counts"],
        "skin.gain_spread": case["gain_spread"],
        "skin.taxel_gain": None,
        "bench.baseline_frames": IDLE_FRAMES,
    }


def run_case(args: tuple[Path, Path, Path, Path | None, Path | None, str, str]) -> list[dict]:
    """Bench one skin case, then locate and evaluate it with every method: rows."""
    from fruitcli.evaluation.report import evaluate_pair
    from fruitcli.scene import load_scene
    from fruitcli.sensing.stages import LocateFiles, locate_inputs, run_bench, run_locate

    scene_path, work, taxels, states, surface, unit, name = args
    scene = load_scene(scene_path)
    bench_scene = scene.with_values(bench_skin_values(name, scene.bench.indenters))
    base = Path(work) / name.replace(" ", "_").replace(",", "")
    board, fitted = CALIBRATED.get(name, ("gaussian", "gaussian"))
    table = {}  # the crossing's table, where the board or the locator needs one
    if "electrostatic" in (board, fitted):
        table["electrostatic"] = crossing_table(bench_scene, Path(work))
    run_bench(
        bench_scene,
        taxels,
        states,
        base / "bench",
        surface_path=surface,
        surface_unit=unit,
        crossing_dir=table.get(board),
    )
    located_table = table.get(fitted)
    body = BenchBody(taxels, states, surface, unit)
    board_table = table.get(board)
    skin_table = _locator_skin(name, bench_scene, scene, body, base, board_table, located_table)
    outline = body.taxels_mm(scene.bench.state)
    rows = []
    cases = variants()
    chosen: dict[str, int] = {}  # per indenter, the frames its calibration run chose
    if name in CALIBRATED:
        model_setting = next(c[2] for c in cases if c[0] == "model")

        def locate(keys: dict, bench: Path, folder: Path) -> None:
            inputs = locate_inputs(
                scene.with_values(keys), skin_table=skin_table, crossing_dir=located_table
            )
            with model_setting():
                run_locate(inputs, LocateFiles(bench, taxels, states, folder, surface, unit))

        chosen = _frames_chosen(locate, scene.bench.indenters, base, outline)
        cases.append((CHOSEN_LABEL, {"detection.method": "model"}, model_setting))
    else:
        keys = {"detection.method": "model", "detection.model_frames": 8}
        cases.append((WIDTH_LABEL, keys, next(c[2] for c in cases if c[0] == "model")))
    for label, changes, setting in cases:
        for ind in scene.bench.indenters:
            # the locator knows which indenter touches, as the bench does: its footprint
            keys = {**changes, "detection.footprint": ind}
            if label == CHOSEN_LABEL:
                keys["detection.model_frames"] = chosen[ind]
            located = scene.with_values(keys)
            # the uncalibrated cases' other rows assume the scene's skin
            skin = skin_table if name in CALIBRATED or label == WIDTH_LABEL else None
            inputs = locate_inputs(located, skin_table=skin, crossing_dir=located_table)
            frames = base / "bench" / ind / "frames.npz"
            out = base / label.replace(" ", "_").replace(",", "") / ind
            times = []
            for _ in range(REPEATS):
                with setting():
                    files = LocateFiles(frames, taxels, states, out, surface, unit)
                    summary = run_locate(inputs, files, workers=1)
                times.append(summary["seconds"])
            with np.load(frames, allow_pickle=False) as f:
                n_frames = len(f["frames"])
            s, _, truth, measured = evaluate_pair(
                base / "bench" / ind / "truth.csv",
                out / "measured.csv",
                scene.bench.reference_length_mm,
                f"{name}, {label}, {ind}",
            )
            c = s["compare"]
            inside = inside_outline(truth, outline)
            share, sigma = model_fits(out / "touches.csv")
            rows.append(
                {
                    "bench_skin": name,
                    "method": label,
                    "indenter": ind,
                    "n": s["n"],
                    "mean_mm": c["none"]["mean_mm"],
                    "reg_mean_mm": c["translation"]["mean_mm"],
                    "reg_std_mm": c["translation"]["std_mm"],
                    "reg_median_mm": c["translation"]["median_mm"],
                    "us_per_frame": 1e6 * float(np.median(times)) / max(n_frames, 1),
                    "model_share": share,
                    "model_sigma_mm": sigma,
                    "n_inside": int(inside.sum()),
                    "reg_mean_inside_mm": registered_mean(truth[inside], measured[inside]),
                    "model_frames": (
                        keys.get("detection.model_frames", 1) if "model" in label else None
                    ),
                }
            )
    return rows


def _locator_skin(
    name: str,
    bench_scene: Scene,
    scene: Scene,
    body: BenchBody,
    base: Path,
    board_table: Path | None,
    located_table: Path | None,
) -> Any:
    """The [skin] table bench skin `name`'s locator gets, made under the case's folder
    `base` on `body`: `calibrated_skin` for the calibrated cases, else `scene`'s with the
    footprint widths from another run's touches (`touch_width_skin`, for the
    ``WIDTH_LABEL`` row alone)."""
    if name in CALIBRATED:
        return calibrated_skin(
            bench_scene,
            body,
            base / "calibration",
            board_table,
            located_table,
            scene.bench.indenters,
        )
    return touch_width_skin(bench_scene, scene, body, base / "widths", scene.bench.indenters)


def _frames_chosen(
    locate: Callable[[dict, Path, Path], None],
    indenters: Iterable[str],
    base: Path,
    outline_mm: np.ndarray,
) -> dict[str, int]:
    """Per indenter, the model's `[detection].model_frames` chosen on its own calibration
    run (BASE/calibration/bench/NAME, `model_frames.choose`, on its samples inside the
    outline of the taxels `outline_mm` (T, 3)); ``locate(keys, frames_npz, folder)``
    locates a recording with those [detection] keys."""
    from fruitcli.studies import model_frames

    chosen = {}
    for ind in indenters:

        def with_frames(frames: int, bench: Path, folder: Path, ind: str = ind) -> None:
            keys = {"detection.method": "model", "detection.model_frames": frames}
            locate({**keys, "detection.footprint": ind}, bench, folder)

        chosen[ind] = model_frames.choose(
            with_frames,
            base / "calibration" / "bench" / ind,
            base / "frames" / ind,
            outline_mm=outline_mm,
        ).frames
    return chosen


Variant = tuple[str, dict[str, object], Callable[[], AbstractContextManager[object]]]
"""A locate row: its label, its [detection] keys, and the context its settings hold in."""


def variants() -> list[Variant]:
    """(row label, its [detection] keys, a context manager factory for its settings):
    every method of `METHODS` with its defaults, then the model's `MODEL_SETTINGS`; every
    model row runs inside `model_fit.tuned` (its defaults too), so cases run on threads
    of one process (a Dask worker) do not mix their settings."""
    from contextlib import nullcontext
    from functools import partial

    from fruitcli.sensing.detection import model_fit
    from fruitcli.sensing.detection.methods import METHODS

    model_defaults = partial(model_fit.tuned, model_fit.HALF, model_fit.ITERATIONS)
    out: list[Variant] = [
        (m, {"detection.method": m}, model_defaults if spec.refine == "model" else nullcontext)
        for m, spec in METHODS.items()
    ]
    for label, (half, iterations, frames) in MODEL_SETTINGS.items():
        cap = model_fit.ITERATIONS if iterations is None else iterations
        keys = {"detection.method": "model", "detection.model_frames": frames}
        out.append((label, keys, partial(model_fit.tuned, half, cap)))
    return out


def crossing_table(scene: Scene, work: Path) -> Path:
    """The skin stage's folder (the crossing's table) of `scene` with an electrostatic
    skin, run once under `work`."""
    from fruitcli.workflow import planner

    es = scene.with_values({"skin.model": "electrostatic"})
    root = work / "crossing"
    planner.run(es, root, until="skin", shared=work.resolve().parent)
    return planner.Context(root).dir("skin")


def model_fits(touches_csv: Path) -> tuple[float, float]:
    """(share of the touches the model method placed, the median of their 1-sigma radii
    in mm); NaN, NaN for the other methods."""
    from fruitcli.tables import read_table

    with open(touches_csv) as fh:
        header = next((ln for ln in fh if not ln.startswith("#")), "")
    if not header.rstrip().endswith(",fit"):
        return float("nan"), float("nan")
    cols = read_table(touches_csv, ["pos_err_mm", "fit"], numeric=[])
    placed = cols["fit"] == "model"
    if not len(placed):
        return float("nan"), float("nan")
    radii = cols["pos_err_mm"][placed].astype(float)
    sigma = float(np.median(radii)) if placed.any() else float("nan")
    return float(placed.mean()), sigma


def table_markdown(rows: list[dict], scene_name: str, stamp: str) -> str:
    """The study's table: one row per bench skin, method and indenter."""
    lines = [
        f"# Detection methods on {scene_name}: error against run time",
        "",
        stamp,
        "",
        "| bench skin | method | indenter | n | mean error | registered mean | registered std "
        "| registered median | inside the outline: n, registered mean | us per frame "
        "| placed by the model | the model's 1-sigma radius |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        share = "" if np.isnan(r["model_share"]) else f"{100 * r['model_share']:.0f} %"
        sigma = "" if np.isnan(r["model_sigma_mm"]) else f"{r['model_sigma_mm']:.2f} mm"
        lines.append(
            f"| {r['bench_skin']} | {r['method']} | {r['indenter']} | {r['n']} | "
            f"{r['mean_mm']:.2f} mm | {r['reg_mean_mm']:.2f} mm | {r['reg_std_mm']:.2f} mm | "
            f"{r['reg_median_mm']:.2f} mm | {r['n_inside']}, {r['reg_mean_inside_mm']:.2f} mm | "
            f"{r['us_per_frame']:.1f} | {share} | {sigma} |"
        )
    lines += [
        "",
        "Bench skins differ from the skin the locator assumes: calibrated: the board's gains "
        f"spread +-{100 * GAIN_SPREAD:.0f} %, the locator uses `fruit calibrate`'s fit to "
        "another run at other sample points (half a pitch off the taxels and right over "
        f"them; the law and gains from the {CALIBRATION_INDENTER} indenter, each "
        "indenter's footprint width from its own descents there); electrostatic: the "
        "board is the crossing "
        "table's, the locator a Gaussian law calibrated as above; gaussian, table "
        "fitted: a Gaussian board, the locator the crossing table calibrated as above; "
        + "; ".join(
            f"{k}: field sigma {v['field_sigma_mm']:g} mm, {v['contact_counts']:g} counts at "
            f"contact, gains +-{100 * v['gain_spread']:.0f} %, the locator assumes the scene's "
            "[skin]"
            for k, v in BENCH_SKINS.items()
            if v["field_sigma_mm"] is not None
        )
        + f". Every bench records {IDLE_FRAMES} idle frames before its first descent, all of "
        "them the locator's baseline. The locator is told which indenter touches "
        "(`[detection].footprint`), as the bench knows. Registered: translation (the "
        "paper's protocol). Inside the outline: "
        "the samples within the convex hull of the taxels seen from above (at the bench's state), "
        "registered on their own. The model's 1-sigma radius: the median of the fit's own "
        "position uncertainty over the touches it placed. Time per frame: `fruit locate`'s "
        "loop on one thread, file reading and writing included, set-up left out, median of "
        f"{REPEATS} runs. "
        + "Model settings: model is the 5x5 window (the N9 and the ring beyond) with at most "
        + f"{_default_iterations()} Levenberg-Marquardt iterations; "
        + ", ".join(
            f"{k}: a {2 * h + 1}x{2 * h + 1} window, "
            + (f"at most {it} iterations" if it else "the default cap")
            + (f", the mean of the touch's frame and the {f - 1} before it" if f > 1 else "")
            for k, (h, it, f) in MODEL_SETTINGS.items()
        )
        + ". "
        + _chosen_note(rows)
        + (
            f" {WIDTH_LABEL} (the boards not calibrated): the locator assumes the scene's "
            "[skin] but each indenter's footprint width, which `fruit calibrate` without "
            "--truth found from the touches alone of another run at the calibration's sample "
            "points."
            if any(r["method"] == WIDTH_LABEL for r in rows)
            else ""
        ),
    ]
    return "\n".join(lines) + "\n"


def _chosen_note(rows: list[dict]) -> str:
    """The sentence on the chosen row: what it is and how many frames each board got."""
    chosen = [r for r in rows if r["method"] == CHOSEN_LABEL]
    if not chosen:
        return ""
    return (
        f"{CHOSEN_LABEL}: the mean of as many frames ({', '.join(map(str, MODEL_FRAMES))}) "
        "as place best the touches of the indenter's calibration run inside the taxels' "
        f"outline (all of them when fewer than {MIN_INSIDE} lie inside; as the demo's "
        "model rows): "
        + ", ".join(f"{r['bench_skin']} {r['indenter']} {r['model_frames']}" for r in chosen)
        + "."
    )


def _default_iterations() -> int:
    from fruitcli.sensing.detection.model_fit import ITERATIONS

    return ITERATIONS


def _method_colours(plt: ModuleType, n: int) -> list:
    """n colours, one per method: tab10's without its grey (the boards' markers are grey
    in the legend), then tab20's darker ones, repeating past 17."""
    tab10, tab20b = plt.get_cmap("tab10"), plt.get_cmap("tab20b")
    palette = [tab10(i) for i in range(10) if i != 7] + [tab20b(i) for i in range(0, 20, 4)]
    palette += [tab20b(i) for i in range(2, 20, 4)]
    return [palette[k % len(palette)] for k in range(n)]


def plot(path: Path, rows: list[dict], scene_name: str) -> None:
    """Registered mean error against time per frame, one panel per bench skin: a marker
    per method (its colour and shape), filled for the first indenter and hollow for the
    others; N9's error per indenter is a dotted line across its panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    methods = list(dict.fromkeys(r["method"] for r in rows))
    skins = list(dict.fromkeys(r["bench_skin"] for r in rows))
    inds = list(dict.fromkeys(r["indenter"] for r in rows))
    markers = "osD^vP*Xdph<>"
    colors = _method_colours(plt, len(methods))
    ncols = min(3, len(skins))
    nrows = -(-len(skins) // ncols)
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(4.2 * ncols + 2.6, 3.4 * nrows), sharex=True, sharey=True
    )
    axes = np.atleast_1d(axes).ravel()
    top = max((r["reg_mean_mm"] for r in rows if np.isfinite(r["reg_mean_mm"])), default=1.0)
    for ax, skin in zip(axes, skins, strict=False):
        for r in (r for r in rows if r["bench_skin"] == skin):
            k = methods.index(r["method"])
            filled = inds.index(r["indenter"]) == 0
            ax.scatter(
                r["us_per_frame"],
                r["reg_mean_mm"],
                marker=markers[k % len(markers)],
                s=46,
                facecolors=colors[k] if filled else "none",
                edgecolors=colors[k],
                linewidths=1.4,
            )
            if r["method"] == methods[0]:
                ax.axhline(
                    r["reg_mean_mm"],
                    color=colors[k],
                    linestyle=":" if filled else "--",
                    linewidth=1,
                )
        ax.set_title(f"board: {skin}", fontsize=10)
        ax.set_xscale("log")
        ax.set_ylim(0, 1.1 * top)
        ax.grid(True, which="both", color="0.9")
    for k, ax in enumerate(axes[: len(skins)]):
        if k + ncols >= len(skins):  # the lowest panel of its column: its x axis labelled
            ax.xaxis.set_tick_params(labelbottom=True)
            ax.set_xlabel("us per frame (log scale)")
    for ax in axes[::ncols]:
        ax.set_ylabel("registered mean error (mm)")
    handles = [
        plt.Line2D([], [], marker=markers[k % len(markers)], color=colors[k], linestyle="",
                   label=m)
        for k, m in enumerate(methods)
    ]  # fmt: skip
    handles += [
        plt.Line2D([], [], marker="o", linestyle="", color="0.3",
                   markerfacecolor="0.3" if k == 0 else "none",
                   label=f"{ind} indenter ({'filled' if k == 0 else 'hollow'})")
        for k, ind in enumerate(inds)
    ]  # fmt: skip
    handles += [
        plt.Line2D([], [], color="0.3", linestyle=":" if k == 0 else "--",
                   label=f"{methods[0]}, {ind} indenter")
        for k, ind in enumerate(inds)
    ]  # fmt: skip
    fig.suptitle(
        f"Detection methods on {scene_name}: registered mean error against time per frame, "
        "on boards the locator does not assume",
        fontsize=11,
    )
    spare = axes[len(skins) :]
    for ax in spare:
        ax.set_visible(False)
    if len(spare):  # the legend in the first empty panel
        spare[0].set_visible(True)
        spare[0].axis("off")
        spare[0].legend(handles=handles, fontsize=8, loc="center", ncols=2, frameon=False)
        fig.tight_layout()
    else:
        fig.legend(handles=handles, fontsize=8, loc="center right", frameon=False)
        fig.tight_layout(rect=(0, 0, 0.8, 1))
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
