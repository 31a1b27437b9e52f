"""Calibrating the skin's forward model from a bench recording (real or virtual).

Units: mm, counts. The model fitted is the virtual bench's (`fruitcli.sensing.skin.forward`),
with a gain per taxel:

    v(frame, taxel) = gain_t * contact_counts * exp(-d^2 / (2 S^2)) * exp(-g / gap_decay_mm)
    d^2 = r^2 + height_as_distance h^2,   g = gap + height_as_gap |h|
    S = sigma (1 + widening_per_mm * max(g, height_as_gap |h|))

v = C - C0 (C0: the mean of the recording's idle frames), h the height of the sample's
contact point (truth.csv) over the taxel at rest (z, the printer's approach), r the rest
of their 3D distance, gap the tip's height above the contact point. The two height
terms say how the board's field sees a crossing below or above the contact point: as
distance (a Gaussian in 3D) or as gap (the electrostatic crossing's table); on a curved
body the descents' crossings lie at various heights and fix both (0 .. ``MAX_HEIGHT_FORM``;
a weak prior, ``HEIGHT_PRIOR_COUNTS``, keeps them at 1 and 0 where they do not). They
are kept only when they explain the descents better than the 3D distance by more than
the Bayesian information criterion asks of two more parameters (the sum of squared
residuals, over the 3D distance fit's mean square, falls by more than 2 ln(M T)) and by
at least ``HEIGHT_FORM_MIN_FALL`` of it; else the law is the 3D distance's (1 and 0),
fitted without them. The widening (0 .. ``MAX_WIDENING_PER_MM``: a field that spreads as
it reaches farther) is then fitted on top of the law kept, and kept by the same test for
one parameter, with ``WIDENING_MIN_FALL`` as its least share. Frames
used: every frame of every sample's descent (from the first frame after the previous
sample's frame to the sample's own frame). The gap of a frame is
``printer_mm`` z minus the model origin's z (meta ``model_origin_mm``) minus the contact
z for a printer-bench recording; for a virtual-bench recording (no ``printer_mm``) it is
``start - j * step_mm`` for the j-th frame of the descent, as the virtual bench moves
(start: the sample's in meta ``start_gap_mm``, else ``START_GAP_MM``). Least squares over
log-parameters (scipy; the height terms bounded, linear), the gains normalized to mean 1
(their common factor is contact_counts). The noise std is that of the idle frames, less the
rounding of integer counts (1/12 count^2). Taxels whose fitted activation never reaches
``MEASURED_MIN_COUNTS`` keep gain 1 and are marked not measured. With ``[skin].model =
"electrostatic"`` the model fitted is the crossing table's instead: its counts per fF and
the gains (`calibrate_crossing`), the same frames and noise. Where the run has samples
right over taxels, those taxels' gains come from them instead (`taxel_gains`: compared at
equal gaps, the law does not enter them; the fitted ones take up where the law is wrong).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.skin.virtual_bench import START_GAP_MM
from fruitcli.tables import Taxels, integer_column, read_taxels

if TYPE_CHECKING:
    from fruitcli.scene import BoardSection, SkinSection
    from fruitcli.sensing.frames.recording import Recording
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

MEASURED_MIN_COUNTS = 10.0  # a taxel's gain is measured when its activation reaches this
ROUNDING_VAR = 1.0 / 12.0  # variance of rounding to integer counts
GAUGE_WEIGHT = 100.0  # weight of mean(log gain) = 0 (gains and contact_counts trade off)
HEIGHT_PRIOR_COUNTS = 1.0  # counts per unit of height_as_distance - 1 and height_as_gap
# the least share of the squared residuals the height form must remove (an assumption:
# a Gaussian board's descents on the deformed Fruit, its taxels taken at rest, give 0.1 %
# for the form; an electrostatic board's 2-9 %)
HEIGHT_FORM_MIN_FALL = 0.01
# the same for the widening with the gap (an assumption: a Gaussian board's descents give
# 2e-5 and less; an electrostatic board's on the Fruit 0.5-2 %)
WIDENING_MIN_FALL = 0.002


def descent_gaps(
    rec: Recording, truth_z: dict[int, float], n_idle: int, where: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame indices (M,), sample id per frame (M,), gap mm (M,)) of every descent frame."""
    if rec.sample is None:
        raise FrameError(f"{where}: no 'sample' key: not a bench recording")
    frames, samples, gaps = [], [], []
    start = n_idle
    printer_z = None  # the tip's height over the model's origin (N,) mm
    if rec.printer_mm is not None:
        origin = rec.meta.get("model_origin_mm")
        if origin is None:
            raise FrameError(f"{where}: printer_mm without meta model_origin_mm")
        printer_z = rec.printer_mm[:, 2] - float(origin[2])
    step = rec.meta.get("step_mm")
    starts = rec.meta.get("start_gap_mm", {})  # per sample id, where the descent started
    if not isinstance(starts, dict):
        raise FrameError(f"{where}: meta start_gap_mm: expected a table of sample -> mm")
    if printer_z is None and step is None:
        raise FrameError(f"{where}: meta has no step_mm (virtual bench) and no printer_mm")
    for f in np.flatnonzero(rec.sample >= 0):
        k = int(rec.sample[f])
        idx = np.arange(start, f + 1)
        start = int(f) + 1
        if k not in truth_z:
            continue
        if printer_z is not None:
            gap: np.ndarray = printer_z[idx] - truth_z[k]
        else:
            assert step is not None  # checked above
            start_mm = float(starts.get(str(k), START_GAP_MM))
            gap = start_mm - np.arange(idx.size) * float(step)
        frames.append(idx)
        samples.append(np.full(idx.size, k))
        gaps.append(gap)
    if not frames:
        raise FrameError(f"{where}: no sample frame to calibrate on")
    return np.concatenate(frames), np.concatenate(samples), np.concatenate(gaps)


def check_samples(
    rec_samples: np.ndarray, truth_ids: np.ndarray, frames_where: str, truth_where: str
) -> None:
    """The truth file and the recording must name the same samples."""
    have = set(int(k) for k in rec_samples[rec_samples >= 0])
    want = set(int(k) for k in truth_ids)
    if len(truth_ids) != len(want):
        raise FrameError(f"{truth_where}: a sample appears twice")
    missing, extra = sorted(want - have), sorted(have - want)
    if missing or extra:
        parts = []
        if missing:
            parts.append(
                f"samples {', '.join(map(str, missing[:5]))} have no frame in {frames_where}"
            )
        if extra:
            parts.append(
                f"{frames_where} has frames of samples "
                f"{', '.join(map(str, extra[:5]))} that are not in it"
            )
        raise FrameError(f"{truth_where}: does not match the recording: {'; '.join(parts)}")


def fit_skin(
    v: np.ndarray, dist_mm: np.ndarray, gap_mm: np.ndarray, height_mm: np.ndarray | None = None
) -> dict:
    """Fit v (M, T) counts = g_t A exp(-d^2/2s^2) exp(-g/l) (the module's law) for 3D
    distances dist (M, T) mm, gaps (M,) mm and heights h (M, T) mm of the contact point
    over each taxel, the height terms kept only when the criterion of the module's
    docstring asks for them (None, or all 0 as on a flat body: not tried), then the
    widening likewise. -> {contact_counts, sigma_mm, gap_decay_mm, height_as_distance,
    height_as_gap, widening_per_mm, height_form_gain and widening_gain (the fall of the
    squared residuals in noise variances; the form's 0 when not tried), gain (T,),
    measured (T,), rms_counts}."""
    plain = _fit_law(v, dist_mm, gap_mm, None)
    best, gain = plain, 0.0
    if height_mm is not None and np.any(height_mm):
        form = _fit_law(v, dist_mm, gap_mm, height_mm)
        gain = _fall(form, plain, v.size)
        if gain > max(2.0 * 2.0 * np.log(v.size), HEIGHT_FORM_MIN_FALL * v.size):
            best = form
    kept_heights = height_mm if best is not plain else None
    wide = _fit_law(v, dist_mm, gap_mm, kept_heights, widen=True)
    widening_gain = _fall(wide, best, v.size)
    if widening_gain > max(2.0 * np.log(v.size), WIDENING_MIN_FALL * v.size):
        best = wide
    return {**best, "height_form_gain": float(gain), "widening_gain": float(widening_gain)}


def _fall(fit: dict, simpler: dict, size: int) -> float:
    """How much `fit` lowers `simpler`'s sum of squared residuals, in `simpler`'s mean
    squares (`size` of them): what the information criterion weighs."""
    return size * (1.0 - fit["rms_counts"] ** 2 / max(simpler["rms_counts"] ** 2, 1e-300))


def _fit_law(
    v: np.ndarray,
    dist_mm: np.ndarray,
    gap_mm: np.ndarray,
    height_mm: np.ndarray | None,
    widen: bool = False,
) -> dict:
    """`fit_skin`'s law fitted with its height terms (`height_mm` given) or without them
    (1 and 0), and with the width's growth per mm of gap (`widen`) or without it (0)."""
    from scipy.optimize import least_squares

    from fruitcli.scene.limits import MAX_HEIGHT_FORM, MAX_WIDENING_PER_MM

    t = v.shape[1]
    free = 2 if height_mm is not None else 0  # the height terms fitted
    grow = int(widen)  # the widening fitted
    h = np.zeros_like(dist_mm) if height_mm is None else np.asarray(height_mm, float)
    h2, habs = h * h, np.abs(h)
    r2 = np.maximum(dist_mm**2 - h2, 0.0)  # the offset across z
    pressed_gap = np.maximum(gap_mm, 0.0)[:, None]
    first_gain = 3 + free + grow  # the log-gains' first column

    def unpack(x: np.ndarray):
        a, s, lam = np.exp(x[:3])
        alpha, beta = (x[3], x[4]) if free else (1.0, 0.0)
        w = x[3 + free] if grow else 0.0
        return a, s, lam, alpha, beta, w, np.exp(x[first_gain:])

    def terms(x: np.ndarray):
        """(model, squared distance, the gap the width grows with, 1 + w times it); the 3D
        distance's law needs only the model (the rest None, 0 and 1)."""
        a, s, lam, alpha, beta, w, g = unpack(x)
        if not free and not grow:  # the 3D distance, as before the two forms
            m = g[None, :] * a * np.exp(-0.5 * (dist_mm / s) ** 2) * np.exp(-gap_mm / lam)[:, None]
            return m, None, 0.0, 1.0
        d2 = r2 + alpha * h2
        spread = pressed_gap + beta * habs
        q = 1.0 + w * spread
        fall = (gap_mm[:, None] + beta * habs) / lam
        m = g[None, :] * a * np.exp(-0.5 * d2 / (s * q) ** 2 - fall)
        return m, d2, spread, q

    def model(x: np.ndarray):
        return terms(x)[0]

    def residual(x: np.ndarray):
        prior = HEIGHT_PRIOR_COUNTS * np.array([x[3] - 1.0, x[4]]) if free else np.zeros(0)
        gauge = GAUGE_WEIGHT * x[first_gain:].mean()
        return np.concatenate([(model(x) - v).ravel(), prior, [gauge]])

    def jacobian(x: np.ndarray):
        """d residual / d (log A, log s, log l, [alpha, beta,] [w,] log g): m, m d^2/S^2,
        m g/l, [-m h^2/2S^2, -m |h|/l + m d^2 w |h| / S^2 q,] [m d^2 G / S^2 q,] and m in
        taxel t's column for log g_t (S = s q the width, q = 1 + w G, G the gap it grows
        with; without the widening, q = 1); the priors' and the gauge's rows last."""
        _, s, lam, alpha, beta, w, _ = unpack(x)
        m, d2, spread, q = terms(x)
        width2 = (s * q) ** 2
        jac = np.zeros((m.size + free + 1, first_gain + t))
        jac[: m.size, 0] = m.ravel()
        if not free and not grow:
            jac[: m.size, 1] = (m * (dist_mm / s) ** 2).ravel()
            jac[: m.size, 2] = (m * (gap_mm / lam)[:, None]).ravel()
        else:
            jac[: m.size, 1] = (m * d2 / width2).ravel()
            jac[: m.size, 2] = (m * (gap_mm[:, None] + beta * habs) / lam).ravel()
        if free:
            jac[: m.size, 3] = (-0.5 * m * h2 / width2).ravel()
            jac[: m.size, 4] = (-m * habs / lam).ravel()
            jac[m.size, 3] = jac[m.size + 1, 4] = HEIGHT_PRIOR_COUNTS
        if grow:
            spread_slope = m * d2 / width2 / q  # d m / d spread, over w
            jac[: m.size, 3 + free] = (spread_slope * spread).ravel()
            if free:
                jac[: m.size, 4] += (spread_slope * w * habs).ravel()
        rows = np.arange(m.size)
        jac[rows, first_gain + rows % t] = m.ravel()
        jac[-1, first_gain:] = GAUGE_WEIGHT / t
        return jac

    peak = max(float(v.max()), 1.0)
    x0 = np.r_[
        np.log(peak * 2.0), np.log(6.0), np.log(2.0), [1.0, 0.0][:free], [0.0][:grow], np.zeros(t)
    ]
    lo = np.full(x0.size, -np.inf)
    hi = np.full(x0.size, np.inf)
    lo[3 : 3 + free], hi[3 : 3 + free] = 0.0, MAX_HEIGHT_FORM
    lo[3 + free : first_gain], hi[3 + free : first_gain] = 0.0, MAX_WIDENING_PER_MM
    # a trial step far out (the log-gain of a taxel no sample reached) overflows; its
    # cost is then inf or huge and the step is turned down, without numpy's warning
    with np.errstate(over="ignore", invalid="ignore"):
        res = least_squares(
            residual, x0, jac=jacobian, bounds=(lo, hi), method="trf", x_scale="jac"
        )
    return _law_result(unpack(res.x), model(res.x), v)


def _law_result(params: tuple, pred: np.ndarray, v: np.ndarray) -> dict:
    """`_fit_law`'s result from its parameters (A, sigma, decay, alpha, beta, widening,
    gains (T,)) and its model of v (M, T): the gains of taxels the model never takes
    to ``MEASURED_MIN_COUNTS`` set to 1 (not measured), the others normalized to mean 1
    (their factor goes into contact_counts)."""
    a, s, lam, alpha, beta, w, g = params
    measured = pred.max(axis=0) >= MEASURED_MIN_COUNTS
    g = np.where(measured, g, np.nan)
    scale = float(np.nanmean(g)) if measured.any() else 1.0
    gain = np.where(measured, g / scale, 1.0)
    return {
        "contact_counts": float(a * scale),
        "sigma_mm": float(s),
        "gap_decay_mm": float(lam),
        "height_as_distance": float(alpha),
        "height_as_gap": float(beta),
        "widening_per_mm": float(w),
        "gain": gain,
        "measured": measured,
        "rms_counts": float(np.sqrt(np.mean((pred - v) ** 2))),
    }


def noise_std_counts(idle: np.ndarray) -> tuple[float, np.ndarray]:
    """(overall, per taxel (T,)) noise std of idle counts (K, T), rounding removed."""
    var = np.var(idle, axis=0, ddof=1) if idle.shape[0] > 1 else np.zeros(idle.shape[1])
    per = np.sqrt(np.maximum(var - ROUNDING_VAR, 0.0))
    return float(np.sqrt(max(var.mean() - ROUNDING_VAR, 0.0))), per


def skin_toml(indenter: str, fit: dict, noise: float, gains_name: str = "gains.csv") -> str:
    """The ``[skin]`` table of a calibration."""
    return (
        "# fruit calibrate: the skin's forward model fitted to a bench recording\n"
        "[skin]\n"
        f"footprint_sigma_mm = {{ {indenter} = {fit['sigma_mm']:.4f} }}\n"
        f"contact_counts = {fit['contact_counts']:.4f}\n"
        f"gap_decay_mm = {fit['gap_decay_mm']:.4f}\n"
        f"height_as_distance = {fit['height_as_distance']:.4f}\n"
        f"height_as_gap = {fit['height_as_gap']:.4f}\n"
        f"widening_per_mm = {fit['widening_per_mm']:.4f}\n"
        "gain_spread = 0.0\n"
        f'taxel_gain = "{gains_name}"\n'
        f"noise_std_counts = {noise:.4f}\n"
    )


@dataclass(frozen=True)
class CalibrateInputs:
    """What calibrating reads of the scene: its [board] (the recording's frames and the
    taxels' cells in them), ``[detection].baseline_frames`` (the idle frames when the
    recording's meta does not give them) and its [skin] (an electrostatic calibration
    carries its crossing keys over). The stages and the command build it
    (`fruitcli.sensing.inputs_stage.calibrate_inputs`)."""

    board: BoardSection
    baseline_frames: int
    skin: SkinSection


@dataclass(frozen=True)
class BenchRun:
    """A bench recording read for calibration: its taxels, their counts (N, T) in every
    frame, how many idle frames it starts with, its indenter, how many samples it has,
    and its descent frames (M,) with their contact points (M, 3) mm and gaps (M,) mm
    (`descent_gaps`)."""

    taxels: Taxels
    counts: np.ndarray
    n_idle: int
    indenter: str
    samples: int
    frames: np.ndarray
    contact: np.ndarray
    gaps: np.ndarray


def read_bench_run(
    inputs: CalibrateInputs,
    frames_path: str | Path,
    truth_csv: str | Path,
    taxels_csv: str | Path,
    indenter: str | None = None,
) -> BenchRun:
    """The recording `frames_path` of taxels `taxels_csv` on the [board] and its
    truth.csv, checked against each other; `indenter` (None: the recording's meta);
    FrameError naming the file when they do not fit."""
    from fruitcli.sensing.frames.board import taxel_cells
    from fruitcli.sensing.frames.recording import read_recording
    from fruitcli.tables import read_table

    board = inputs.board
    taxels = read_taxels(taxels_csv, FrameError)
    rows, cols = taxel_cells(taxels, board, str(taxels_csv))
    rec = read_recording(frames_path, board.rows, board.cols, board.format)
    where = str(frames_path)
    truth = read_table(Path(truth_csv), ["sample", "x_mm", "y_mm", "z_mm"], error=FrameError)
    ids = integer_column(Path(truth_csv), truth, "sample", FrameError)
    if rec.sample is None:
        raise FrameError(f"{where}: no 'sample' key: not a bench recording")
    check_samples(rec.sample, ids, where, str(truth_csv))
    name = indenter or rec.meta.get("indenter")
    if not name:
        raise FrameError(f"{where}: meta names no indenter: give --indenter")
    n_idle = int(rec.meta.get("baseline_frames", inputs.baseline_frames))
    if not 1 < n_idle < len(rec):
        raise FrameError(
            f"{where}: {n_idle} idle frames (meta baseline_frames): expected 2 .. {len(rec) - 1}"
        )
    pts = np.stack([truth["x_mm"], truth["y_mm"], truth["z_mm"]], axis=1)
    point = dict(zip(ids.tolist(), pts, strict=True))
    frames, samples, gaps = descent_gaps(rec, {k: p[2] for k, p in point.items()}, n_idle, where)
    return BenchRun(
        taxels,
        rec.frames[:, rows, cols].astype(float),
        n_idle,
        str(name),
        len(ids),
        frames,
        np.stack([point[int(k)] for k in samples]),
        gaps,
    )


def run_calibrate(
    inputs: CalibrateInputs,
    frames_path: str | Path,
    truth_csv: str | Path,
    taxels_csv: str | Path,
    out_dir: str | Path,
    indenter: str | None = None,
    progress: Callable[[str], None] | None = None,
    response: CrossingSkin | None = None,
) -> dict:
    """Fit the skin to a bench recording (`read_bench_run`); write DIR/skin.toml,
    DIR/gains.csv and DIR/calibration.json (`write_calibration`). -> the summary.
    `response`: the electrostatic skin (`crossing_skin.CrossingSkin`, ``[skin].model =
    "electrostatic"``): its counts per fF and the gains are fitted
    (`calibrate_crossing`); None: the Gaussian model's footprint, activation and gap
    decay."""
    say = progress or (lambda msg: None)
    run = read_bench_run(inputs, frames_path, truth_csv, taxels_csv, indenter)
    taxels, name = run.taxels, run.indenter
    idle = run.counts[: run.n_idle]
    v = run.counts[run.frames] - idle.mean(axis=0)
    say(f"fitting {len(run.frames)} descent frames of {run.samples} samples x {len(taxels)} taxels")
    noise, noise_per = noise_std_counts(idle)
    if response is None:
        offset = run.contact[:, None, :] - taxels.xyz_mm[None, :, :]
        dist, height = np.linalg.norm(offset, axis=2), offset[:, :, 2]
        fit = _gains_over_taxels(fit_skin(v, dist, run.gaps, height), "contact_counts", v, run)
        toml = skin_toml(name, fit, noise)
        figures = {
            "footprint_sigma_mm": fit["sigma_mm"],
            "contact_counts": fit["contact_counts"],
            "gap_decay_mm": fit["gap_decay_mm"],
            "height_as_distance": fit["height_as_distance"],
            "height_as_gap": fit["height_as_gap"],
            "height_form_gain": fit["height_form_gain"],
            "widening_per_mm": fit["widening_per_mm"],
            "widening_gain": fit["widening_gain"],
        }
        fitted = (
            f"sigma {fit['sigma_mm']:.2f} mm, contact {fit['contact_counts']:.1f} counts, gap "
            f"decay {fit['gap_decay_mm']:.2f} mm, height as distance "
            f"{fit['height_as_distance']:.2f} and as gap {fit['height_as_gap']:.2f}, widening "
            f"{fit['widening_per_mm']:.3f} per mm"
        )
    else:
        from fruitcli.sensing.skin import calibrate_crossing as cc

        response.object_index(name)  # the table must hold the recording's indenter
        drop = cc.drop_ff(response, name, run.contact, taxels.xyz_mm, run.gaps)
        fit = cc.fit_scale(v, drop, MEASURED_MIN_COUNTS, GAUGE_WEIGHT)
        fit = _gains_over_taxels(fit, "counts_per_ff", v, run)
        toml = cc.skin_toml(inputs.skin, fit, noise)
        figures = {"skin_model": "electrostatic", "counts_per_ff": fit["counts_per_ff"]}
        fitted = f"{fit['counts_per_ff']:.4g} counts per fF"
    summary = {
        "indenter": name,
        **figures,
        "noise_std_counts": noise,
        "rms_residual_counts": fit["rms_counts"],
        "frames": int(len(run.frames)),
        "samples": run.samples,
        "taxels_measured": int(fit["measured"].sum()),
        "gains_over_taxels": int(fit["over"].sum()),
        "taxels": len(taxels),
        "idle_frames": run.n_idle,
        "recording": str(frames_path),
        "truth": str(truth_csv),
    }
    write_calibration(out_dir, toml, taxels, fit, noise_per, summary)
    say(
        f"{fitted}, noise {noise:.2f} counts, {int(fit['measured'].sum())}/{len(taxels)} "
        f"gains measured, rms residual {fit['rms_counts']:.2f} counts"
    )
    return summary


def _gains_over_taxels(fit: dict, amplitude: str, v: np.ndarray, run: BenchRun) -> dict:
    """`fit` with the gains of the taxels the run has samples right over taken from those
    (`taxel_gains`: the law does not enter them), the others as fitted; the law's
    `amplitude` key takes their common factor. Adds ``over`` (T,)."""
    from fruitcli.sensing.skin.taxel_gains import combine, gains_over_taxels

    gain, over = gains_over_taxels(v, run.contact, run.gaps, run.taxels.xyz_mm)
    fit = {**fit, "over": over}
    if over.any():
        fit["gain"], fit["measured"], factor = combine(fit["gain"], fit["measured"], gain, over)
        fit[amplitude] *= factor
    return fit


def write_calibration(
    out_dir: str | Path,
    toml: str,
    taxels: Taxels,
    fit: dict,
    noise_per: np.ndarray,
    summary: dict,
) -> None:
    """DIR/skin.toml (`toml`), DIR/gains.csv (each taxel's fitted gain, noise std (T,)
    counts and whether it was measured) and DIR/calibration.json (`summary`), all or
    none."""
    from fruitcli.fsutil import staged_dir, write_csv, write_json, write_text

    with staged_dir(out_dir) as tmp:
        write_text(tmp / "skin.toml", toml)
        write_csv(
            tmp / "gains.csv",
            ["id", "i", "j", "gain", "noise_std_counts", "measured"],
            (
                [
                    int(taxels.ids[k]),
                    int(taxels.i[k]),
                    int(taxels.j[k]),
                    float(fit["gain"][k]),
                    float(noise_per[k]),
                    int(fit["measured"][k]),
                ]
                for k in range(len(taxels))
            ),
            comments=[
                "per-taxel gain (mean 1 over measured taxels; 1 where not "
                "measured; from the samples right over the taxel where the run has them) "
                "and noise std (counts) from fruit calibrate"
            ],
        )
        write_json(tmp / "calibration.json", summary)
