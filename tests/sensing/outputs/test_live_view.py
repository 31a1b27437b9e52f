"""The live view (`fruit live --view`) in a real headless Chromium, driven over the
DevTools protocol on a pipe, against the emulated board."""

import base64
import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from fruitcli.sensing.live.board_emulator import BoardEmulator
from fruitcli.tables import read_taxels
from tests.sensing.detection.test_drift import board_taxel_csv

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


class Chromium:
    """Headless Chromium with ``--remote-debugging-pipe``: commands on its fd 3, replies
    on its fd 4, JSON messages ended by NUL."""

    def __init__(self, profile_dir, width=960, height=560):
        cmd_r, self.cmd_w = os.pipe()
        self.res_r, res_w = os.pipe()

        def onto_3_and_4():  # in the child: dup first, as the pipes may be 3 or 4
            a, b = os.dup(cmd_r), os.dup(res_w)
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.proc = subprocess.Popen(
            [
                CHROMIUM,
                *FLAGS,
                f"--user-data-dir={profile_dir}",
                "--remote-debugging-pipe",
                f"--window-size={width},{height}",
                "about:blank",
            ],
            preexec_fn=onto_3_and_4,
            close_fds=False,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(cmd_r)
        os.close(res_w)
        self.buf = b""
        self.next_id = 0
        self.session = None
        self.size = (width, height)

    def call(self, method, params=None, timeout=30.0, session=True):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self.cmd_w, json.dumps(msg).encode() + b"\0")
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            while b"\0" in self.buf:
                raw, self.buf = self.buf.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self.next_id:
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    return reply["result"]
            import select

            if select.select([self.res_r], [], [], 0.2)[0]:
                chunk = os.read(self.res_r, 1 << 20)
                if not chunk:
                    raise RuntimeError("chromium closed its pipe")
                self.buf += chunk
        raise TimeoutError(method)

    def open(self, url):
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})[
            "sessionId"
        ]
        w, h = self.size
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": w, "height": h, "deviceScaleFactor": 1, "mobile": False},
        )
        self.call("Page.navigate", {"url": url})

    def js(self, expression):
        r = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        if "exceptionDetails" in r:
            raise RuntimeError(r["exceptionDetails"])
        return r["result"].get("value")

    def wait_for(self, expression, timeout=30.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            value = self.js(expression)
            if value:
                return value
            time.sleep(0.2)
        raise TimeoutError(expression)

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])

    def close(self):
        try:
            self.call("Browser.close", session=False, timeout=5)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        os.close(self.cmd_w)
        os.close(self.res_r)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def held_touch_frames(n=3000, cell=(10, 5), counts=60.0, seed=0):
    """Idle board (500 counts, noise std 0.5) with a touch held on `cell` from frame 20
    on: a Gaussian of sigma 0.8 cells centred on the cell (its N9 centroid is the cell)."""
    rng = np.random.default_rng(seed)
    f = 500 + rng.normal(0, 0.5, (n, 21, 12))
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    f[20:] += counts * np.exp(-((r - cell[0]) ** 2 + (c - cell[1]) ** 2) / (2 * 0.8**2))
    return np.round(f).astype(np.int64)


@pytest.mark.skipif(CHROMIUM is None, reason="needs chromium (.ci/run installs it)")
def test_live_view_in_headless_chromium(tmp_path):
    (tmp_path / "s.toml").write_text("[detection]\nbaseline_frames = 10\n")
    taxels = board_taxel_csv(tmp_path / "t.csv")  # x = 16 i, y = 12 j mm
    em = BoardEmulator(held_touch_frames(), fps=30, wait_for_reader=True)
    th = em.start()
    port = free_port()
    live = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from fruitcli.cli.main import main; main()",
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            em.path,
            "--taxels",
            str(taxels),
            "--view",
            f"127.0.0.1:{port}",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    browser = None
    try:
        url = f"http://127.0.0.1:{port}/"
        end = time.monotonic() + 30
        while time.monotonic() < end:  # the server is up once fruit live has started
            try:
                state = json.loads(urllib.request.urlopen(url + "state", timeout=2).read())
                if state["touches"]:
                    break
            except OSError:
                pass
            time.sleep(0.2)
        assert state["touches"] and len(state["activation"]) == 252
        browser = Chromium(tmp_path / "profile")
        browser.open(url)
        n = browser.wait_for("document.querySelectorAll('#markers .touch').length")
        assert n == 1
        browser.wait_for("document.getElementById('status').textContent === 'live'")
        m = browser.js("""(() => { const m = document.querySelector('#markers .touch');
            return {id: m.dataset.id, x: +m.dataset.xMm, y: +m.dataset.yMm,
                    left: parseFloat(m.style.left), top: parseFloat(m.style.top),
                    label: m.textContent}; })()""")
        assert m["id"] == "0" and m["label"] == "0"
        assert m["x"] == pytest.approx(160.0, abs=1.0) and m["y"] == pytest.approx(60.0, abs=1.0)
        # the page's top view: taxels x 0..320 mm, y 0..132 mm fitted in 560 x 400 px
        # (40 px margins), y up: the marker sits on taxel (10, 5)
        s = min(560 / 320, 400 / 132)
        ox, oy = 40 + (560 - s * 320) / 2, 40 + (400 - s * 132) / 2
        assert m["left"] == pytest.approx(ox + s * 160, abs=2)
        assert m["top"] == pytest.approx(480 - oy - s * 60, abs=2)
        # the heat map under the marker is the scale's top colour (60 counts > 2 x 20);
        # a taxel far from the touch is the bottom colour
        pixel = """((x, y) => Array.from(document.getElementById('heat').getContext('2d')
                    .getImageData(x, y, 1, 1).data.slice(0, 3)))"""
        assert browser.js(f"{pixel}({m['left']:.0f}, {m['top']:.0f})") == [253, 231, 37]
        far = (ox + s * 16 * 2, 480 - oy - s * 12 * 1)  # taxel (2, 1)
        dark = browser.js(f"{pixel}({far[0]:.0f}, {far[1]:.0f})")  # noise: about 0 counts
        assert np.abs(np.array(dark) - [68, 1, 84]).max() <= 20, dark
        text = browser.js("document.querySelector('#touches li').textContent")
        import re

        got = re.fullmatch(r"id 0: \(([-\d.]+), ([-\d.]+), ([-\d.]+)\) mm, peak (\d+) counts", text)
        assert got, text
        assert [float(v) for v in got.groups()] == pytest.approx([160, 60, 0, 60], abs=1.5)
        assert browser.js("document.getElementById('baseline').textContent") == "tracking"
        fps = float(browser.js("document.getElementById('fps').textContent"))
        assert 15 < fps < 60  # the emulator plays 30 frames/s (read in bursts when busy)
        assert browser.js("document.getElementById('flags').textContent") == "all healthy"
        frame0 = int(browser.js("document.body.dataset.frame"))
        browser.wait_for(f"+document.body.dataset.frame > {frame0 + 15}")  # it is live
        png = browser.screenshot()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        (tmp_path / "view.png").write_bytes(png)
        shot = os.environ.get("FRUIT_VIEW_SCREENSHOT")  # the README's figure
        if shot:
            (tmp_path / "view.png").replace(shot)
    finally:
        if browser is not None:
            browser.close()
        live.send_signal(2)
        try:
            live.communicate(timeout=10)
        finally:
            live.kill()
            em.stop.set()
            th.join(5)


def test_view_port_in_use_is_one_line(tmp_path):
    from click.testing import CliRunner

    from fruitcli.cli.main import cli

    (tmp_path / "s.toml").write_text("[detection]\nbaseline_frames = 10\n")
    taxels = board_taxel_csv(tmp_path / "t.csv")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        res = CliRunner().invoke(
            cli,
            [
                "live",
                str(tmp_path / "s.toml"),
                "--port",
                str(tmp_path / "tty"),
                "--taxels",
                str(taxels),
                "--view",
                str(port),
            ],
        )
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        f"Error: --view 127.0.0.1:{port}: port {port} is in use (another program listens "
        "there; choose another port)"
    )
    res = CliRunner().invoke(
        cli,
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            str(tmp_path / "tty"),
            "--taxels",
            str(taxels),
            "--view",
            "nosuchhost.invalid:8080",
        ],
    )
    assert res.exit_code == 1 and "host 'nosuchhost.invalid' does not resolve" in res.output
    res = CliRunner().invoke(
        cli,
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            str(tmp_path / "tty"),
            "--taxels",
            str(taxels),
            "--view",
            "80800",
        ],
    )
    assert res.exit_code == 1 and "expected [HOST:]PORT with a port in 1-65535" in res.output


def test_view_state_has_pressures_touches_fps_and_baseline(tmp_path, capsys):
    from fruitcli.sensing.detection.drift import DriftTracker
    from fruitcli.sensing.detection.frames_to_touches import Locator
    from fruitcli.sensing.detection.settings import Settings
    from fruitcli.sensing.frames.board import default_board
    from fruitcli.sensing.live.loop import LiveLocator
    from fruitcli.sensing.live.outputs import Outputs
    from fruitcli.sensing.live.serial_ports import PressureState

    taxels = read_taxels(board_taxel_csv(tmp_path / "t.csv"))
    live = LiveLocator(
        Locator(taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=10)),
        drift=DriftTracker(60, 20),
        health=True,
    )
    pressure = PressureState(("c1", "c2"))
    out = Outputs(live, taxels, lambda message: None, 1.0, pressure)
    frames = held_touch_frames(40)
    st = out.view_state()
    assert st["baseline"] == "collecting 0/10" and st["touches"] == [] and st["fps"] == 0
    assert st["pressures"] == {}  # nothing measured yet
    pressure.update("P c1=2.5 c2=7.0")
    for k, f in enumerate(frames):
        out.frame(f, out.t0 + k / 25)  # 25 frames/s
    st = out.view_state()
    assert st["frame"] == 39 and st["baseline"] == "tracking" and st["reconnects"] == 0
    assert st["fps"] == pytest.approx(25.0)
    assert st["pressures"] == {"c1": 2.5, "c2": 7.0}
    (t,) = st["touches"]
    assert t["id"] == 0 and (t["x_mm"], t["y_mm"], t["i"], t["j"]) == pytest.approx(
        (160, 60, 10, 5), abs=0.2
    )
    assert st["activation"][10 * 12 + 5] == pytest.approx(60, abs=2)
    assert st["flags"] == {"dead": [], "stuck": [], "saturated": [], "noisy": []}
    assert capsys.readouterr().out.count('"touch": 0') == 20  # the JSON lines
