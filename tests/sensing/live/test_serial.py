"""`fruit record` and `fruit live` end to end through the emulated board on a real pty."""

import json
import os
import termios
import threading
import time

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.sensing.frames.recording import Recording, read_recording, write_npz
from fruitcli.sensing.live.board_emulator import BoardEmulator, synthetic_frames
from fruitcli.sensing.live.serial_ports import PressureState, parse_pressure_line
from fruitcli.tables import read_table
from tests.helpers.locate import locate_scene
from tests.sensing.skin.test_virtual_bench import pad_states, pad_taxel_csv


def invoke(args):
    return CliRunner().invoke(cli, args)


def test_record_npz_with_log_lines_and_a_cut_line(tmp_path):
    frames = synthetic_frames(40, seed=1)
    em = BoardEmulator(frames, fps=0, log_every=5, cut_at=[7], wait_for_reader=True)
    th = em.start()
    out = tmp_path / "rec.npz"
    res = invoke(["record", "--port", em.path, "--out", str(out), "--frames", "30"])
    em.stop.set()
    th.join(5)
    assert res.exit_code == 0, res.output
    rec = read_recording(out)
    expected = np.delete(frames, 7, axis=0)[:30]
    assert np.array_equal(rec.frames, expected)
    assert np.all(np.diff(rec.t_s) >= 0) and rec.meta["port"] == em.path
    assert "30 ascii frames" in res.output and not (tmp_path / "rec.npz.partial.log").exists()


def test_record_port_vanishing_keeps_every_whole_frame(tmp_path):
    frames = synthetic_frames(60, seed=2)
    em = BoardEmulator(frames, fps=200, log_every=9, vanish_after=25, wait_for_reader=True)
    th = em.start()
    out = tmp_path / "rec.log"
    res = invoke(["record", "--port", em.path, "--out", str(out), "--seconds", "20"])
    th.join(5)
    assert res.exit_code == 1
    assert f"{em.path}: port closed after 25 frames; {out} holds them" in res.output
    rec = read_recording(out)
    assert np.array_equal(rec.frames, frames[:25])


def test_record_npz_port_vanishing_converts(tmp_path):
    frames = synthetic_frames(30, seed=3)
    em = BoardEmulator(frames, fps=0, vanish_after=12, wait_for_reader=True)
    th = em.start()
    res = invoke(["record", "--port", em.path, "--out", str(tmp_path / "r.npz")])
    th.join(5)
    assert res.exit_code == 1
    assert np.array_equal(read_recording(tmp_path / "r.npz").frames, frames[:12])


def test_record_bad_ports(tmp_path):
    res = invoke(
        [
            "record",
            "--port",
            str(tmp_path / "ttyNOPE"),
            "--out",
            str(tmp_path / "r.npz"),
            "--frames",
            "3",
        ]
    )
    assert res.exit_code == 1 and "serial port does not exist" in res.output
    em = BoardEmulator(synthetic_frames(5), fps=0)
    import serial

    hold = serial.Serial(em.path, exclusive=True)
    try:
        res = invoke(
            ["record", "--port", em.path, "--out", str(tmp_path / "r.npz"), "--frames", "3"]
        )
        assert res.exit_code == 1 and "serial port is busy" in res.output
    finally:
        hold.close()
        em.close()
    res = invoke(["record", "--port", "x", "--out", "r.npz", "--frames", "3", "--seconds", "1"])
    assert res.exit_code == 1 and "give --frames or --seconds, not both" in res.output
    res = invoke(["record", "--port", "x", "--out", "r.npz", "--frames", "0"])
    assert res.exit_code == 2


SCENE = """
[grid]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[detection]
baseline_frames = 5
"""


def touch_frames(n=30, seed=0, noise=True):
    """Idle 4 x 4 pad frames with touches at known places in frames 10..19."""
    rng = np.random.default_rng(seed)
    f = 500 + rng.integers(-1, 2, (n, 21, 12)) * int(noise)
    for k in range(10, 20):
        f[k, 1, 1] += 40 + k
        f[k, 1, 2] += 15
        f[k, 2, 1] += 10
    return f.astype(np.int64)


def live_lines(output):
    return [json.loads(ln) for ln in output.splitlines() if ln.startswith("{")]


def test_live_matches_batch_locate(tmp_path):
    frames = touch_frames()
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    em = BoardEmulator(frames, fps=0, log_every=4, cut_at=[], wait_for_reader=True)
    th = em.start()
    res = invoke(
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            em.path,
            "--taxels",
            str(taxels),
            "--frames",
            "30",
            "--no-drift",
        ]
    )  # the batch has no drift
    th.join(5)
    assert res.exit_code == 0, res.output
    lines = live_lines(res.output)
    assert [d["frame"] for d in lines] == list(range(10, 21))
    assert lines[-1]["touches"] == []
    write_npz(tmp_path / "f.npz", Recording(frames, np.arange(30.0)))
    from fruitcli.scene import load_scene

    locate_scene(load_scene(tmp_path / "s.toml"), tmp_path / "f.npz", taxels, None, tmp_path / "o")
    t = read_table(tmp_path / "o" / "touches.csv", ["frame", "i", "j", "x_mm", "peak"])
    assert t["frame"].tolist() == [d["frame"] for d in lines[:-1]]
    assert np.allclose(t["x_mm"], [d["touches"][0]["x_mm"] for d in lines[:-1]], atol=1e-3)
    assert t["peak"] == pytest.approx([d["touches"][0]["peak"] for d in lines[:-1]])


def test_live_port_vanishing_is_one_error_line(tmp_path):
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    em = BoardEmulator(touch_frames(), fps=0, vanish_after=15, wait_for_reader=True)
    th = em.start()
    res = invoke(["live", str(tmp_path / "s.toml"), "--port", em.path, "--taxels", str(taxels)])
    th.join(5)
    assert res.exit_code == 1
    assert f"Error: {em.path}: port closed after 15 frames" in res.output
    assert [d["frame"] for d in live_lines(res.output)] == list(range(10, 15))


class PressureSource:
    """A pty that sends 'P bend=<kPa>' lines every 10 ms once a reader opened it."""

    def __init__(self, kpa):
        self.master, self.slave = os.openpty()
        import tty

        tty.setraw(self.slave)
        self.attrs = termios.tcgetattr(self.slave)
        self.path = os.ttyname(self.slave)
        self.kpa = kpa
        self.stop = threading.Event()
        self.th = threading.Thread(target=self.run, daemon=True)
        self.th.start()

    def run(self):
        while termios.tcgetattr(self.slave) == self.attrs and not self.stop.is_set():
            time.sleep(0.01)
        time.sleep(0.1)
        while not self.stop.is_set():
            try:
                os.write(self.master, f"noise\r\nP bend={self.kpa}\r\n".encode())
            except OSError:
                return
            time.sleep(0.01)

    def close(self):
        self.stop.set()
        self.th.join(2)
        os.close(self.master)
        os.close(self.slave)


def test_live_with_pressure_moves_taxels_through_states(tmp_path):
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    states = pad_states(tmp_path / "st.npz")
    src = PressureSource(2.0)  # bend = angle / 90 deg: state 2, bent 180 deg
    em = BoardEmulator(touch_frames(noise=False), fps=50, wait_for_reader=True)
    th = em.start()
    try:
        res = invoke(
            [
                "live",
                str(tmp_path / "s.toml"),
                "--port",
                em.path,
                "--taxels",
                str(taxels),
                "--states",
                str(states),
                "--pressure-port",
                src.path,
                "--frames",
                "20",
            ]
        )
    finally:
        th.join(5)
        src.close()
    assert res.exit_code == 0, res.output
    d = live_lines(res.output)[0]["touches"][0]
    with np.load(states) as z:
        bent = z["taxels_mm"][2]
    # the touch's neighbourhood on the bent pad: taxels (1, 1), (1, 2), (2, 1)
    w = np.array([50, 15, 10.0]) / 75  # frame 10: peak 40 + 10
    expect = w @ bent[[5, 6, 9]]
    assert [d["x_mm"], d["y_mm"], d["z_mm"]] == pytest.approx(expect, abs=1e-3)


def test_pressure_line_protocol():
    assert parse_pressure_line("P c1=2.5 c2=0.0") == {"c1": 2.5, "c2": 0.0}
    assert parse_pressure_line("P c1=abc") is None
    assert parse_pressure_line("[Muca] hi") is None
    st = PressureState(("c1", "c2"))
    st.update("P c2=3")
    st.update("P c3=1")
    assert st.kpa.tolist() == [0.0, 3.0] and st.skipped == 1


def test_emulate_board_command_in_a_subprocess_feeds_record(tmp_path):
    import subprocess
    import sys

    rec = Recording(synthetic_frames(50, seed=4), np.arange(50.0))
    write_npz(tmp_path / "src.npz", rec)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from fruitcli.cli.main import main; main()",
            "emulate-board",
            "--from",
            str(tmp_path / "src.npz"),
            "--fps",
            "0",
            "--log-every",
            "3",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/")
        res = invoke(["record", "--port", path, "--out", str(tmp_path / "r.log"), "--frames", "40"])
        assert res.exit_code == 0, res.output
        assert np.array_equal(read_recording(tmp_path / "r.log").frames, rec.frames[:40])
    finally:
        proc.wait(10)
    res = invoke(["emulate-board", "--bench", str(tmp_path / "nothing")])
    assert res.exit_code == 1 and "no <indenter>/frames.npz" in res.output


def test_emulator_stops_when_its_reader_has_gone(monkeypatch):
    """A reader takes a few lines and closes the port: the emulator, finding the port
    full for NO_READER_S, stops instead of blocking forever, and says why."""
    import serial

    from fruitcli.sensing.live import board_emulator as emulator

    monkeypatch.setattr(emulator, "NO_READER_S", 0.5)
    em = BoardEmulator(synthetic_frames(5000), fps=0, wait_for_reader=True)
    th = em.start()
    port = serial.Serial(em.path, 115200, timeout=2)
    for _ in range(5):
        port.readline()
    port.close()
    th.join(20)
    assert not th.is_alive() and em.reader_gone and 0 < em.sent < 5000


def test_record_wrong_frame_size_says_why_and_writes_nothing(tmp_path):
    em = BoardEmulator(synthetic_frames(8), fps=0, vanish_after=8, wait_for_reader=True)
    th = em.start()
    out = tmp_path / "r.npz"
    res = invoke(["record", "--port", em.path, "--out", str(out), "--rows", "20"])
    th.join(5)
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "8 lines of 252 counts, expected 240 = 20 x 12" in res.output
    assert "nothing written" in res.output and "holds them" not in res.output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("out", ["r.npz", "r.log"])
def test_record_no_frame_is_an_error_and_writes_nothing(tmp_path, out):
    res = invoke(["record", "--port", "loop://", "--seconds", "0.2", "--out", str(tmp_path / out)])
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "loop://: no frame received" in res.output and "nothing written" in res.output
    assert list(tmp_path.iterdir()) == []


def test_record_refuses_an_unknown_out_suffix(tmp_path):
    res = invoke(
        ["record", "--port", "loop://", "--seconds", "0.2", "--out", str(tmp_path / "r.xyz")]
    )
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "r.xyz: expected a .npz or a MuCa log" in res.output
    assert list(tmp_path.iterdir()) == []


def test_live_wrong_frame_size_says_why(tmp_path):
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    em = BoardEmulator(synthetic_frames(12, rows=20), fps=0, vanish_after=12, wait_for_reader=True)
    th = em.start()
    res = invoke(["live", str(tmp_path / "s.toml"), "--port", em.path, "--taxels", str(taxels)])
    th.join(5)
    assert res.exit_code == 1
    assert f"Error: {em.path}: port closed after 0 frames" in res.output
    assert "12 lines of 240 counts, expected 252 = 21 x 12" in res.output


@pytest.mark.parametrize(
    "args, msg",
    [
        (
            ["--pressure-port", "/dev/nonexistent"],
            "--pressure-port /dev/nonexistent: nothing uses the pressures; it needs --states or "
            "--online",
        ),
        (
            ["--frames", "5", "--baseline-frames", "50"],
            "--frames 5: expected more than the 50 baseline frames",
        ),
        (["--frames", "5"], "--frames 5: expected more than the 5 baseline frames"),
    ],
)
def test_live_refuses_options_that_cannot_work(tmp_path, args, msg):
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    res = invoke(
        ["live", str(tmp_path / "s.toml"), "--port", "loop://", "--taxels", str(taxels), *args]
    )
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert f"Error: {msg}" in res.output


@pytest.mark.parametrize("out", ["old.npz", "old.log"])
def test_record_refuses_an_existing_out_and_overwrite_keeps_it_until_frames_arrive(tmp_path, out):
    path = tmp_path / out
    path.write_bytes(b"an earlier recording")
    res = invoke(
        ["record", "--port", str(tmp_path / "ttyNOPE"), "--out", str(path), "--frames", "3"]
    )  # refused before the port is opened
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert f"--out {path}: exists; give --overwrite to replace it" in res.output
    res = invoke(
        ["record", "--port", "loop://", "--seconds", "0.2", "--out", str(path), "--overwrite"]
    )  # no frame: the earlier recording stays
    assert res.exit_code == 1 and f"{path} left as it was" in res.output, res.output
    assert path.read_bytes() == b"an earlier recording"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out]
    frames = synthetic_frames(20, seed=5)
    em = BoardEmulator(frames, fps=0, vanish_after=8, wait_for_reader=True)
    th = em.start()
    res = invoke(["record", "--port", em.path, "--out", str(path), "--overwrite"])
    th.join(5)
    assert res.exit_code == 1 and "port closed after 8 frames" in res.output, res.output
    assert np.array_equal(read_recording(path).frames, frames[:8])
    assert sorted(p.name for p in tmp_path.iterdir()) == [out]


def test_record_refuses_to_start_over_an_unfinished_recording(tmp_path):
    partial = tmp_path / "r.npz.partial.log"
    partial.write_text("1.5," + ",".join(["500"] * 252) + "\n")
    res = invoke(
        ["record", "--port", "loop://", "--seconds", "0.2", "--out", str(tmp_path / "r.npz")]
    )
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert f"{partial}: left by a recording that did not finish" in res.output
    assert len(read_recording(partial)) == 1
