"""Soak: 8 hours of an exhibition in compressed time through `fruit live --reconnect`.

The emulated board drifts 40 counts over the 8 hours (thermal, per taxel 20-40 counts),
has 1-count noise, a visitor's touch every 6 s (2 s long) and three cable pulls (1 min,
30 s, 2 min); 1 frame per emulated second, played 1000 times faster (28.8 s).
"""

import re
import subprocess
import time

import numpy as np
import pytest

from tests.helpers.soak_board import SoakBoard, SoakPlan
from tests.sensing.detection.test_drift import check_touches, live_command, sessions_of

SCALE = 1000.0


def rss_kb(pid: int) -> int:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


@pytest.mark.slow
def test_eight_hours_compressed(tmp_path):
    plan = SoakPlan(seed=11)
    assert len(plan.touches) > 4000
    link = tmp_path / "ttyFRUIT"
    board = SoakBoard(plan, link, time_scale=SCALE)
    spans = plan.connected()
    total = sum(len(plan.frame_times(a, b)) for a, b in spans)
    proc = subprocess.Popen(
        live_command(
            tmp_path,
            link,
            "--frames",
            str(total),
            "--time-scale",
            str(SCALE),
            "--log",
            str(tmp_path / "run.log"),
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(0.5)
    th = board.start()
    rss = []
    import threading

    def sample():
        while proc.poll() is None:
            try:
                rss.append((time.monotonic(), rss_kb(proc.pid)))
            except OSError:
                return
            time.sleep(0.25)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    try:
        out, err = proc.communicate(timeout=240)
    finally:
        board.stop.set()
        proc.kill()
        th.join(10)
        sampler.join(2)
    assert board.error is None
    assert proc.returncode == 0, err[-2000:]
    # no lost frame: every whole frame of every connection reached the detection
    assert board.sent == [len(plan.frame_times(a, b)) for a, b in spans]
    assert f"] {total} frames" in err and "3 reconnects" in err
    # every touch detected once, where it was, on all its frames; no false touch
    check_touches(plan, sessions_of(out))
    assert "taxels: all healthy" in err
    # memory flat: the second half of the run against its second quarter
    t0, t1 = rss[0][0], rss[-1][0]
    q2 = [kb for t, kb in rss if t0 + 0.25 * (t1 - t0) <= t < t0 + 0.5 * (t1 - t0)]
    q4 = [kb for t, kb in rss if t >= t0 + 0.75 * (t1 - t0)]
    assert len(q2) >= 5 and len(q4) >= 5
    growth_mb = (np.median(q4) - np.median(q2)) / 1024
    assert growth_mb < 2.0, f"RSS grew {growth_mb:.1f} MB"
    # without the drift tracker the same day gives false touches once the drift passes
    # the threshold (20 counts after about 4 hours): see test_drift_is_needed below
    # a status line a minute, from the first frame into the last hour: a minute is 60 ms
    # of wall time here, and a frame that arrives late on a busy machine pushes the next
    # lines back, so the count is not exact (461 of 480 in a loaded CI run, 402-462 with
    # a CPU hog beside the test); the clock starts with the process, before the board
    log = (tmp_path / "run.log").read_text()
    t_status = np.array([float(t) for t in re.findall(r" status t (\d+) s,", log)])
    assert 0.75 * 8 * 60 <= len(t_status) <= 8 * 60 + 1
    assert np.all(np.diff(t_status) >= 59.0)  # printed to the second
    assert t_status[-1] - t_status[0] >= 7 * 3600.0


def test_a_fixed_baseline_fails_the_soak_day_and_the_tracker_does_not():
    """The first connection (5 h) of the soak plan in process: with a fixed baseline the
    drift (past 20 counts after about 4 h) makes false touches; with the tracker none."""
    from fruitcli.sensing.detection.drift import DriftTracker
    from fruitcli.sensing.detection.frames_to_touches import Locator
    from fruitcli.sensing.detection.settings import Settings
    from fruitcli.sensing.frames.board import default_board
    from fruitcli.sensing.live.loop import LiveLocator
    from fruitcli.tables import Taxels

    plan = SoakPlan(seed=11)
    a, b = plan.connected()[0]
    frames, times = plan.frames(a, b), plan.frame_times(a, b)
    truth = [tc for tc in plan.touches if tc.end_s <= b]
    i, j = np.divmod(np.arange(21 * 12), 12)
    taxels = Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0 * i], 1))
    found = {}
    for name, drift in (("fixed", None), ("tracked", DriftTracker(60.0, 20.0))):
        live = LiveLocator(Locator(taxels, default_board(), taxels.xyz_mm, Settings()), drift=drift)
        sessions = set()
        for f, t in zip(frames, times, strict=True):
            lf = live.step(f, t)
            if lf is not None:
                sessions.update(lf.sessions.ids.tolist())
        found[name] = len(sessions)
    assert found["tracked"] == len(truth)
    assert found["fixed"] > len(truth) + 100
