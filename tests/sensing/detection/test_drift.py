"""Weeks of running: the drift tracker, taxel health flags, the rotating log, reconnects."""

import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.sensing.detection.drift import DriftTracker
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.health import TaxelHealth
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.live.run_log import RunLog
from fruitcli.tables import Taxels
from tests.helpers.soak_board import SoakBoard, SoakPlan


def test_drift_follows_a_ramp_with_the_first_order_lag():
    """A ramp r counts/s through C0' = (C - C0) / tau lags by r tau once settled."""
    tr = DriftTracker(tau_s=10.0, threshold_counts=20.0)
    base = np.zeros(3)
    rate = 0.05  # counts/s
    for k in range(2001):  # 10 Hz for 200 s
        t = k * 0.1
        tr.update(base, np.full(3, rate * t), t)
    # the exact discrete lag: a = 1 - exp(-dt / tau), lag = r dt (1 - a) / a
    a = -math.expm1(-0.1 / 10.0)
    assert base == pytest.approx(rate * 200.0 - rate * 0.1 * (1 - a) / a, abs=1e-6)
    assert tr.adapted == 2001 and tr.frozen == 0


def test_a_hovering_hand_below_the_threshold_is_not_absorbed():
    """15 counts held for 10 minutes (threshold 20): the baseline stays; the per-frame
    tracker of the bench replays (drift_rate) absorbs it, as it always did."""
    tr = DriftTracker(tau_s=30.0, threshold_counts=20.0)
    base = np.full(4, 500.0)
    hover = np.array([515.0, 508.0, 500.0, 500.0])
    for k in range(6000):
        tr.update(base, hover, k * 0.1)
    assert base.tolist() == [500.0, 500.0, 500.0, 500.0]
    assert tr.frozen == 6000
    # the old tracker: C0 += r (C - C0) on every frame below threshold - hysteresis
    i, j = np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1])
    taxels = Taxels(np.arange(4), i, j, np.zeros((4, 3)))
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(drift_rate=0.01))
    stream = Stream(loc, np.full(4, 500.0))
    for _ in range(6000):
        stream.step(hover)
    assert stream.baseline[0] == pytest.approx(515.0, abs=0.01)  # absorbed


def test_drift_freezes_for_the_hold_time_and_follows_counts_below_the_baseline():
    tr = DriftTracker(tau_s=1.0, threshold_counts=20.0, hold_s=4.0)
    base = np.full(2, 500.0)
    tr.update(base, np.array([530.0, 500.0]), 0.0)  # a touch
    tr.update(base, np.array([500.0, 490.0]), 1.0)  # 1 s later: held, but 490 followed
    assert base[0] == 500.0
    assert base[1] == pytest.approx(500 - 10 * (1 - math.exp(-1.0)))
    b1 = base[1]
    tr.update(base, np.array([505.0, b1]), 3.9)  # still held
    assert base[0] == 500.0
    tr.update(base, np.array([505.0, b1]), 4.5)  # hold over: adapts over dt = 0.6 s
    assert base[0] == pytest.approx(500 + 5 * (1 - math.exp(-0.6)))


@pytest.mark.parametrize("tau", [0.0, -1.0, math.inf, math.nan])
def test_drift_time_constant_must_be_positive(tau):
    with pytest.raises(FrameError, match="drift time constant: expected a finite number"):
        DriftTracker(tau, 20.0)


def test_taxel_health_flags():
    h = TaxelHealth(5, threshold_counts=20.0, run_frames=50)
    rng = np.random.default_rng(0)
    for _ in range(60):
        v = 500 + rng.normal(0, 1.0, 5)
        v[1] = 0  # dead
        v[2] = 612  # stuck
        v[3] = 65535  # saturated (also stuck: it never changes)
        v[4] = 500 + rng.normal(0, 8.0)  # noisy: std 8 > 20 / 4
        h.update(np.round(v), quiet=True)
    f = h.flags()
    assert f["dead"].tolist() == [1]
    assert f["stuck"].tolist() == [2, 3]
    assert f["saturated"].tolist() == [3]
    assert f["noisy"].tolist() == [4]
    std = h.noise_std()
    assert 0.5 < std[0] < 1.5 and 5 < std[4] < 12
    assert (
        h.summary(np.array([10, 11, 12, 13, 14]))
        == "taxels: dead 11; stuck 12, 13; saturated 13; noisy 14"
    )


def test_rotating_log_stays_bounded(tmp_path):
    log = RunLog(tmp_path / "run.log", max_bytes=2000, backups=2)
    for k in range(500):
        log.status(f"line {k} " + "x" * 40)
    log.close()
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["run.log", "run.log.1", "run.log.2"]
    assert all((tmp_path / f).stat().st_size <= 2000 for f in files)
    last = (tmp_path / "run.log").read_text().splitlines()[-1]
    assert last.endswith("status line 499 " + "x" * 40) and last[:4].isdigit()


SCENE = "[detection]\nbaseline_frames = 10\n"


def board_taxel_csv(path):
    lines = ["# the whole 21 x 12 board, mm", "id,i,j,x_mm,y_mm,z_mm"]
    for n in range(21 * 12):
        i, j = divmod(n, 12)
        lines.append(f"{n},{i},{j},{16.0 * i},{12.0 * j},0.0")
    path.write_text("\n".join(lines) + "\n")
    return path


def live_command(tmp_path, link, *extra):
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = board_taxel_csv(tmp_path / "t.csv")
    return [
        sys.executable,
        "-c",
        "from fruitcli.cli.main import main; main()",
        "live",
        str(tmp_path / "s.toml"),
        "--port",
        str(link),
        "--taxels",
        str(taxels),
        "--reconnect",
        *extra,
    ]


def sessions_of(stdout: str) -> dict[int, list]:
    """session id -> [(frame, i, j), ...] from the JSON lines."""
    import json

    out: dict[int, list] = {}
    for line in stdout.splitlines():
        if line.startswith("{"):
            d = json.loads(line)
            for t in d["touches"]:
                out.setdefault(t["touch"], []).append((d["frame"], t["i"], t["j"]))
    return out


def check_touches(plan: SoakPlan, sessions: dict[int, list]):
    """Every touch found once, in order, where it was; nothing else."""
    assert len(sessions) == len(plan.touches)
    for (sid, rows), tc in zip(sorted(sessions.items()), plan.touches, strict=True):
        i = np.mean([r[1] for r in rows])
        j = np.mean([r[2] for r in rows])
        assert abs(i - tc.row) < 0.5 and abs(j - tc.col) < 0.5, (sid, tc)
        assert len(rows) == round((tc.end_s - tc.start_s) * plan.fps)  # every frame


def test_reconnect_after_a_cable_pull_rebaselines_and_goes_on(tmp_path):
    plan = SoakPlan(
        hours=0.02,
        fps=5.0,
        drift_counts=2.0,
        touch_every_s=4.0,
        touch_s=1.0,
        pulls=((36.0, 3.0),),
        quiet_after_s=4.0,
        seed=3,
    )
    link = tmp_path / "ttyFRUIT"
    board = SoakBoard(plan, link, time_scale=20.0)
    total = sum(len(plan.frame_times(a, b)) for a, b in plan.connected())
    proc = subprocess.Popen(
        live_command(
            tmp_path,
            link,
            "--frames",
            str(total),
            "--time-scale",
            "20",
            "--log",
            str(tmp_path / "run.log"),
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(0.5)  # fruit live waits for the port first (--reconnect)
    th = board.start()
    try:
        out, err = proc.communicate(timeout=60)
    finally:
        board.stop.set()
        proc.kill()
        th.join(10)
    assert board.error is None
    assert proc.returncode == 0, err
    assert board.sent == [len(plan.frame_times(a, b)) for a, b in plan.connected()]
    assert "port lost after " in err
    assert "reconnected (1); collecting 10 baseline frames" in err
    assert f"{total} frames" in err and "1 reconnect " in err
    check_touches(plan, sessions_of(out))
    log = (tmp_path / "run.log").read_text()
    assert log.count(" down ") == log.count(" up ") == len(plan.touches)
    assert "event port" in log and "reconnect 1" in log
    assert "status t " in log  # a status line per (emulated) minute


def test_frames_while_reconnecting_and_a_drift_tau_of_zero(tmp_path):
    res = CliRunner().invoke(cli, ["live", "x.toml", "--port", "p", "--drift-tau-s", "0"])
    assert res.exit_code == 2 and "--drift-tau-s" in res.output and "0.0" in res.output
    # a port that never comes back: --reconnect waits (and says so) until interrupted
    cmd = live_command(tmp_path, tmp_path / "ttyNONE")
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 90  # start-up alone took over 20 s on a loaded machine
    err = b""
    os.set_blocking(proc.stderr.fileno(), False)
    while time.monotonic() < deadline and b"waiting for it" not in err:
        time.sleep(0.1)
        err += proc.stderr.buffer.read() or b""
    proc.send_signal(2)
    _, rest = proc.communicate(timeout=30)
    err = err.decode() + rest
    assert "ttyNONE: serial port does not exist; waiting for it (--reconnect)" in err
    assert proc.returncode == 130 and "Interrupted." in err and "Traceback" not in err


def test_rebaseline_ends_the_touches_and_collects_a_new_baseline():
    import json

    from fruitcli.sensing.live.loop import LiveLocator

    i, j = np.divmod(np.arange(16), 4)
    taxels = Taxels(np.arange(16), i, j, np.stack([16.0 * i, 16.0 * j, 0 * i], axis=1))
    live = LiveLocator(
        Locator(taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=2)),
        drift=DriftTracker(60, 20),
    )
    idle = np.full((21, 12), 500)
    touched = idle.copy()
    touched[1, 1] += 50
    assert live.step(idle, 0.0) is None and live.step(idle, 0.1) is None
    assert live.baseline_state == "tracking" and live.baselines == 1
    f = live.step(touched, 0.2)
    assert f.sessions.ids.tolist() == [0] and live.json_line(f) is not None
    ended, line = live.rebaseline(0.3)
    assert ended == [0] and json.loads(line) == {"frame": 2, "t_s": 0.3, "touches": []}
    assert live.baseline_state == "collecting 0/2"
    # the board back with counts 40 higher: the new baseline takes them
    assert live.step(idle + 40, 1.0) is None and live.step(idle + 40, 1.1) is None
    f = live.step(idle + 40, 1.2)
    assert len(f.touches) == 0 and live.baselines == 2
    assert live.baseline_shift() == pytest.approx(np.full(16, 40.0))
    f = live.step(touched + 40, 1.3)
    assert f.sessions.ids.tolist() == [1]  # a new session id, never 0 again
    assert live.rebaseline(1.4)[0] == [1]


def test_log_in_a_missing_folder_is_one_line(tmp_path):
    (tmp_path / "s.toml").write_text(SCENE)
    res = CliRunner().invoke(
        cli,
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            str(tmp_path / "tty"),
            "--taxels",
            str(board_taxel_csv(tmp_path / "t.csv")),
            "--log",
            str(tmp_path / "no" / "run.log"),
        ],
    )
    assert res.exit_code == 1
    assert (
        res.output.strip().splitlines()[-1]
        == f"Error: {tmp_path / 'no' / 'run.log'}: No such file or directory"
    )


def test_a_log_that_cannot_be_written_is_counted_not_fatal(tmp_path, capsys):
    log = RunLog(tmp_path / "run.log", max_bytes=10_000, backups=1)
    log.handler.stream.close()  # as if the disk had gone away
    log.status("one")
    log.status("two")
    assert log.failed == 2 and "Traceback" not in capsys.readouterr().err
    log.close()


def test_a_noisy_taxel_is_flagged_and_does_not_freeze_the_drift_tracker():
    """Taxel 0 has noise std 6 counts (over a quarter of the threshold): it crosses the
    guard (10 counts) on about 10 % of the frames, which alone would hold the tracker
    frozen; once flagged noisy it no longer does, and the others follow a ramp of
    0.1 counts/s with their first-order lag."""
    from fruitcli.sensing.live.loop import LiveLocator

    i, j = np.divmod(np.arange(16), 4)
    taxels = Taxels(np.arange(16), i, j, np.stack([16.0 * i, 16.0 * j, 0 * i], axis=1))
    ends = {}
    for health in (False, True):
        live = LiveLocator(
            Locator(taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=10)),
            drift=DriftTracker(10.0, 20.0),
            health=health,
        )
        noise = np.random.default_rng(5)
        for k in range(3000):  # 10 frames/s, 300 s
            f = 500.0 + 0.1 * k / 10 + noise.normal(0, 0.5, (21, 12))
            f[0, 0] += noise.normal(0, 6.0) - 0.1 * k / 10  # taxel 0: noisy, no drift
            live.step(np.round(f), k / 10)
        ends[health] = live.stream.baseline[1:] - 500.0
        if health:
            assert live.health.flags()["noisy"].tolist() == [0]
    assert np.median(ends[True]) == pytest.approx(30.0 - 0.1 * 10, abs=0.5)  # r tau lag
    assert np.median(ends[False]) < 10.0  # frozen most of the time
