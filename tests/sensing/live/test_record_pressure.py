"""`fruit record --pressure-port`: frames with the latest chamber pressures over real
pseudo-terminals, and `fruit locate` reporting frames off the simulated states' path."""

import os
import termios
import threading
import time
import tty

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.sensing.detection.pressure_path import path_distance_kpa
from fruitcli.sensing.frames.recording import Recording, read_npz, read_recording, write_npz
from fruitcli.sensing.live.board_emulator import BoardEmulator, synthetic_frames
from fruitcli.tables import read_table
from tests.sensing.skin.test_virtual_bench import pad_states, pad_taxel_csv


def invoke(args):
    return CliRunner().invoke(cli, args)


class PressureSource:
    """A pump controller on a pty: after a reader opens it, line j is ``P bend=<0.1 j>``
    every `period_s`, with a junk line and an unknown chamber mixed in."""

    def __init__(self, lines=60, period_s=0.03):
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.slave = slave
        self.attrs = termios.tcgetattr(slave)  # before any reader can configure it
        self.path = os.ttyname(slave)
        self.lines, self.period_s = lines, period_s
        self.stop = threading.Event()

    def run(self):
        try:
            end = time.monotonic() + 10
            while termios.tcgetattr(self.slave) == self.attrs and time.monotonic() < end:
                time.sleep(0.01)
            time.sleep(0.1)  # pyserial flushes the input right after configuring
            os.write(self.master, b"pump ready\r\nP other=1.0\r\n")
            for j in range(self.lines):
                if self.stop.is_set():
                    break
                os.write(self.master, f"P bend={0.1 * j:.1f}\r\n".encode())
                time.sleep(self.period_s)
        except (OSError, termios.error):
            pass  # closed by the test

    def close(self):
        self.stop.set()
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


def test_record_with_pressures_each_frame_carries_the_latest_reading(tmp_path):
    frames = synthetic_frames(40, seed=11)
    em = BoardEmulator(frames, fps=20, wait_for_reader=True)
    src = PressureSource()
    threads = [em.start(), threading.Thread(target=src.run, daemon=True)]
    threads[1].start()
    out = tmp_path / "rec.npz"
    try:
        res = invoke(
            [
                "record",
                "--port",
                em.path,
                "--out",
                str(out),
                "--frames",
                "40",
                "--pressure-port",
                src.path,
                "--chambers",
                "bend",
            ]
        )
    finally:
        em.stop.set()
        src.close()
        for th in threads:
            th.join(5)
    assert res.exit_code == 0, res.output
    assert "pressure lines: " in res.output and "2 skipped" in res.output
    rec = read_npz(out)
    assert np.array_equal(rec.frames, frames)
    assert rec.chamber_names == ("bend",) and rec.pressure_kpa.shape == (40, 1)
    t, p = rec.pressure_t_s, rec.pressure_kpa[:, 0]
    have = np.isfinite(t)
    assert have.sum() >= 30  # the pressure lines start at once, frames take 2 s
    assert np.all(p[~have] == 0.0)  # before the first reading: 0 kPa, time NaN
    assert np.all(t[have] <= rec.t_s[have])  # the reading came before the frame
    assert np.all(np.diff(t[have]) >= 0) and np.all(np.diff(p) >= -1e-12)
    j = np.round(p[have] / 0.1)
    assert np.allclose(p[have], 0.1 * j) and j[-1] >= 30  # values are lines sent, in order
    assert not list(tmp_path.glob("*.partial*"))


@pytest.mark.parametrize(
    "args, msg",
    [
        (["--pressure-port", "loop://"], "--pressure-port loop://: give --chambers"),
        (["--chambers", "c1"], "--chambers: needs --pressure-port"),
        (
            ["--pressure-port", "loop://", "--chambers", "c1,c1"],
            "--chambers c1,c1: expected distinct non-empty names",
        ),
    ],
)
def test_record_pressure_options_are_checked(tmp_path, args, msg):
    res = invoke(
        ["record", "--port", "loop://", "--out", str(tmp_path / "r.npz"), "--seconds", "0.2", *args]
    )
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert msg in res.output and list(tmp_path.iterdir()) == []
    res = invoke(
        [
            "record",
            "--port",
            "loop://",
            "--out",
            str(tmp_path / "r.log"),
            "--seconds",
            "0.2",
            "--pressure-port",
            "loop://",
            "--chambers",
            "c1",
        ]
    )
    assert res.exit_code == 1 and "chamber pressures are recorded in an .npz only" in res.output
    res = invoke(
        [
            "record",
            "--port",
            "loop://",
            "--out",
            str(tmp_path / "r.npz"),
            "--seconds",
            "0.2",
            "--pressure-port",
            str(tmp_path / "nope"),
            "--chambers",
            "c1",
        ]
    )
    assert res.exit_code == 1 and "serial port does not exist" in res.output
    assert list(tmp_path.iterdir()) == []


def test_path_distance_closed_form():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    p = np.array([[1.0, 1.0], [3.0, 3.0], [1.0, -0.5], [2.0, 1.0], [-1.0, 0.0]])
    assert path_distance_kpa(p, path) == pytest.approx([1.0, np.sqrt(2), 0.5, 0.0, 1.0])


def test_locate_counts_frames_off_the_states_path(tmp_path):
    """The pad's states lie at 0, 1, 2 kPa of one chamber: frames recorded at up to 3 kPa
    lie up to 1 kPa off the path; those more than 0.5 kPa off are counted and listed."""
    states = pad_states(tmp_path / "s.npz")
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    n = 61
    kpa = np.linspace(0.0, 3.0, n)[:, None]
    t_reading = np.r_[np.nan, np.arange(1, n) * 0.05 - 0.01]
    rec = Recording(
        synthetic_frames(n, seed=12), np.arange(n) * 0.05, kpa, ("bend",), pressure_t_s=t_reading
    )
    write_npz(tmp_path / "r.npz", rec)
    back = read_npz(tmp_path / "r.npz")
    assert np.array_equal(back.pressure_t_s, t_reading, equal_nan=True)  # round trip
    res = invoke(
        [
            "locate",
            str(tmp_path / "r.npz"),
            "--taxels",
            str(taxels),
            "--states",
            str(states),
            "--out",
            str(tmp_path / "loc"),
        ]
    )
    assert res.exit_code == 0, res.output
    off = np.flatnonzero(kpa[:, 0] - 2.0 > 0.5)  # 2.55 ... 3.0 kPa
    assert (
        f"{off.size} of {n} frames have pressures more than 0.5 kPa off the states' "
        f"path (up to 1.00 kPa, frame {n - 1})" in res.output
    )
    assert "1 frames before the first pressure reading taken at 0 kPa" in res.output
    got = read_table(tmp_path / "loc" / "off_path.csv", ["frame", "t_s", "distance_kpa"])
    assert got["frame"].astype(int).tolist() == off.tolist()
    assert got["distance_kpa"] == pytest.approx(kpa[off, 0] - 2.0, abs=1e-6)


def test_record_with_pressures_then_locate(tmp_path):
    """The whole loop on ptys: a recording with pressures located on the pad's states."""
    frames = synthetic_frames(30, seed=13, rows=21, cols=12)
    em = BoardEmulator(frames, fps=30, wait_for_reader=True)
    src = PressureSource(lines=40, period_s=0.02)
    threads = [em.start(), threading.Thread(target=src.run, daemon=True)]
    threads[1].start()
    try:
        res = invoke(
            [
                "record",
                "--port",
                em.path,
                "--out",
                str(tmp_path / "r.npz"),
                "--frames",
                "30",
                "--pressure-port",
                src.path,
                "--chambers",
                "bend",
            ]
        )
    finally:
        em.stop.set()
        src.close()
        for th in threads:
            th.join(5)
    assert res.exit_code == 0, res.output
    rec = read_recording(tmp_path / "r.npz")
    assert np.isfinite(rec.pressure_t_s).sum() >= 20
    states = pad_states(tmp_path / "s.npz")
    res = invoke(
        [
            "locate",
            str(tmp_path / "r.npz"),
            "--taxels",
            str(pad_taxel_csv(tmp_path / "t.csv")),
            "--states",
            str(states),
            "--out",
            str(tmp_path / "loc"),
        ]
    )
    assert res.exit_code == 0, res.output
    expected = int((rec.pressure_kpa[:, 0] > 2.5).sum())
    if expected:
        assert f"{expected} of 30 frames have pressures more than 0.5 kPa" in res.output
    else:
        assert "pressures within 0.5 kPa of the states' path" in res.output
