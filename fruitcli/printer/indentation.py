"""The paper's bench protocol (Sec. V-B) on a real printer and board.

Units: mm (printer and model coordinates), mm/min, counts, s. For each sample point (as
the virtual bench: a quarter taxel off each taxel, or the [bench].samples CSV, with the
model surface under it): move at the safe height above it (``[printer].safe_height_mm``
above the model's highest point), go down to ``START_GAP_MM`` above the expected surface,
then descend in ``step_mm`` steps; after each move wait for it to finish (M400) and read
the next whole board frame that began after that (`BoardStream.next_frame_after`); stop at the first
frame in which some taxel's v = C - C0 exceeds the threshold (C0: the mean of the
larger of ``[bench].baseline_frames`` and ``[detection].baseline_frames`` frames at the
safe height before the first sample, so `fruit locate` finds the same baseline): that
frame and the position are the sample's; retract to the safe height; next sample. The
printer's position is checked with M114 at each sample's start and touch.

A sample outside ``bed_mm``, no touch before ``max_press_mm`` below the expected surface,
a printer error or time-out, a board or printer port that vanishes, Ctrl-C: the tip is
retracted (when the printer still answers), every frame recorded so far is written, and
the run stops with one line naming the sample. Outputs are those of the virtual bench,
``<out>/<indenter>/frames.npz`` (with ``printer_mm`` (N, 3) for every frame) and
``truth.csv`` in model coordinates, so `fruit locate` and `fruit evaluate` work unchanged.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fruitcli.errors import FrameError, FruitError
from fruitcli.fsutil import write_csv
from fruitcli.geometry.body_surface import surface_heights, taxel_surface_heights
from fruitcli.printer.marlin import Marlin, PrinterError, PrinterGone, PrinterHalted
from fruitcli.printer.placement import Placement
from fruitcli.scene import BoardSection, PrinterSection
from fruitcli.sensing.frames.board import taxel_cells
from fruitcli.sensing.frames.recording import Recording, write_npz
from fruitcli.sensing.skin.virtual_bench import START_GAP_MM
from fruitcli.tables import read_taxels

if TYPE_CHECKING:
    from fruitcli.sensing.bench_stage import SampleSpec
    from fruitcli.sensing.live.serial_ports import FrameReader
    from fruitcli.tables import Taxels

POSITION_TOL_MM = 0.02  # M114 against the commanded position
FRAME_TIMEOUT_S = 5.0  # longest wait for a board frame after a move
RETRACT_TIMEOUT_S = 10.0  # the retract after an error waits this long for its ok
YIELD_S = 0.0005  # the board reader's pause between reads
POINT_HEADER = ["sample", "x_mm", "y_mm", "z_mm"]


class BenchStopped(FruitError):
    """The bench stopped at a sample (bed limit, no touch, printer or board failure)."""


@dataclass(frozen=True)
class PrinterBenchInputs:
    """What the printer bench reads of the scene: its name and file name (for the
    recording's meta and the messages), [printer], [board], the touch threshold
    (``[detection].threshold_counts``), the idle frames before the first sample (the
    larger of ``[bench].baseline_frames`` and ``[detection].baseline_frames``), the FEM
    state the samples are on (``[bench].state``) and where they are (``[bench].samples``)."""

    scene_name: str
    file_name: str
    printer: PrinterSection
    board: BoardSection
    threshold_counts: float
    baseline_frames: int
    state: int
    samples: SampleSpec


def bench_samples(
    state: int, samples: SampleSpec, taxels: Taxels, states_npz: str | Path | None
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """(sample ids (m,), contact points (m, 3) model mm, highest model z mm, samples in
    all): the virtual bench's sample points over the surface, at FEM `state` with
    `states_npz`."""
    from fruitcli.sensing.bench_stage import spec_points
    from fruitcli.sensing.detection.locate import load_states

    if states_npz is not None:
        states = load_states(states_npz, len(taxels))
        taxels_mm = states.taxels_mm[state]
        xy = spec_points(samples, taxels_mm)
        nodes = states.nodes_mm(state)
        z = surface_heights(xy, nodes, states.surface_tris)
        top = float(nodes[:, 2].max())
    else:
        taxels_mm = taxels.xyz_mm
        xy = spec_points(samples, taxels_mm)
        z = taxel_surface_heights(xy, taxels_mm)
        top = float(taxels_mm[:, 2].max())
    ids = np.flatnonzero(np.isfinite(z))
    return ids, np.column_stack([xy[ids], z[ids]]), top, len(xy)


class BenchLog:
    """Every frame read, with the tip position and the sample it closes (-1: none)."""

    def __init__(self):
        self.frames, self.t_s, self.printer_mm, self.sample = [], [], [], []
        self.truth: list[tuple[int, np.ndarray]] = []

    def add(self, counts: np.ndarray, t_s: float, tip_mm: np.ndarray, sample: int = -1) -> None:
        self.frames.append(counts)
        self.t_s.append(t_s)
        self.printer_mm.append(np.asarray(tip_mm, float))
        self.sample.append(sample)

    def save(self, out: Path, meta: dict, indenter: str) -> None:
        if not self.frames:
            return
        rec = Recording(
            np.stack(self.frames),
            np.asarray(self.t_s, float),
            sample=np.asarray(self.sample, np.int64),
            meta=meta,
            printer_mm=np.stack(self.printer_mm),
        )
        write_npz(out / "frames.npz", rec)
        write_csv(
            out / "truth.csv",
            POINT_HEADER,
            ([k, *map(float, p)] for k, p in self.truth),
            comments=[
                f"printer bench contact points ({indenter} indenter): the model "
                "surface under each sample, model coordinates, mm"
            ],
        )


class BoardStream:
    """Reads the board all the time in a thread (as a host must: a board whose port
    fills up sends stale frames), keeping the recent frames with the stream offset of
    their first byte."""

    def __init__(self, reader: FrameReader):
        import collections
        import threading

        self.reader = reader
        self.frames: collections.deque = collections.deque(maxlen=256)
        self.error: FruitError | None = None
        self.stop = threading.Event()
        self.cond = threading.Condition()
        self.read_lock = threading.Lock()  # a byte is counted read or waiting, never both
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.is_set():
            try:
                with self.read_lock:
                    got = self.reader.poll()
            except FruitError as exc:  # the port vanished
                with self.cond:
                    self.error = exc
                    self.cond.notify_all()
                return
            if got:
                with self.cond:
                    self.frames.extend(got)
                    self.cond.notify_all()
            time.sleep(YIELD_S)  # let next_frame_after take the read lock

    def next_frame_after(self, timeout_s: float = FRAME_TIMEOUT_S) -> tuple[np.ndarray, float]:
        """The next whole frame whose first byte arrived after now: (counts, t_s)."""
        with self.read_lock:
            try:
                waiting = self.reader.port.in_waiting
            except (OSError, TypeError, ValueError):
                waiting = 0  # the port vanished: the reading thread reports it
            mark = self.reader.bytes_read + waiting
        with self.cond:
            end = time.monotonic() + timeout_s
            while True:
                while self.frames:
                    counts, t_s, start = self.frames.popleft()
                    if start >= mark:
                        return counts, t_s
                if self.error is not None:
                    raise self.error
                left = end - time.monotonic()
                if left <= 0:
                    break
                self.cond.wait(left)
        why = self.reader.skip_reasons()
        raise FrameError(
            f"{self.reader.name}: no whole board frame within {timeout_s:g} s "
            "after the move" + (f" ({why})" if why else "")
        )

    def close(self) -> None:
        self.stop.set()
        self.thread.join(1.0)


def _move(printer: Marlin, tip: np.ndarray, feed: float) -> None:
    """Queue a move of the tip to `tip` (x, y, z) mm at `feed` mm/min."""
    printer.move(float(tip[0]), float(tip[1]), float(tip[2]), feed)


def check_reach(
    pr: Any, placement: Placement, contact_mm: np.ndarray, top_z: float, where: str
) -> float:
    """The safe height in printer z (mm); it must be reachable (`pr`: the scene's
    [printer] record)."""
    z_safe = float(placement.origin[2] + top_z + pr.safe_height_mm)
    bed = pr.bed_mm
    if z_safe > bed[5]:
        raise BenchStopped(
            f"{where}: [printer].safe_height_mm: the safe height, printer z = "
            f"{z_safe:.2f} mm ({pr.safe_height_mm:g} mm above the model's "
            f"top), is above the bed's reachable z max {bed[5]:g} mm"
        )
    if placement.origin[2] + contact_mm[:, 2].min() - pr.max_press_mm < bed[2] - 1e-9:
        raise BenchStopped(
            f"{where}: [printer].model_origin_mm: the model's surface minus "
            f"max_press_mm lies below the bed's z min {bed[2]:g} mm"
        )
    return z_safe


def outside_bed(p: np.ndarray, z_low: float, z_safe: float, bed: Sequence[float]) -> bool:
    return not (
        bed[0] <= p[0] <= bed[3]
        and bed[1] <= p[1] <= bed[4]
        and z_low >= bed[2]
        and z_safe <= bed[5]
    )


def run_printer_bench(
    inputs: PrinterBenchInputs,
    taxels_csv: str | Path,
    states_npz: str | Path | None,
    printer_port: str,
    board_port: str,
    out_dir: str | Path,
    indenter: str,
    fmt: str = "auto",
    board_baud: int = 115200,
    progress: Callable[[str], None] | None = None,
    overwrite: bool = False,
) -> dict:
    """Run the bench on a printer and a board; -> summary. Raises BenchStopped (after
    saving what was recorded) when it cannot finish."""
    from fruitcli.sensing.live.serial_ports import FrameReader

    say = progress or (lambda msg: None)
    pr = inputs.printer
    out = Path(out_dir) / indenter
    _check_overwrite(out / "frames.npz", overwrite)
    taxels = read_taxels(taxels_csv, FrameError)
    board = inputs.board
    rows, cols = taxel_cells(taxels, board, str(taxels_csv))
    threshold = inputs.threshold_counts
    # idle frames first: enough for the bench's C0 and for `fruit locate`'s baseline
    n_base = inputs.baseline_frames
    placement = Placement.from_printer(pr)
    ids, contact, top, n_all = bench_samples(inputs.state, inputs.samples, taxels, states_npz)
    if not len(ids):
        raise BenchStopped(f"{inputs.file_name}: no sample point over the taxels' surface")
    z_safe = check_reach(pr, placement, contact, top, inputs.file_name)
    feed = pr.feed_mm_min
    say(
        f"{len(ids)} samples ({n_all - len(ids)} off the surface left out), safe height "
        f"z = {z_safe:.2f} mm, {indenter} indenter"
    )
    ser, bser = _open_ports(printer_port, pr.baud, board_port, board_baud)
    printer = Marlin(ser, printer_port, pr.timeout_s, log=say)
    stream = BoardStream(FrameReader(bser, board.rows, board.cols, board_port, fmt))
    log = BenchLog()
    meta = _bench_meta(inputs, indenter, (printer_port, board_port), placement)
    where = "start-up"
    tip = None
    try:
        printer.wait_ready()
        printer.command("G21")
        printer.command("G90")
        if pr.home:
            say("homing (G28)")
            printer.command("G28")
        x0, y0, _ = printer.position()
        tip = np.array([x0, y0, z_safe])
        _move(printer, tip, feed)
        printer.finish_moves()
        c0 = _baseline(stream, log, tip, n_base, (rows, cols))
        say(f"baseline from {n_base} frames ({stream.reader.format} board)")
        for n, (k, p_model) in enumerate(zip(ids, contact, strict=True)):
            where = f"sample {k} (model x {p_model[0]:.2f}, y {p_model[1]:.2f} mm)"
            p = placement.to_printer(p_model)
            z_low = p[2] - pr.max_press_mm
            if outside_bed(p, z_low, z_safe, pr.bed_mm):
                raise BenchStopped(
                    f"{where}: printer x {p[0]:.2f}, y {p[1]:.2f}, z "
                    f"{z_low:.2f}..{z_safe:.2f} mm is outside [printer].bed_mm "
                    f"{pr.bed_mm}"
                )
            tip = np.array([p[0], p[1], z_safe])
            _move(printer, tip, feed)
            tip = np.array([p[0], p[1], p[2] + START_GAP_MM])
            _move(printer, tip, feed)
            printer.finish_moves()
            check_position(printer, tip, where)
            # the descent keeps x, y: a stop within it retracts from the same place
            bar = (c0, (rows, cols), threshold)
            _press(printer, stream, log, tip, (int(k), p_model), bar, pr, z_low, where)
            tip = np.array([p[0], p[1], z_safe])
            _move(printer, tip, feed)
            say(f"{where}: touch at printer z {log.printer_mm[-1][2]:.2f} mm ({n + 1}/{len(ids)})")
        printer.finish_moves()
    except (FruitError, KeyboardInterrupt) as exc:
        meta["stopped"] = _stop_line(exc, where)
        retracted = retract(printer, tip, z_safe, feed, exc)
        log.save(out, meta, indenter)
        raise _stopped(exc, where, log, out, retracted or tip is None) from None
    finally:
        stream.close()
        ser.close()
        bser.close()
    log.save(out, meta, indenter)
    return {
        "indenter": indenter,
        "samples": len(log.truth),
        "frames": len(log.frames),
        "off_surface": n_all - len(ids),
        "resends": printer.resends,
        "out": str(out),
    }


class BenchInterrupted(BenchStopped):
    """Ctrl-C: everything recorded was saved and the tip retracted."""


def _press(
    printer: Marlin,
    stream: BoardStream,
    log: BenchLog,
    tip: np.ndarray,
    sample: tuple[int, np.ndarray],
    bar: tuple,
    pr: Any,
    z_low: float,
    where: str,
) -> None:
    """Lower the tip from `tip` (x, y, z) mm in [printer].step_mm steps until a frame
    closes `sample` (id, model point mm): `bar` = (baseline counts c0 (T,), the taxels'
    board cells (rows, cols), threshold counts), a touch when some taxel rises more than
    the threshold over c0. BenchStopped below z = `z_low` mm (`pr`: the [printer] record)."""
    c0, (rows, cols), threshold = bar
    k, p_model = sample
    while True:
        counts, t_s = stream.next_frame_after()
        if np.any(counts[rows, cols] - c0 > threshold):
            log.add(counts, t_s, tip, k)
            check_position(printer, tip, where)
            log.truth.append((k, p_model))
            return
        log.add(counts, t_s, tip)
        z = tip[2] - pr.step_mm
        if z < z_low - 1e-9:
            raise BenchStopped(
                f"{where}: no touch registered down to "
                f"[printer].max_press_mm = {pr.max_press_mm:g} mm "
                "below the expected surface"
            )
        tip = np.array([tip[0], tip[1], z])
        _move(printer, tip, pr.feed_mm_min)
        printer.finish_moves()


def _check_overwrite(frames_npz: Path, overwrite: bool) -> None:
    """Refuse to replace an earlier run's frames without --overwrite."""
    if frames_npz.exists() and not overwrite:
        raise BenchStopped(
            f"{frames_npz}: exists; give --overwrite to replace it "
            "(it is replaced once the new run has frames)"
        )


def _open_ports(printer_port: str, baud: int, board_port: str, board_baud: int) -> tuple:
    """(the printer's port, the board's port), open; neither is left open on a failure."""
    from fruitcli.sensing.live.serial_ports import open_port

    ser = open_port(printer_port, baud)
    try:
        bser = open_port(board_port, board_baud)
    except FrameError:
        ser.close()
        raise
    return ser, bser


def _bench_meta(
    inputs: PrinterBenchInputs, indenter: str, ports: tuple[str, str], placement: Placement
) -> dict:
    """The recording's meta: the scene, indenter, ports (printer, board), the bench's
    settings and the model's placement on the bed; "stopped" is set when it stops."""
    pr = inputs.printer
    return {
        "source": "printer bench",
        "scene": inputs.scene_name,
        "indenter": indenter,
        "printer_port": ports[0],
        "board_port": ports[1],
        "step_mm": pr.step_mm,
        "threshold_counts": inputs.threshold_counts,
        "baseline_frames": inputs.baseline_frames,
        "model_origin_mm": list(placement.origin),
        "rotate_z_deg": pr.rotate_z_deg,
        "stopped": "",
    }


def _baseline(
    stream: BoardStream, log: BenchLog, tip: np.ndarray, n_base: int, cells: tuple
) -> np.ndarray:
    """The taxels' idle counts C0 (T,): the mean of the next `n_base` frames at the
    taxels' board `cells` (rows, cols), each frame logged at `tip`."""
    for _ in range(n_base):
        counts, t_s = stream.next_frame_after()
        log.add(counts, t_s, tip)
    rows, cols = cells
    return np.mean([f[rows, cols] for f in log.frames], axis=0)


def _stop_line(exc: BaseException, where: str) -> str:
    """The recording's meta "stopped": where the bench stopped and why."""
    stopped = "interrupted (Ctrl-C)" if isinstance(exc, KeyboardInterrupt) else str(exc)
    return f"{where}: {stopped}" if where not in stopped else stopped


def _stopped(
    exc: BaseException, where: str, log: BenchLog, out: Path, retracted: bool
) -> BenchStopped:
    """The error a stopped bench ends with: where, why, what was kept in `out`, and
    whether the tip was left down (`retracted` False)."""
    kept = (
        f"{len(log.frames)} frames and {len(log.truth)} samples kept in {out}"
        if log.frames
        else "no frame recorded"
    )
    tail = "" if retracted else " (not retracted: the printer does not answer)"
    if isinstance(exc, KeyboardInterrupt):
        return BenchInterrupted(f"interrupted at {where}; {kept}{tail}")
    msg = str(exc) if where in str(exc) else f"{where}: {exc}"
    return BenchStopped(f"{msg}; {kept}{tail}")


def retract(
    printer: Marlin, tip: np.ndarray | None, z_safe: float, feed: float, exc: BaseException
) -> bool:
    """Lift the tip to the safe height when the printer can still take commands."""
    if tip is None or isinstance(exc, (PrinterGone, PrinterHalted)):
        return False
    try:
        printer.timeout_s = min(printer.timeout_s, RETRACT_TIMEOUT_S)
        printer.move(tip[0], tip[1], z_safe, feed)
        printer.finish_moves()
        return True
    except (PrinterError, KeyboardInterrupt):
        return False


def check_position(printer: Marlin, tip: np.ndarray, where: str) -> None:
    """M114 must report the commanded position (within POSITION_TOL_MM)."""
    got = np.asarray(printer.position())
    if np.max(np.abs(got - tip)) > POSITION_TOL_MM:
        raise BenchStopped(
            f"{where}: the printer reports X{got[0]:.2f} Y{got[1]:.2f} "
            f"Z{got[2]:.2f} after a move to X{tip[0]:.2f} Y{tip[1]:.2f} "
            f"Z{tip[2]:.2f} (software endstops or lost steps)"
        )
