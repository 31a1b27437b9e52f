"""The real bench: `fruit bench --printer --board` end to end through `fruit emulate-printer`
(two real pseudo-terminals), with a Resend, a missing ok, a printer Error:, a bed limit,
no touch, a vanishing board and Ctrl-C; the Marlin host protocol; bad [printer] tables."""

import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.bench import printer_bench_inputs
from fruitcli.cli.main import cli
from fruitcli.errors import SceneError
from fruitcli.printer.emulator import PrinterEmulator
from fruitcli.printer.indentation import BenchInterrupted, BenchStopped, run_printer_bench
from fruitcli.printer.marlin import checksum, numbered
from fruitcli.printer.placement import Placement
from fruitcli.printer.skin_board import SkinBoard
from fruitcli.scene import load_scene
from fruitcli.sensing.frames.recording import read_npz
from fruitcli.sensing.live.board_emulator import BoardEmulator
from fruitcli.sensing.skin import forward
from fruitcli.tables import read_table, read_taxels
from tests.sensing.skin.test_virtual_bench import pad_taxel_csv

SAMPLES = [(-20.0, -20.0), (0.0, 4.0), (12.0, -6.0)]
PRINTER = """
[printer]
model_origin_mm = [100.0, 100.0, 0.0]
rotate_z_deg = 30.0
safe_height_mm = 10.0
step_mm = 0.1
feed_mm_min = 3000
timeout_s = 3
"""


def make_scene(tmp_path, printer=PRINTER, extra=""):
    pad_taxel_csv(tmp_path / "t.csv")
    (tmp_path / "samples.csv").write_text(
        "sample,x_mm,y_mm\n" + "".join(f"{k},{x},{y}\n" for k, (x, y) in enumerate(SAMPLES))
    )
    (tmp_path / "s.toml").write_text(f"""
[grid]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
taxels = "t.csv"
[bench]
indenters = ["small"]
samples = "samples.csv"
baseline_frames = 5
[board]
format = "binary"
{extra}
{printer}
""")
    return tmp_path / "s.toml"


def expected_touch_gap_mm(xy):
    """Gap (mm) at which the nearest taxel's mean activation reaches the threshold: the
    forward model in closed form, 60 exp(-d^2 / 2 sigma^2) exp(-gap / 2) = 20."""
    t = forward.pad_taxels_mm(z_mm=3.0)
    d = np.min(np.hypot(t[:, 0] - xy[0], t[:, 1] - xy[1]))
    sigma = forward.footprint_sigma_mm("small")
    return forward.GAP_DECAY_MM * np.log(
        forward.CONTACT_COUNTS / forward.THRESHOLD_COUNTS * np.exp(-0.5 * (d / sigma) ** 2)
    )


def test_marlin_line_checksum():
    assert checksum("N1 G21") == (ord("N") ^ ord("1") ^ ord(" ") ^ ord("G") ^ ord("2") ^ ord("1"))
    assert numbered(7, "M400") == f"N7 M400*{checksum('N7 M400')}"


def test_bench_end_to_end_through_emulate_printer_with_a_resend(tmp_path):
    # a skin without noise: each touch is then at one gap, the closed form's to within a
    # step (with noise the first frame over the threshold came up to 0.5 mm early, about
    # once in a hundred runs, as which frames took which draws depends on timing)
    scene = make_scene(tmp_path, extra="[skin]\nnoise_std_counts = 0.0")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from fruitcli.cli.main import main; main()",
            "emulate-printer",
            "--board-from",
            str(scene),
            "--baud",
            "2000000",
            "--time-scale",
            "0.1",
            "--fault",
            "resend:6",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        printer = proc.stdout.readline().split()[1]
        board = proc.stdout.readline().split()[1]
        res = CliRunner().invoke(
            cli,
            [
                "bench",
                str(scene),
                "--printer",
                printer,
                "--board",
                board,
                "--out",
                str(tmp_path / "out"),
            ],
        )
    finally:
        proc.terminate()
        proc.wait(10)
    assert res.exit_code == 0, res.output
    assert "small: 3 samples" in res.output and "(1 lines resent)" in res.output
    rec = read_npz(tmp_path / "out" / "small" / "frames.npz")
    assert rec.printer_mm.shape == (len(rec), 3) and rec.meta["source"] == "printer bench"
    touch = np.flatnonzero(rec.sample >= 0)
    assert rec.sample[touch].tolist() == [0, 1, 2]
    place = Placement([100.0, 100.0, 0.0], 30.0)
    for k, f in zip(rec.sample[touch], touch, strict=True):
        p = place.to_printer([*SAMPLES[k], 3.0])
        assert rec.printer_mm[f, :2] == pytest.approx(p[:2], abs=1e-3)  # above the sample
        gap = rec.printer_mm[f, 2] - p[2]
        # counts are whole numbers and a touch needs v > 20: the activation must reach
        # 20.5, 2 ln(20.5 / 20) = 0.049 mm below the closed form's gap, then the
        # descent's next step (0.1 mm) at most
        below = expected_touch_gap_mm(SAMPLES[k]) - gap
        assert 0.049 < below < 0.15, (k, gap)
    truth = read_table(tmp_path / "out" / "small" / "truth.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    assert truth["x_mm"].tolist() == [s[0] for s in SAMPLES] and np.all(truth["z_mm"] == 3.0)
    res = CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "out" / "small" / "frames.npz"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--scene",
            str(scene),
            "--out",
            str(tmp_path / "loc"),
        ],
    )
    assert res.exit_code == 0, res.output
    measured = read_table(tmp_path / "loc" / "measured.csv", ["sample", "x_mm", "y_mm"])
    assert measured["sample"].astype(int).tolist() == [0, 1, 2]
    err = np.hypot(measured["x_mm"] - truth["x_mm"], measured["y_mm"] - truth["y_mm"])
    assert np.all(err < 6.0)  # the N9 centroid on a 16 mm pitch


class Rig:
    """The printer and the board emulators in this process (their state can be read)."""

    def __init__(
        self,
        scene_path,
        faults=None,
        vanish_after=None,
        printer_bed=None,
        fmt="binary",
        baud=2000000,
        time_scale=0.1,
    ):
        self.scene = load_scene(scene_path)
        pr = self.scene.printer
        bed = printer_bed or pr.bed_mm
        self.printer = PrinterEmulator(bed, (bed[0], bed[1], bed[5]), time_scale, faults)
        skin = SkinBoard(
            read_taxels(scene_path.parent / "t.csv"),
            self.scene.board,
            Placement.from_printer(pr),
            self.printer.tip_mm,
        )
        self.board = BoardEmulator(
            skin.frame, fps=0, wait_for_reader=True, fmt=fmt, baud=baud, vanish_after=vanish_after
        )
        self.fmt = fmt
        self.threads = [self.printer.start(), threading.Thread(target=self.board.play, daemon=True)]
        self.threads[1].start()

    def run(self, out, progress=None):
        """run_printer_bench itself (to inject Ctrl-C or a pulled cable via `progress`)."""
        try:
            return run_printer_bench(
                printer_bench_inputs(self.scene),
                self.scene.path.parent / "t.csv",
                None,
                self.printer.path,
                self.board.path,
                out,
                "small",
                self.fmt,
                progress=progress,
            )
        finally:
            self.end()

    def cli(self, out):
        """`fruit bench SCENE --printer P --board B --out OUT`: -> the click result."""
        try:
            return CliRunner().invoke(
                cli,
                [
                    "bench",
                    str(self.scene.path),
                    "--printer",
                    self.printer.path,
                    "--board",
                    self.board.path,
                    "--out",
                    str(out),
                ],
            )
        finally:
            self.end()

    def end(self):
        self.z_at_end = float(self.printer.tip_mm(1e18)[2])
        self.printer.stop.set()
        self.board.stop.set()
        for th in self.threads:
            th.join(5)


def one_error_line(res, pattern):
    import re

    assert res.exit_code == 1 and res.output.count("Error: ") == 1, res.output
    line = [ln for ln in res.output.splitlines() if ln.startswith("Error: ")][0]
    assert re.search(pattern, line[len("Error: ") :]), line


def kept(out):
    return read_npz(Path(out) / "small" / "frames.npz")


def test_a_missing_ok_times_out_retracts_and_keeps_the_frames(tmp_path):
    rig = Rig(make_scene(tmp_path), faults={"no-ok": [40]})
    one_error_line(
        rig.cli(tmp_path / "out"),
        r"^sample \d \(model x .*\): /dev/.*: no 'ok' for '(G1|M400).*' within 3 s "
        r"\(printer not answering\); \d+ frames and \d samples kept in .*small$",
    )
    assert rig.z_at_end == pytest.approx(13.0)  # retracted to the safe height
    rec = kept(tmp_path / "out")
    assert len(rec) > 10 and "no 'ok'" in rec.meta["stopped"]


def test_a_printer_error_halts_keeps_the_frames_and_says_so(tmp_path):
    rig = Rig(make_scene(tmp_path), faults={"halt": [45]})
    one_error_line(
        rig.cli(tmp_path / "out"),
        r"Error:Printer halted\. kill\(\) called! \(the printer has stopped\); "
        r"\d+ frames and \d samples kept in .*\(not retracted: the printer does "
        r"not answer\)$",
    )
    assert len(kept(tmp_path / "out")) > 10


def test_a_sample_outside_the_bed_stops_there_after_the_samples_before(tmp_path):
    printer = PRINTER + "bed_mm = [0, 0, 0, 220, 102, 250]\n"  # sample 1 is at y 103.5
    rig = Rig(make_scene(tmp_path, printer))
    one_error_line(
        rig.cli(tmp_path / "out"),
        r"^sample 1 \(model x 0\.00, y 4\.00 mm\): printer x 98\.00, y 103\.46, "
        r"z 1\.50\.\.13\.00 mm is outside \[printer\]\.bed_mm .*; \d+ frames and "
        r"1 samples kept in",
    )
    assert rig.z_at_end == pytest.approx(13.0)
    assert kept(tmp_path / "out").sample.max() == 0
    truth = read_table(tmp_path / "out" / "small" / "truth.csv", ["sample"])
    assert truth["sample"].tolist() == [0]


def test_no_touch_before_max_press_is_an_error_naming_the_sample(tmp_path):
    rig = Rig(make_scene(tmp_path, extra="[detection]\nthreshold_counts = 5000.0\n"))
    one_error_line(
        rig.cli(tmp_path / "out"),
        r"^sample 0 .*: no touch registered down to "
        r"\[printer\]\.max_press_mm = 1\.5 mm below",
    )
    rec = kept(tmp_path / "out")
    assert rig.z_at_end == pytest.approx(13.0)
    assert rec.printer_mm[:, 2].min() == pytest.approx(
        Placement([100, 100, 0], 30).to_printer([-20, -20, 3.0])[2] - 1.5, abs=1e-6
    )


def test_the_board_vanishing_retracts_and_keeps_the_frames(tmp_path):
    rig = Rig(make_scene(tmp_path))

    def progress(msg):  # the cable is pulled once sample 0 is done
        if msg.startswith("sample 0"):
            rig.board.vanish_after = 0

    with pytest.raises(
        BenchStopped,
        match=r"^sample 1 .*: /dev/.*: port closed or unplugged.*"
        r"; \d+ frames and 1 samples kept in",
    ):
        rig.run(tmp_path / "out", progress)
    assert rig.z_at_end == pytest.approx(13.0)
    assert kept(tmp_path / "out").sample.max() == 0


def test_the_printer_vanishing_keeps_the_frames_and_says_it_could_not_retract(tmp_path):
    rig = Rig(make_scene(tmp_path))

    def progress(msg):
        if msg.startswith("sample 0"):
            rig.printer.stop.set()  # its thread closes the pty

    with pytest.raises(
        BenchStopped,
        match=r"^sample 1 .*: printer port closed or unplugged.*"
        r"; \d+ frames and 1 samples kept in .*\(not "
        r"retracted: the printer does not answer\)$",
    ):
        rig.run(tmp_path / "out", progress)
    assert kept(tmp_path / "out").sample.max() == 0


def test_m114_catches_a_move_the_printer_clamped(tmp_path):
    """The scene's bed_mm claims more room than the printer has: its software endstops
    clamp the move to sample 1 (y 103.5 -> 102), and M114 says so."""
    rig = Rig(make_scene(tmp_path), printer_bed=[0, 0, 0, 220, 102, 250])
    one_error_line(
        rig.cli(tmp_path / "out"),
        r"^sample 1 .*: the printer reports X98\.00 Y102\.00 Z8\.00 after a move to "
        r"X98\.00 Y103\.46 Z8\.00 \(software endstops or lost steps\); \d+ frames "
        r"and 1 samples kept",
    )
    assert rig.printer.clamped >= 1 and rig.z_at_end == pytest.approx(13.0)


def test_ctrl_c_retracts_and_keeps_the_frames(tmp_path):
    def progress(msg):
        if msg.startswith("sample 1"):
            raise KeyboardInterrupt

    rig = Rig(make_scene(tmp_path))
    with pytest.raises(
        BenchInterrupted,
        match=r"^interrupted at sample 1 .*; \d+ frames and "
        r"2 samples kept in",
    ):
        rig.run(tmp_path / "out", progress)
    assert rig.z_at_end == pytest.approx(13.0)
    assert kept(tmp_path / "out").meta["stopped"].endswith("interrupted (Ctrl-C)")


@pytest.mark.parametrize(
    "line, msg",
    [
        ("step_mm = 0.0", r"\[printer\]\.step_mm: expected 0 < step <= 1 mm, got 0\.0"),
        ("step_mm = 1.5", r"\[printer\]\.step_mm: expected 0 < step <= 1 mm, got 1\.5"),
        ("feed_mm_min = 0", r"\[printer\]\.feed_mm_min: expected > 0 mm/min"),
        ("safe_height_mm = -2.0", r"\[printer\]\.safe_height_mm: expected > 0"),
        ("bed_mm = [0, 0, 0, 0, 220, 250]", r"\[printer\]\.bed_mm: expected .* min < max"),
        ("stepmm = 0.1", r"\[printer\]: unknown key 'stepmm' \(did you mean 'step_mm'\?\)"),
    ],
)
def test_bad_printer_tables_are_one_line_errors(tmp_path, line, msg):
    key = line.split("=")[0].strip()
    printer = (
        "".join(ln + "\n" for ln in PRINTER.splitlines() if not ln.startswith(key + " "))
        + line
        + "\n"
    )
    with pytest.raises(SceneError, match=msg):
        load_scene(make_scene(tmp_path, printer))


def test_printer_table_without_origin_and_unreachable_safe_height(tmp_path):
    with pytest.raises(SceneError, match=r"\[printer\]: missing key 'model_origin_mm'"):
        load_scene(make_scene(tmp_path, "[printer]\nstep_mm = 0.2\n"))
    scene = make_scene(tmp_path, PRINTER + "bed_mm = [0, 0, 0, 220, 220, 12]\n")
    res = CliRunner().invoke(
        cli,
        [
            "bench",
            str(scene),
            "--printer",
            "/dev/nonexistent-p",
            "--board",
            "/dev/nonexistent-b",
            "--out",
            str(tmp_path / "out"),
        ],
    )
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "[printer].safe_height_mm: the safe height, printer z = 13.00 mm" in res.output
    scene = make_scene(tmp_path)
    res = CliRunner().invoke(
        cli,
        [
            "bench",
            str(scene),
            "--printer",
            "/dev/nonexistent-p",
            "--board",
            "/dev/nonexistent-b",
            "--out",
            str(tmp_path / "out"),
        ],
    )
    assert res.exit_code == 1 and "/dev/nonexistent-p: serial port does not exist" in res.output
    res = CliRunner().invoke(
        cli, ["bench", str(scene), "--printer", "/dev/x", "--out", str(tmp_path / "out")]
    )
    assert res.exit_code == 2 and "needs both --printer and --board" in res.output
    assert not (tmp_path / "out").exists()


def test_busy_lines_while_homing_extend_the_time_out():
    """G28 takes 1.2 s, the time-out is 0.6 s: the printer's busy lines every 0.5 s keep
    the host waiting, and the ok arrives."""
    import serial

    from fruitcli.printer.emulator import HOME_S
    from fruitcli.printer.marlin import Marlin, PrinterError

    em = PrinterEmulator(time_scale=1.0, faults={"no-ok": [4]})  # M110, G28, M114, G21
    th = em.start()
    port = serial.Serial(em.path, 115200, timeout=0.05)
    try:
        host = Marlin(port, "printer", timeout_s=0.6)
        host.wait_ready()
        t0 = time.monotonic()
        host.command("G28")
        assert host.busy >= 2 and time.monotonic() - t0 >= HOME_S * 0.9
        assert host.position() == (0.0, 0.0, 0.0)
        with pytest.raises(PrinterError, match=r"printer: no 'ok' for 'G21' within 0\.6 s"):
            host.command("G21")  # the fourth command line is never answered
    finally:
        port.close()
        em.stop.set()
        th.join(5)
