"""Sensing speed: detection + 3D location in batch (replay) and per frame (live loop),
and `fruit locate` end to end on long recordings.

Targets: >= 100,000 frames/s in batch on 21 x 12 frames; <= 0.1 ms median per
frame in the live loop. 47 taxels on a 12 x 7 taxel grid, half the frames touched
(one or two touches), taxels moving through 5 FEM states by chamber pressure.
Targets: `fruit locate` >= 200,000 frames/s end to end (the whole command on
200,000 frames minus the whole command on 20,000; 252 taxels on the full 21 x 12 board,
a touch in every frame) and < 2 GB peak memory on 1,000,000 frames.
`python tests/performance/bench_sensing.py recordings` runs only the latter,
`python tests/performance/bench_sensing.py model` only the model method's figures,
`python tests/performance/bench_sensing.py latency` only the OSC latency.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.frames.muca_line import format_line, parse_line
from fruitcli.tables import Taxels, read_taxels

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # tests.helpers


def fruit_like_taxels() -> Taxels:
    grid_i, grid_j = np.meshgrid(np.arange(12), np.arange(7), indexing="ij")
    i, j = grid_i.ravel(), grid_j.ravel()
    keep = np.hypot((i - 5.5) / 6.5, (j - 3) / 4.2) <= 1.0  # an oval patch
    i, j = i[keep][:47], j[keep][:47]
    xyz = np.stack([16.0 * i, 12.0 * j, 5 * np.sin(i / 3)], axis=1)
    return Taxels(np.arange(len(i)), i, j, xyz)


def frames_with_touches(n: int, taxels: Taxels, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    f = 500 + rng.normal(0, 1.5, (n, 21, 12))
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    for k in range(2):
        touched = rng.random(n) < (0.5 if k == 0 else 0.15)
        centre = (
            taxels.i[rng.integers(len(taxels), size=n)],
            taxels.j[rng.integers(len(taxels), size=n)],
        )
        blob = 60 * np.exp(
            -(
                (r - centre[0][:, None, None] - 0.3) ** 2
                + (c - centre[1][:, None, None] + 0.25) ** 2
            )
            / 1.2
        )
        f += blob * touched[:, None, None]
    return np.maximum(np.round(f), 0).astype(np.int64)


def main():
    taxels = fruit_like_taxels()
    states = np.stack([taxels.xyz_mm + [0, 0, 2.0 * s] for s in range(5)])
    state_kpa = np.stack([np.linspace(0, 8, 5), np.linspace(0, 4, 5)], axis=1)
    settings = Settings(baseline_frames=10)
    loc = Locator(taxels, default_board(), states, settings, state_kpa)
    n = 200_000
    frames = frames_with_touches(n, taxels)
    kpa = np.random.default_rng(1).uniform(0, 8, (n, 2))
    base = loc.baseline(frames)
    loc.batch(frames[:1000], base, kpa[:1000])  # warm up
    t0 = time.perf_counter()
    table = loc.batch(frames, base, kpa)
    dt = time.perf_counter() - t0
    print(
        f"batch: {n} frames of 21x12, {len(table)} touches, {dt:.3f} s -> "
        f"{n / dt:,.0f} frames/s (target >= 100,000)"
    )
    rest = Locator(taxels, default_board(), taxels.xyz_mm, settings)
    t0 = time.perf_counter()
    rest.batch(frames, base)
    dt = time.perf_counter() - t0
    print(f"batch at rest (no pressure interpolation): {n / dt:,.0f} frames/s")

    stream = Stream(loc, base)
    values = loc.values(frames[:20_000])
    times = np.empty(len(values))
    for k, v in enumerate(values):
        t = time.perf_counter()
        stream.step(v, kpa[k], k)
        times[k] = time.perf_counter() - t
    print(
        f"live loop (detect + locate per frame): median {np.median(times) * 1e3:.4f} ms, "
        f"p99 {np.percentile(times, 99) * 1e3:.4f} ms (target median <= 0.1 ms)"
    )
    lines = [format_line(f) for f in frames[:5000]]
    t0 = time.perf_counter()
    for line in lines:
        parse_line(line, 252)
    dt = (time.perf_counter() - t0) / len(lines)
    from fruitcli.sensing.frames.muca import AsciiDecoder

    dec = AsciiDecoder(21, 12)
    raw = [(line + "\r\n").encode() for line in lines]
    dec.feed(raw[0])
    t0 = time.perf_counter()
    for packet in raw:
        dec.feed(packet)
    fast = (time.perf_counter() - t0) / len(raw)
    print(
        f"live loop line parsing (252 counts): {fast * 1e3:.4f} ms per frame through the "
        f"board decoder (compiled fast path), {dt * 1e3:.4f} ms by parse_line (odd lines)"
    )
    recordings()


# method, [detection].model_frames, the skin's [skin].height_as_gap ("as gap": a calibrated
# electrostatic board's form, 0.7, height_as_distance 0, widening_per_mm WIDENING; a touch
# at the grid's edge placed by its peak taxel whose fit leaves more than the noise gets a
# second fit, `model_fit._mirror_spread`)
METHOD_FRAMES = (("n9", 1, 0.0), ("model", 1, 0.0), ("model", 8, 0.0), ("model", 1, 0.7))
WIDENING = 0.07  # per mm of gap, about what `fruit calibrate` finds for that board


def _heights(as_gap: float):
    """The default skin's gap law, with the height difference as gap and the footprint
    widening with the gap (``WIDENING``) when `as_gap` > 0."""
    if not as_gap:
        return None
    from dataclasses import replace

    from fruitcli.sensing.skin.forward import DEFAULT_PARAMS
    from fruitcli.sensing.skin.heights import gap_law

    form = replace(
        DEFAULT_PARAMS, height_as_gap=as_gap, height_as_distance=0.0, widening_per_mm=WIDENING
    )
    return gap_law(form)


def _method_name(method: str, frames: int, as_gap: float) -> str:
    name = method if frames == 1 else f"{method}, mean of {frames} frames"
    return name if not as_gap else f"{name}, height as gap {as_gap}, widening {WIDENING}"


def model_method(n: int = 100_000) -> None:
    """The model method ([detection].method = "model"): batch frames/s on the same frames
    as N9 (taxels moving through the states), and the live loop's time per frame with
    10 touches on the full 21 x 12 board (target p99 <= 1 ms)."""
    taxels = fruit_like_taxels()
    states = np.stack([taxels.xyz_mm + [0, 0, 2.0 * s] for s in range(5)])
    state_kpa = np.stack([np.linspace(0, 8, 5), np.linspace(0, 4, 5)], axis=1)
    frames = frames_with_touches(n, taxels)
    kpa = np.random.default_rng(1).uniform(0, 8, (n, 2))
    for method, k, as_gap in METHOD_FRAMES:
        settings = Settings(method=method, model_frames=k)
        heights = _heights(as_gap)
        loc = Locator(taxels, default_board(), states, settings, state_kpa, heights=heights)
        base = loc.baseline(frames)
        method = _method_name(method, k, as_gap)
        loc.batch(frames[:1000], base, kpa[:1000])  # warm up (numba's first compile)
        t0 = time.perf_counter()
        table = loc.batch(frames, base, kpa)
        dt = time.perf_counter() - t0
        print(
            f"batch, method {method}: {n} frames, {len(table)} touches, {dt:.3f} s -> "
            f"{n / dt:,.0f} frames/s on one thread (target >= 100,000)"
        )
        workers = min(os.cpu_count() or 1, 4)  # as fruit locate runs its chunks
        t0 = time.perf_counter()
        total = sum(
            len(t)
            for t in loc.chunks(lambda a, k: frames[a : a + k], n, base, kpa, workers=workers)
        )
        dt = time.perf_counter() - t0
        print(
            f"batch, method {method}, {workers} threads: {total} touches, {dt:.3f} s -> "
            f"{n / dt:,.0f} frames/s (target >= 100,000)"
        )
    i, j = (a.ravel() for a in np.meshgrid(np.arange(21), np.arange(12), indexing="ij"))
    board = Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0 * i], axis=1))
    rng = np.random.default_rng(3)
    centres = np.stack([rng.uniform(0, 320, (2000, 10)), rng.uniform(0, 132, (2000, 10))], -1)
    d = np.linalg.norm(board.xyz_mm[None, None, :, :2] - centres[:, :, None, :], axis=3)
    v = (60 * np.exp(-0.5 * (d / 6.18) ** 2)).sum(axis=1) + rng.normal(0, 1.2, (2000, i.size))
    for method, k, as_gap in METHOD_FRAMES:
        settings = Settings(method=method, model_frames=k)
        loc = Locator(board, default_board(), board.xyz_mm, settings, heights=_heights(as_gap))
        stream = Stream(loc, np.zeros(i.size))
        method = _method_name(method, k, as_gap)
        stream.step(v[0])
        times, touches = np.empty(len(v)), 0
        for k, frame in enumerate(v):
            t = time.perf_counter()
            touches += len(stream.step(frame, None, k))
            times[k] = time.perf_counter() - t
        print(
            f"live loop, method {method}, 10 touches ({touches / len(v):.1f} found per "
            f"frame): median {np.median(times) * 1e3:.3f} ms, p99 "
            f"{np.percentile(times, 99) * 1e3:.3f} ms per frame (target p99 <= 1 ms)"
        )


def write_touch_recording(path: Path, n: int, seed: int = 0, chunk: int = 20_000) -> None:
    """An n-frame 21 x 12 recording .npz written in chunks (as np.savez lays it out):
    10 flat baseline frames, then a touch in every frame (30 % of them a second one)."""
    rng = np.random.default_rng(seed)
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    header = {
        "descr": np.lib.format.dtype_to_descr(np.dtype("<i8")),
        "fortran_order": False,
        "shape": (n, 21, 12),
    }
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        with zf.open("frames.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, header)
            for a in range(0, n, chunk):
                m = min(chunk, n - a)
                f = 500.0 + rng.integers(-2, 3, (m, 21, 12))
                for amp, share in ((60.0, 1.0), (45.0, 0.3)):
                    ci = rng.uniform(0, 20, m)[:, None, None]
                    cj = rng.uniform(0, 11, m)[:, None, None]
                    on = (rng.random(m) < share)[:, None, None]
                    f += on * amp * np.exp(-((r - ci) ** 2 + (c - cj) ** 2) / 1.2)
                if a == 0:
                    f[:10] = 500.0
                fh.write(np.round(f).astype("<i8").tobytes())
        for key, arr in (
            ("t_s", np.arange(n) / 100.0),
            ("meta", np.array(json.dumps({"source": "bench_sensing"}))),
        ):
            with zf.open(f"{key}.npy", "w") as fh:
                np.lib.format.write_array(fh, arr)


def full_board_taxels(path: Path) -> Path:
    """252 taxels, one on every cell of the 21 x 12 board (the largest grid)."""
    lines = ["id,i,j,x_mm,y_mm,z_mm"]
    lines += [
        f"{i * 12 + j},{i},{j},{16.0 * j},{12.0 * i},{np.sin(i / 3):.6f}"
        for i in range(21)
        for j in range(12)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


# Forks the command from this small process, so that the command's peak memory (which on
# Linux counts what its parent held when it forked) is not the benchmark's own.
_TRAMPOLINE = """
import json, os, sys, time
t0 = time.perf_counter()
pid = os.fork()
if pid == 0:
    os.execv(sys.argv[1], sys.argv[1:])
_, status, usage = os.wait4(pid, 0)
print(json.dumps([time.perf_counter() - t0, usage.ru_utime + usage.ru_stime,
                  usage.ru_maxrss / 1024, os.waitstatus_to_exitcode(status)]))
"""


def run_command(args: list[str]) -> tuple[float, float, float]:
    """Run a command; (wall s, user + sys CPU s, peak resident memory MB) of it alone."""
    proc = subprocess.run(
        [sys.executable, "-c", _TRAMPOLINE, *args], capture_output=True, text=True
    )
    if proc.returncode:
        raise SystemExit(f"{' '.join(args)}: {proc.stderr}")
    wall, cpu, peak_mb, code = json.loads(proc.stdout.strip().splitlines()[-1])
    if code:
        raise SystemExit(f"{' '.join(args)} failed (exit {code}): {proc.stderr}")
    return wall, cpu, peak_mb


def recordings(repeats: int = 5) -> None:
    """`fruit locate` end to end on 20,000, 200,000 and 1,000,000 frames:
    frames/s = 180,000 / (time on 200,000 - time on 20,000), from the best and the median
    of `repeats` runs each (a shared machine's load only adds time), and peak memory on
    1,000,000 frames (one run; frames/s against the best 20,000-frame run)."""
    fruit = str(Path(sys.executable).with_name("fruit"))
    with tempfile.TemporaryDirectory(prefix="bench-locate-") as tmp_name:
        tmp = Path(tmp_name)
        taxels = full_board_taxels(tmp / "taxels.csv")
        sizes = (20_000, 200_000, 1_000_000)
        for n in sizes:
            write_touch_recording(tmp / f"r{n}.npz", n, seed=n)
        cmd = {
            n: [
                fruit,
                "-q",
                "locate",
                str(tmp / f"r{n}.npz"),
                "--taxels",
                str(taxels),
                "--out",
                str(tmp / f"o{n}"),
            ]
            for n in sizes
        }
        print(
            "load average before:",
            ", ".join(f"{x:.1f}" for x in os.getloadavg()),
            f"({os.cpu_count()} CPUs)",
        )
        runs = {
            n: [run_command(cmd[n]) for _ in range(repeats if n < sizes[-1] else 1)] for n in sizes
        }
        for n in sizes:
            walls = ", ".join(f"{w:.2f}" for w, _, _ in runs[n])
            print(
                f"  {' '.join(cmd[n][1:4])} ...: wall {walls} s, CPU "
                f"{np.median([c for _, c, _ in runs[n]]):.2f} s, peak "
                f"{max(m for _, _, m in runs[n]):.0f} MB"
            )
        small, big = sizes[0], sizes[1]
        spread_wall = max(np.ptp([w for w, _, _ in runs[n]]) for n in (small, big))
        spread_cpu = max(np.ptp([c for _, c, _ in runs[n]]) for n in (small, big))
        for name, pick in (("best", np.min), ("median", np.median)):
            wall = pick([w for w, _, _ in runs[big]]) - pick([w for w, _, _ in runs[small]])
            cpu = pick([c for _, c, _ in runs[big]]) - pick([c for _, c, _ in runs[small]])
            print(
                f"fruit locate end to end, {name} of {repeats}: ({big:,} - {small:,} frames)"
                f" / (wall difference {wall:.2f} s) -> "
                + rate(big - small, wall, spread_wall)
                + " (target >= 200,000); by CPU "
                "time " + rate(big - small, cpu, spread_cpu)
            )
        huge = sizes[-1]
        wall = runs[huge][0][0] - np.min([w for w, _, _ in runs[small]])
        print(
            f"fruit locate on {huge:,} frames: peak memory {runs[huge][0][2]:.0f} MB "
            f"(target < 2,048 MB), wall {runs[huge][0][0]:.1f} s; ({huge:,} - {small:,} "
            f"frames) / (wall difference {wall:.2f} s) -> {(huge - small) / wall:,.0f} "
            "frames/s"
        )
        one_thread_cpu(tmp / f"r{small}.npz", tmp / f"r{big}.npz", taxels, tmp / "inproc")
        print("load average after:", ", ".join(f"{x:.1f}" for x in os.getloadavg()))
        same = check_against_reference(tmp / f"r{small}.npz", taxels, tmp / f"o{small}")
        print(
            f"touches.csv of {small:,} frames, the paper's columns, equal the first batch "
            f"path's (tests/helpers/locate_reference.py) to the byte: {same}"
        )


def one_thread_cpu(small: Path, big: Path, taxels: Path, out: Path, repeats: int = 3) -> None:
    """`run_locate` in this process on one thread: frames/s by the CPU time of the big
    recording less the small one's (best of `repeats`), steadier than wall time on a
    loaded machine."""
    from tests.helpers.locate import locate_scene

    cpu = {}
    for path in (small, big):
        n = int(path.stem[1:])
        locate_scene(None, path, taxels, None, out, workers=1)  # loaded and compiled
        times = []
        for _ in range(repeats):
            t0 = time.process_time()
            locate_scene(None, path, taxels, None, out, workers=1)
            times.append(time.process_time() - t0)
        cpu[n] = min(times)
    (n0, c0), (n1, c1) = sorted(cpu.items())
    print(
        f"run_locate in process, one thread, best of {repeats}: CPU {c0:.3f} s on {n0:,} "
        f"frames, {c1:.3f} s on {n1:,} -> {(n1 - n0) / (c1 - c0):,.0f} frames/s per CPU"
    )


def rate(frames: int, seconds: float, spread: float) -> str:
    """frames / seconds as frames/s, flagged when the time is within the runs' spread (the
    command's start-up jitter dominates it), or 'not measurable' when it is not positive
    (a negative rate once came out of a median here)."""
    if seconds <= 0:
        return f"not measurable (difference {seconds:.2f} s, runs' spread {spread:.2f} s)"
    text = f"{frames / seconds:,.0f} frames/s"
    if seconds <= spread:
        text += (
            f" (within the runs' spread of {spread:.2f} s, so mostly start-up jitter; "
            "the 1,000,000-frame line is steadier)"
        )
    return text


def check_against_reference(frames_npz: Path, taxels_csv: Path, out_dir: Path) -> bool:
    from fruitcli.sensing.frames.board import taxel_cells
    from fruitcli.sensing.frames.recording import read_npz
    from tests.helpers.locate_reference import locate, touches_csv_text

    rec = read_npz(frames_npz)
    tx = read_taxels(taxels_csv)
    rows, cols = taxel_cells(tx, default_board())
    text = touches_csv_text(
        locate(rec.frames, rec.t_s, tx.i, tx.j, rows, cols, tx.xyz_mm),
        rec.t_s,
        f"touches of {frames_npz.name}: frame index from 0 "
        "(baseline frames included), t_s in s, i, j fractional grid "
        "coordinates, x_mm, y_mm, z_mm in mm, peak in counts",
    )
    got = (out_dir / "touches.csv").read_text()
    return _paper_columns(text) == _paper_columns(got)


def _paper_columns(text: str) -> list[str]:
    """The data rows' first nine fields (frame .. peak); later columns (height, strength,
    size, kind) came after the reference and are left out."""
    rows = [line for line in text.splitlines() if line and not line.startswith("#")]
    return [",".join(line.split(",")[:9]) for line in rows]


def bench_osc_latency(n_frames: int = 3000, live_defaults: bool = False, hovers: bool = False):
    """Board line arriving -> last TUIO/OSC bundle of the frame leaving, with 10
    simultaneous touches (target p99 <= 1 ms). Each frame's line is written to a pty; the
    clock starts when the pty has it for the reader (select), then the live loop's own
    objects read, parse, locate, give session ids and send 4 bundles to 127.0.0.1, in
    one thread. `live_defaults`: with `fruit live`'s drift tracker and taxel flags;
    `hovers`: with [detection].hovers (every touch's height, strength and size are
    computed and sent in any case)."""
    import os
    import select
    import socket
    import tty

    from fruitcli.sensing.live.idle_gc import FrameGC
    from fruitcli.sensing.live.loop import LiveLocator
    from fruitcli.sensing.live.serial_ports import FrameReader, open_port
    from fruitcli.sensing.outputs.tuio import Normalizer, TuioSender

    i, j = np.divmod(np.arange(21 * 12), 12)
    taxels = Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0 * i], axis=1))
    loc = Locator(
        taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=10, hovers=hovers)
    )
    from fruitcli.sensing.detection.drift import DriftTracker

    live = (
        LiveLocator(loc, drift=DriftTracker(60.0, 20.0), health=True)
        if live_defaults
        else LiveLocator(loc)
    )
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    sink.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    tuio = TuioSender(sink.getsockname(), Normalizer.from_taxels(i, j, taxels.xyz_mm))
    master, slave = os.openpty()
    tty.setraw(slave)
    port = open_port(os.ttyname(slave))
    reader = FrameReader(port, 21, 12, "pty")
    rng = np.random.default_rng(7)
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    centres = [(a, b) for a in (2, 7, 12, 17) for b in (2, 6, 10)][:10]
    lat, cpu, counts = [], [], []
    lines = []  # made beforehand: the loop's thread does only what `fruit live` does
    for k in range(n_frames + 10):
        f = 500 + rng.normal(0, 1.0, (21, 12))
        if k >= 10:
            for a, b in centres:
                d = 0.3 * np.sin(k / 20)  # the fingers move a little
                f += 60 * np.exp(-((r - a - d) ** 2 + (c - b + d) ** 2) / (2 * 0.6**2))
        lines.append((format_line(np.round(f).astype(np.int64)) + "\r\n").encode())
    load = os.getloadavg()
    frame_gc = FrameGC().__enter__()  # as `fruit live` does
    try:
        for line in lines:
            while os.read(sink.fileno(), 65536) if _readable(sink) else False:
                pass  # drain what the previous frames sent
            os.write(master, line)
            select.select([port.fileno()], [], [])
            t0, c0 = time.perf_counter(), time.thread_time()
            got: list = []
            while not got:
                got = reader.poll()
            lf = live.step(got[0][0], got[0][1])
            if lf is not None:
                tuio.send(
                    lf.t_s,
                    lf.sessions.ids,
                    lf.sessions.new,
                    lf.sessions.ended,
                    lf.ij,
                    lf.touches.xyz_mm,
                    lf.touches.peak,
                    lf.shape,
                    lf.touches.kind,
                )
                lat.append(time.perf_counter() - t0)
                cpu.append(time.thread_time() - c0)
                counts.append(len(lf.touches))
            frame_gc.after_frame()
    finally:
        frame_gc.__exit__()
        port.close()
        os.close(master)
        os.close(slave)
        sink.close()
        tuio.close()
    ms = np.array(lat) * 1e3
    what = (
        "with fruit live's drift tracker and taxel flags"
        if live_defaults
        else "detection, sessions and TUIO only"
    )
    what += ", hovers on" if hovers else ""
    print(
        f"OSC latency ({what}), board line -> TUIO bundles sent, "
        f"{int(np.median(counts))} touches "
        f"({min(counts)}-{max(counts)}), {len(ms)} frames: median {np.median(ms):.3f} ms, "
        f"p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms (target p99 <= 1 ms); "
        f"CPU time of the loop's thread: median {np.median(cpu) * 1e3:.3f} ms, p99 "
        f"{np.percentile(cpu, 99) * 1e3:.3f} ms (wall minus CPU: waiting for a core); "
        f"load average {load[0]:.1f} before, {os.getloadavg()[0]:.1f} after "
        f"({os.cpu_count()} CPUs); garbage collections between frames (generation 0, 1, "
        f"2): {', '.join(map(str, frame_gc.collections))}"
    )


def _readable(sock) -> bool:
    """Data waiting on `sock`."""
    import select

    return bool(select.select([sock], [], [], 0)[0])


if __name__ == "__main__":
    if sys.argv[1:] == ["recordings"]:
        recordings()
    elif sys.argv[1:] == ["model"]:
        model_method()
    elif sys.argv[1:] == ["latency"]:
        bench_osc_latency()
        bench_osc_latency(live_defaults=True)
        bench_osc_latency(live_defaults=True, hovers=True)
    else:
        main()
        model_method()
        bench_osc_latency()
        bench_osc_latency(live_defaults=True)
        bench_osc_latency(live_defaults=True, hovers=True)
