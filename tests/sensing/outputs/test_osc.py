"""Touches out as TUIO 1.1 / plain OSC: received by a real UDP server on 127.0.0.1 and
decoded with python-osc (an implementation independent of fruit's encoder)."""

import socket
import threading

import numpy as np
import pytest
from click.testing import CliRunner
from pythonosc import dispatcher, osc_server
from pythonosc.osc_bundle import OscBundle

from fruitcli.cli.main import cli
from fruitcli.sensing.detection.frames_to_touches import Locator
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.live.board_emulator import BoardEmulator, synthetic_frames
from fruitcli.sensing.live.loop import LiveLocator
from fruitcli.sensing.outputs.tuio import Normalizer, TuioSender
from fruitcli.tables import Taxels

F32 = dict(rel=1e-6, abs=1e-6)  # OSC floats are float32


class Receiver:
    """Every datagram sent to 127.0.0.1:<port>, kept whole."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.dgrams: list[bytes] = []
        self.stop = threading.Event()
        self.th = threading.Thread(target=self.run, daemon=True)
        self.th.start()

    def run(self):
        while not self.stop.is_set():
            try:
                self.dgrams.append(self.sock.recv(65536))
            except TimeoutError:
                continue

    def close(self, expect: int | None = None, wait_s: float = 5.0):
        import time

        end = time.monotonic() + wait_s
        while expect is not None and len(self.dgrams) < expect and time.monotonic() < end:
            time.sleep(0.01)
        self.stop.set()
        self.th.join(2)
        self.sock.close()
        return [[(m.address, m.params) for m in OscBundle(d)] for d in self.dgrams]


def grid_taxels(ni=6, nj=5):
    """Taxels at x = 16 i, y = 12 j, z = 0.5 i (mm)."""
    i, j = np.meshgrid(np.arange(ni), np.arange(nj), indexing="ij")
    i, j = i.ravel(), j.ravel()
    return Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0.5 * i], axis=1))


def frame_with(cells):
    """A noiseless 21 x 12 frame at 500 counts plus `cells` {(row, col): counts}."""
    f = np.full((21, 12), 500, np.int64)
    for (r, c), v in cells.items():
        f[r, c] += v
    return f


def test_tuio_bundles_carry_every_field_in_closed_form():
    taxels = grid_taxels()
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=3))
    live = LiveLocator(loc)
    rx = Receiver()
    norm = Normalizer.from_taxels(taxels.i, taxels.j, taxels.xyz_mm)
    tuio = TuioSender(("127.0.0.1", rx.port), norm, "3Dcur", source="fruit@test")
    # a touch moving one taxel along i per frame (single cells: the N9 centroid is the
    # taxel itself), a static one at (3, 3); frame times: 0.1 s apart, then 0.05 s
    t = [0.0, 0.1, 0.2, 0.3, 0.4, 0.45, 0.55, 0.65]
    frames = [frame_with({}) for _ in range(3)]
    frames += [
        frame_with({(0, 0): 40, (3, 3): 30}),
        frame_with({(1, 0): 41, (3, 3): 30}),
        frame_with({(2, 0): 42, (3, 3): 30}),
        frame_with({(3, 3): 30}),
        frame_with({(5, 4): 50}),
    ]
    sent = []
    for k, f in enumerate(frames):
        lf = live.step(f, t[k])
        if lf is not None:
            tuio.send(
                lf.t_s,
                lf.sessions.ids,
                lf.sessions.new,
                lf.sessions.ended,
                lf.ij,
                lf.touches.xyz_mm,
                lf.touches.peak,
            )
            sent.append(lf)
    got = rx.close(expect=4 * len(sent))
    tuio.close()
    assert len(got) == 4 * len(sent) == 20
    L = 16.0 * 5  # largest side of the taxels' bounding box (x: 0..80 mm)
    # expected per frame: (sessions, (i, j) of each, peak of each)
    want = [
        ([0, 1], [(0, 0), (3, 3)], [40, 30]),
        ([0, 1], [(1, 0), (3, 3)], [41, 30]),
        ([0, 1], [(2, 0), (3, 3)], [42, 30]),
        ([1], [(3, 3)], [30]),
        ([2], [(5, 4)], [50]),
    ]
    v_i = [0.0, 1 / 0.1, 1 / 0.05]  # grid units per s of the moving touch (session id 0)
    for f, (ids, ij, peaks) in enumerate(want):
        b2, b3, bp, plain = got[4 * f : 4 * f + 4]
        for b, prof in ((b2, "/tuio/2Dcur"), (b3, "/tuio/3Dcur"), (bp, "/tuio/_sp")):
            assert [a for a, _ in b] == [prof] * (3 + len(ids))
            assert b[0][1] == ["source", "fruit@test"]
            assert b[1][1] == ["alive", *ids]
            assert b[-1][1] == ["fseq", f + 1]
            assert [m[1][:2] for m in b[2:-1]] == [["set", s] for s in ids]
        for n, s in enumerate(ids):
            i, j = ij[n]
            moving = s == 0
            vi = v_i[f] if moving else 0.0
            vi_prev = v_i[f - 1] if moving and f else 0.0
            dt = t[3 + f] - t[2 + f]
            # 2Dcur: x = i / 5, y = 1 - j / 4; X, Y per s; m = change of speed per s
            x2, y2, X2, Y2, m2 = b2[2 + n][1][2:]
            assert (x2, y2) == pytest.approx((i / 5, 1 - j / 4), **F32)
            assert (X2, Y2) == pytest.approx((vi / 5, 0.0), **F32)
            assert m2 == pytest.approx((vi - vi_prev) / 5 / dt if moving and f else 0.0, **F32)
            # 3Dcur: (x, y, z) mm / L from the bounding box corner (0, 0, 0)
            x3, y3, z3, X3, Y3, Z3, m3 = b3[2 + n][1][2:]
            assert (x3, y3, z3) == pytest.approx((16 * i / L, 12 * j / L, 0.5 * i / L), **F32)
            speed3 = np.hypot(16, 0.5) / L  # per grid unit along i
            assert (X3, Y3, Z3) == pytest.approx((16 * vi / L, 0.0, 0.5 * vi / L), **F32)
            assert m3 == pytest.approx(speed3 * (vi - vi_prev) / dt if moving and f else 0.0, **F32)
            assert bp[2 + n][1] == ["set", s, pytest.approx(peaks[n])]
        # plain messages: frame, downs, touches, ups
        downs = [s for s in ids if s not in (want[f - 1][0] if f else [])]
        ups = [s for s in (want[f - 1][0] if f else []) if s not in ids]
        assert plain[0] == ("/fruit/frame", [f + 1, len(ids), pytest.approx(t[3 + f], **F32)])
        addrs = [a for a, _ in plain[1:]]
        assert addrs == ["/fruit/down"] * len(downs) + ["/fruit/touch"] * len(ids) + [
            "/fruit/up"
        ] * len(ups)
        touch_rows = [p for a, p in plain if a == "/fruit/touch"]
        for n, s in enumerate(ids):
            i, j = ij[n]
            assert touch_rows[n][:7] == pytest.approx(
                [s, 16 * i, 12 * j, 0.5 * i, i, j, peaks[n]], **F32
            )
            assert np.isnan(touch_rows[n][7:10]).all() and touch_rows[n][10] == 0
        assert [p[0] for a, p in plain if a == "/fruit/down"] == downs
        assert [p for a, p in plain if a == "/fruit/up"] == [[s] for s in ups]


def test_25dcur_profile_and_plain_messages_through_a_python_osc_server():
    """2.5D: x, y the 2D cursor's, z the height / L; the plain messages carry height,
    strength, size and kind (1: a hover)."""
    taxels = grid_taxels()
    seen = []
    disp = dispatcher.Dispatcher()
    disp.set_default_handler(lambda address, *args: seen.append((address, list(args))))
    server = osc_server.ThreadingOSCUDPServer(("127.0.0.1", 0), disp)
    th = threading.Thread(target=server.serve_forever, daemon=True)
    th.start()
    try:
        tuio = TuioSender(
            server.server_address,
            Normalizer.from_taxels(taxels.i, taxels.j, taxels.xyz_mm),
            "25Dcur",
        )
        tuio.send(
            1.5,
            np.array([7]),
            np.array([True]),
            [3],
            np.array([[2.0, 1.0]]),
            np.array([[32.0, 12.0, 1.0]]),
            np.array([44.0]),
            np.array([[1.5, 0.47, 6.2]]),
            np.array([1]),
        )
        tuio.close()
        import time

        end = time.monotonic() + 5
        while len(seen) < 16 and time.monotonic() < end:
            time.sleep(0.01)
    finally:
        server.shutdown()
        server.server_close()
    by = {}
    for a, p in seen:
        by.setdefault(a, []).append(p)
    src, alive, st, fseq = by["/tuio/25Dcur"]
    assert src[0] == "source" and alive == ["alive", 7] and fseq == ["fseq", 1]
    assert st[:2] == ["set", 7]
    assert st[2:] == pytest.approx([2 / 5, 1 - 1 / 4, 1.5 / 80, 0, 0, 0, 0], **F32)
    assert by["/fruit/frame"] == [[1, 1, 1.5]]
    assert by["/fruit/down"] == by["/fruit/touch"]
    assert by["/fruit/down"][0] == pytest.approx([7, 32, 12, 1, 2, 1, 44, 1.5, 0.47, 6.2, 1], **F32)
    assert by["/fruit/up"] == [[3]]


SCENE = """
[detection]
baseline_frames = 5
"""


def board_taxel_csv(path):
    lines = ["# the whole 21 x 12 board, mm", "id,i,j,x_mm,y_mm,z_mm"]
    for n in range(21 * 12):
        i, j = divmod(n, 12)
        lines.append(f"{n},{i},{j},{16.0 * i},{12.0 * j},0.0")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_fruit_live_osc_end_to_end(tmp_path):
    (tmp_path / "s.toml").write_text(SCENE)
    taxels = board_taxel_csv(tmp_path / "t.csv")
    frames = synthetic_frames(80, seed=5)  # one touch sweeping over frames 20..59
    em = BoardEmulator(frames, fps=0, wait_for_reader=True)
    th = em.start()
    rx = Receiver()
    res = CliRunner().invoke(
        cli,
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            em.path,
            "--taxels",
            str(taxels),
            "--frames",
            "80",
            "--osc",
            f"127.0.0.1:{rx.port}",
        ],
    )
    th.join(5)
    got = rx.close(expect=4 * 75)
    assert res.exit_code == 0, res.output
    assert len(got) == 4 * 75  # one set of bundles per frame after the 5 baseline frames
    twod = got[0::4]
    assert [b[-1][1] for b in twod] == [["fseq", k] for k in range(1, 76)]
    alive = [b[1][1][1:] for b in twod]
    touched = [k for k, a in enumerate(alive) if a]
    assert touched == list(range(15, 55))  # frames 20..59 (after 5 baseline frames)
    assert all(a == [0] for a in (alive[k] for k in touched))  # one session throughout
    xs = [b[2][1][2] for b in (twod[k] for k in touched)]
    assert xs == sorted(xs) and xs[0] < 0.2 and xs[-1] > 0.7  # sweeping along i
    plain = [m for b in got[3::4] for m in b]
    assert [p for a, p in plain if a == "/fruit/down"][0][0] == 0
    assert [p for a, p in plain if a == "/fruit/up"] == [[0]]
    assert "OSC: 300 bundles sent, 0 failed" in res.output


@pytest.mark.parametrize(
    "target, msg",
    [
        (
            "nosuchhost.invalid:9000",
            "--osc nosuchhost.invalid:9000: host 'nosuchhost.invalid' does not resolve",
        ),
        ("127.0.0.1", "--osc 127.0.0.1: expected HOST:PORT with a port in 1-65535"),
        ("127.0.0.1:0", "--osc 127.0.0.1:0: expected HOST:PORT with a port in 1-65535"),
    ],
)
def test_bad_osc_target_is_one_line(tmp_path, target, msg):
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
            "--osc",
            target,
        ],
    )
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1].startswith(f"Error: {msg}")
