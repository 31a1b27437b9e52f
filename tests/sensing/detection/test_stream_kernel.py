"""The live loop's compiled per-frame N9 (`n9_kernel.n9_frame` in `Stream.step`) against
the numpy path it replaced (tests/helpers/stream_reference.py): the same touches to the bit on
random multitouch frames, for every detection option."""

import numpy as np
import pytest

from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.tables import Taxels
from tests.helpers.stream_reference import ReferenceStream
from tests.sensing.detection.test_detect import BASE, make_taxels

FIELDS = ("frame", "touch", "i", "j", "xyz_mm", "peak")


def random_frames(n, rng, taxels, touches=(0, 10)):
    """Frames (n, 21, 12) with a random number of Gaussian touches of random widths,
    noise, integer counts; some touches sit on plateaus (ties) and on the grid's edges."""
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    f = BASE + rng.normal(0, 1.5, (n, 21, 12))
    for k in range(n):
        for _ in range(rng.integers(*touches, endpoint=True)):
            a = rng.uniform(taxels.i.min() - 0.5, taxels.i.max() + 0.5)
            b = rng.uniform(taxels.j.min() - 0.5, taxels.j.max() + 0.5)
            f[k] += rng.uniform(15, 90) * np.exp(
                -((r - a) ** 2 + (c - b) ** 2) / (2 * rng.uniform(0.4, 1.2) ** 2)
            )
    f = np.round(f)
    f[::7, 3, 4] = f[::7, 3, 5] = BASE + 50  # ties of the maximum
    return f.astype(np.int64)


def full_board():
    i, j = np.divmod(np.arange(21 * 12), 12)
    return Taxels(np.arange(i.size), i, j, np.stack([16.0 * j, 12.0 * i, np.sin(i / 3.0)], axis=1))


SETTINGS = [
    {},
    {"method": "n9_floor", "noise_floor_counts": 6.0},
    {"method": "peaks"},
    {"hysteresis_counts": 8.0, "debounce_frames": 2},
    {"drift_rate": 0.01, "track_gate_mm": 20.0},
    {"threshold_counts": 35.0, "max_touches": 4},
]


@pytest.mark.parametrize("kw", SETTINGS)
@pytest.mark.parametrize("board", ["pad", "full"])
def test_compiled_stream_equals_the_numpy_stream_bit_for_bit(kw, board):
    rng = np.random.default_rng(len(str(kw)) + len(board))
    tx = make_taxels() if board == "pad" else full_board()
    t = len(tx)
    states = np.stack([tx.xyz_mm + [0.0, 0.3 * s, 2.0 * s] for s in range(4)])
    press = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 8.0]])
    gains = [None, rng.uniform(0.8, 1.2, t)]
    frames = random_frames(300, rng, tx)
    kpa = np.repeat(rng.uniform(-1, 9, (100, 2)), 3, axis=0)  # unchanged for 3 frames
    found = 0
    for gain in gains:
        for pos, p in ((tx.xyz_mm, None), (states, kpa)):
            loc = Locator(
                tx,
                default_board(),
                pos,
                Settings(baseline_frames=1, **kw),
                None if p is None else press,
                gain=gain,
            )
            base = loc.baseline(frames[:1]) - 0.5
            new, old = Stream(loc, base), ReferenceStream(loc, base)
            for n, values in enumerate(loc.values(frames)):
                kp = None if p is None else p[n]
                a, b = new.step(values, kp, n), old.step(values.copy(), kp, n)
                for f in FIELDS:
                    x, y = getattr(a, f), getattr(b, f)
                    assert x.dtype == y.dtype and x.shape == y.shape, (f, n)
                    assert np.array_equal(x, y), (f, n, x, y)
                found += len(a)
            assert np.array_equal(new.baseline, old.baseline)
    assert found > 1000  # multitouch frames, not empty ones


def test_ascii_fast_path_reads_what_parse_line_reads():
    """Lines through `AsciiDecoder` (compiled fast path for plain digit lines) give the
    frames `parse_line` gives, and the same lines skipped, for plain and odd lines."""
    from fruitcli.sensing.frames.muca import AsciiDecoder
    from fruitcli.sensing.frames.muca_line import parse_line

    rng = np.random.default_rng(11)
    rows, cols = 3, 4
    n = rows * cols

    def plain(v):
        return ",".join(str(x) for x in v)

    lines = []
    for _ in range(300):
        v = rng.integers(0, 70000, n)
        lines.append(plain(v))
    big = rng.integers(0, 70000, n).astype(object)
    big[3] = 10**18 - 1
    lines += [
        plain(big),  # 18 digits: fast path
        plain(big).replace(str(10**18 - 1), str(10**18)),  # 19 digits: parse_line
        plain(big).replace(str(10**18 - 1), "9" * 25),  # out of range
        "007," + plain(range(n - 1)),  # leading zeros
        plain(range(n)) + ",",  # the firmware's trailing comma
        "12.5," + plain(range(n)),  # host timestamp
        "1," + plain(range(n)),  # shifted
        plain(range(n - 1)),  # one field short
        plain(range(n + 2)),  # too many
        " 1," + plain(range(n - 1)) + " ",  # spaces
        "1,," + plain(range(n - 2)),  # empty field: 0
        "-1," + plain(range(n - 1)),  # negative
        "+1," + plain(range(n - 1)),  # sign
        "1e3," + plain(range(n - 1)),
        "[Muca] Gain set to 2",
        "",
        "," * (n - 1),
        plain(range(n)) + "\r\r",
        plain(range(n)).replace(",", ";"),
        "\u00e9" + plain(range(n)),
    ]
    dec = AsciiDecoder(rows, cols)
    data = b"".join(x.encode("utf-8") + b"\r\n" for x in lines)
    got = []
    for a in range(0, len(data), 97):  # chunks that cut lines
        got += dec.feed(data[a : a + 97])
    want = [parse_line(x.rstrip("\r"), n)[0] for x in lines]
    want = [w.reshape(rows, cols) for w in want if w is not None]
    assert len(got) == len(want) and dec.skipped == len(lines) - len(want)
    for a, b in zip(got, want, strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    # read besides the 300 plain lines: 18 and 19 digits, 007, trailing comma, timestamp,
    # spaces, empty field, +1, all fields empty, \r\r
    assert len(want) == 300 + 10


def test_vectorized_tuio_bundles_equal_the_per_touch_encoder_byte_for_byte():
    """`TuioSender.bundles` (numpy over the touches) against the per-touch Python encoder
    it replaced (tests/helpers/tuio_reference.py), on random sessions that start, move, end and
    come back, with repeated and backwards frame times (dt <= 0), heights, strengths,
    sizes and kinds."""
    from fruitcli.sensing.outputs.tuio import Normalizer, TuioSender
    from tests.helpers.tuio_reference import ReferenceTuioSender

    rng = np.random.default_rng(4)
    tx = full_board()
    norm = Normalizer.from_taxels(tx.i, tx.j, tx.xyz_mm)
    for profile in ("3Dcur", "25Dcur"):
        new = TuioSender(("127.0.0.1", 9), norm, profile, source="fruit@test")
        old = ReferenceTuioSender(("127.0.0.1", 9), norm, profile, source="fruit@test")
        alive: list[int] = []
        next_id, t = 0, 0.0
        for _ in range(400):
            t += float(
                rng.choice([0.0, -0.01, 0.0333, 0.1 * rng.random()], p=[0.1, 0.05, 0.6, 0.25])
            )
            keep = [s for s in alive if rng.random() < 0.85]
            ended = sorted(set(alive) - set(keep))
            born = int(rng.integers(0, 3)) if len(keep) < 10 else 0
            ids = np.array(keep + list(range(next_id, next_id + born)), np.int64)
            next_id += born
            is_new = np.array([s >= next_id - born for s in ids], bool)
            n = len(ids)
            ij = np.column_stack([rng.uniform(-1, 21, n), rng.uniform(-1, 12, n)])
            xyz = rng.normal(0, 80, (n, 3))
            peak = rng.uniform(20, 300, n)
            shape = np.column_stack(
                [rng.uniform(0, 4, n), rng.uniform(0, 1.5, n), rng.uniform(4, 9, n)]
            )
            kind = rng.integers(0, 2, n)
            a = new.bundles(t, ids, is_new, ended, ij, xyz, peak, shape, kind)
            b = old.bundles(t, ids, is_new, ended, ij, xyz, peak, shape, kind)
            assert a == b
            alive = ids.tolist()
        assert new.fseq == 400
    empty = np.zeros(0)
    assert new.bundles(
        t,
        empty.astype(np.int64),
        empty.astype(bool),
        [3],
        np.zeros((0, 2)),
        np.zeros((0, 3)),
        empty,
    ) == old.bundles(
        t,
        empty.astype(np.int64),
        empty.astype(bool),
        [3],
        np.zeros((0, 2)),
        np.zeros((0, 3)),
        empty,
    )


def test_nearest_partner_sessions_equal_the_assignment_solver():
    """`SessionTracker` with its compiled nearest-partner path against the solver alone,
    on random fingers that move, appear, vanish and come close to each other (where the
    solver must decide): the same ids, new flags and ended sessions every frame."""
    from fruitcli.sensing.detection.sessions import SessionTracker

    rng = np.random.default_rng(8)
    fast, slow = SessionTracker(20.0), SessionTracker(20.0)
    slow.fast = False
    decided = []
    nearest = fast._nearest
    fast._nearest = lambda *a: decided.append(nearest(*a)) or decided[-1]  # -1: undecided
    fingers = rng.uniform(0, 200, (6, 3))
    for _ in range(3000):
        fingers += rng.normal(0, 4.0, fingers.shape)
        if rng.random() < 0.05:  # two fingers almost on top of each other
            fingers[1] = fingers[0] + rng.normal(0, 0.5, 3)
        if rng.random() < 0.03:
            fingers[rng.integers(6)] = rng.uniform(0, 200, 3)  # a jump: a new session
        on = rng.random(6) < 0.8
        xyz = fingers[on][rng.permutation(int(on.sum()))]
        a, b = fast.update(xyz), slow.update(xyz)
        assert np.array_equal(a.ids, b.ids) and np.array_equal(a.new, b.new)
        assert a.ended == b.ended
    undecided = decided.count(-1)
    assert 0 < undecided < len(decided) - undecided  # both paths ran
