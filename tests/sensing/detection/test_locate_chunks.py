"""`fruit locate` in chunks writes touches.csv byte for byte as the whole-recording batch
path in its first form did (tests/helpers/locate_reference.py), on varied recordings: multitouch,
no touch, ties, edges and holes in the taxel grid, boards that flip or transpose,
pressures along FEM states, every detection method and chunk sizes down to one frame."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.errors import FrameError
from fruitcli.scene import default_scene
from fruitcli.sensing.frames.board import taxel_cells
from fruitcli.sensing.frames.recording import Recording, write_muca_log, write_npz
from fruitcli.sensing.outputs.csv_rows import format_rows
from fruitcli.tables import read_taxels
from tests.helpers.locate import locate_scene
from tests.helpers.locate_reference import locate as reference_locate
from tests.helpers.locate_reference import touches_csv_text

R, C = 21, 12
BASE = 500


def scene(board=None, detection=None):
    """A scene at the schema's defaults with these [board] and [detection] values."""
    return default_scene().with_values(
        {f"board.{k}": v for k, v in (board or {}).items()}
        | {f"detection.{k}": v for k, v in (detection or {}).items()}
    )


def write_taxels(path, ij, seed=0):
    """Taxel CSV for grid cells `ij` in a shuffled file order (ids not in cell order)."""
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(ij))
    lines = ["id,i,j,x_mm,y_mm,z_mm"]
    for k in order:
        i, j = ij[k]
        lines.append(f"{100 + k},{i},{j},{16.0 * j + 0.1 * i},{12.0 * i},{3 * np.sin(i / 2 + j)}")
    path.write_text("\n".join(lines) + "\n")
    return path


def full_grid(rows=R, cols=C, holes=()):
    return [(i, j) for i in range(rows) for j in range(cols) if (i, j) not in holes]


def touch_frames(n, rng, max_touches=4, n_base=10, amp=(10, 90), noisy_base=False):
    """n frames of 21 x 12 counts: a flat (or noisy) baseline, 0..max_touches blobs per
    frame anywhere (edges included), some exact ties and plateaus of integer counts."""
    r, c = np.meshgrid(np.arange(R), np.arange(C), indexing="ij")
    f = np.full((n, R, C), float(BASE))
    if noisy_base:
        f += rng.normal(0, 2.0, f.shape)
    for _ in range(max_touches):
        on = rng.random(n) < 0.6
        on[:n_base] = False
        ci, cj = rng.uniform(-1, R, n), rng.uniform(-1, C, n)
        a = rng.uniform(*amp, n)
        f += (
            on[:, None, None]
            * a[:, None, None]
            * np.exp(-((r - ci[:, None, None]) ** 2 + (c - cj[:, None, None]) ** 2) / 1.1)
        )
    f = np.round(f).astype(np.int64)
    tie = rng.random(n) < 0.1  # two equal maxima far apart
    tie[:n_base] = False
    f[tie, 3, 3] = BASE + 95
    f[tie, 15, 8] = BASE + 95
    plateau = rng.random(n) < 0.05
    plateau[:n_base] = False
    f[plateau, 10, 0:3] = BASE + 97
    exact = rng.random(n) < 0.05  # exactly the threshold: no touch (strict >)
    exact[:n_base] = False
    f[exact, 19, 11] = BASE + 20
    return np.maximum(f, 0)


def reference_csv(
    frames,
    t_s,
    taxels_csv,
    board,
    det,
    positions=None,
    pressure=None,
    state_pressure=None,
    name="f.npz",
):
    tx = read_taxels(taxels_csv)
    rows, cols = taxel_cells(tx, board)
    table = reference_locate(
        frames,
        t_s,
        tx.i,
        tx.j,
        rows,
        cols,
        tx.xyz_mm if positions is None else positions,
        det.threshold_counts,
        det.baseline_frames,
        det.method,
        det.noise_floor_counts,
        10,
        pressure,
        state_pressure,
    )
    comment = (
        f"touches of {name}: frame index from 0 (baseline frames included), t_s in s, "
        "i, j fractional grid coordinates, x_mm, y_mm, z_mm in mm, peak in counts"
    )
    return touches_csv_text(table, t_s, comment).encode(), table


def paper_columns(data: bytes) -> bytes:
    """touches.csv cut to the reference's columns (frame .. peak) and comment."""
    lines = []
    for line in data.decode().splitlines():
        if line.startswith("#"):
            lines.append(line.split(", height_mm")[0])
        else:
            lines.append(",".join(line.split(",")[:9]))
    return ("\n".join(lines) + "\n").encode()


def located(tmp_path, sc, frames_path, taxels_csv, states=None, chunk=None, out="o"):
    kw = {} if chunk is None else {"chunk_frames": chunk}
    res = locate_scene(sc, frames_path, taxels_csv, states, tmp_path / out, **kw)
    return paper_columns((tmp_path / out / "touches.csv").read_bytes()), res


@pytest.mark.parametrize("method", ["n9", "n9_floor", "peaks"])
def test_chunks_write_the_reference_bytes_for_every_method(tmp_path, method):
    rng = np.random.default_rng(1)
    frames = touch_frames(700, rng, noisy_base=True)
    t_s = 1.7e9 + np.arange(700) / 97.0  # host timestamps: ten digits before the point
    write_npz(tmp_path / "f.npz", Recording(frames, t_s))
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    sc = scene(detection={"method": method, "noise_floor_counts": 4.0})
    want, table = reference_csv(frames, t_s, taxels, sc.board, sc.detection)
    assert len(table[0]) > 700  # multitouch: more touches than frames
    for chunk in (1, 7, 64, 5000):
        got, res = located(tmp_path, sc, tmp_path / "f.npz", taxels, chunk=chunk)
        assert got == want, f"chunk {chunk}"
        assert res["touches"] == len(table[0])


@pytest.mark.parametrize(
    "size, board",
    [
        ((21, 12), {}),  # most cells, in grid order: detection on the frames' own cells
        ((19, 11), {"offset_i": 2, "offset_j": 1}),
        ((12, 7), {}),  # fewer cells: the taxels' counts are taken out
        ((12, 7), {"flip_i": True}),  # not in grid order: taken out
        ((12, 7), {"transpose": True, "flip_j": True}),
    ],
)
def test_holes_offsets_flips_and_transposes(tmp_path, size, board):
    rng = np.random.default_rng(2)
    ij = full_grid(*size, holes={(0, 0), (5, 3), (5, 4), (11, 6), (6, 0)})
    if board.get("transpose"):
        ij = [(j, i) for i, j in ij]  # i runs along the frame's columns
    frames = touch_frames(400, rng, max_touches=3)
    t_s = np.arange(400) * 0.01
    write_npz(tmp_path / "f.npz", Recording(frames, t_s))
    taxels = write_taxels(tmp_path / "t.csv", ij, seed=3)
    sc = scene(board=board)
    want, _ = reference_csv(frames, t_s, taxels, sc.board, sc.detection)
    for chunk in (3, 4096):
        got, _ = located(tmp_path, sc, tmp_path / "f.npz", taxels, chunk=chunk)
        assert got == want


def test_no_touch_gives_the_header_only(tmp_path):
    frames = np.full((50, R, C), BASE, np.int64)
    frames[20:, 4, 4] = BASE + 20  # at the threshold, not above it
    frames[30:, 5, 5] = BASE - 300  # below the baseline: clipped at 0
    write_npz(tmp_path / "f.npz", Recording(frames, np.arange(50) * 0.1))
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    sc = scene()
    want, table = reference_csv(frames, np.arange(50) * 0.1, taxels, sc.board, sc.detection)
    got, res = located(tmp_path, sc, tmp_path / "f.npz", taxels, chunk=16)
    assert got == want and res["touches"] == 0 and len(table[0]) == 0
    assert got.count(b"\n") == 2  # the comment and the header


def states_npz(path, taxels_mm, n_states=4):
    """A states.npz with taxels moving along a two-chamber pressure path (mm, kPa)."""
    t = taxels_mm.shape[0]
    lift = np.array([[0, 0, 0], [0.4, 0, 2.0], [0.4, 1.1, 5.0], [0, 2.0, 9.0]])[:n_states]
    tax = taxels_mm[None] + lift[:, None, :] * (1 + taxels_mm[None, :, :1] / 100)
    nodes = taxels_mm[:4]
    np.savez(
        path,
        rest_nodes=nodes,
        tets=np.array([[0, 1, 2, 3]]),
        surface_tris=np.array([[0, 1, 2]]),
        displacement_mm=np.zeros((n_states, 4, 3)),
        pressure_kpa=np.array([[0, 0], [5.0, 0], [5.0, 3.0], [9.0, 6.0]])[:n_states],
        chamber_names=np.array(["left", "right"]),
        taxels_mm=tax,
        taxel_tet=np.zeros(t, np.int64),
        taxel_bary=np.full((t, 4), 0.25),
    )
    return path, tax


def test_pressures_move_the_taxels_along_the_states_as_before(tmp_path):
    rng = np.random.default_rng(4)
    frames = touch_frames(600, rng, noisy_base=True)
    t_s = np.arange(600) / 30.0
    kpa = np.column_stack([rng.uniform(-2, 11, 600), rng.uniform(-1, 7, 600)])
    # the recording names its chambers in another order than the states
    write_npz(tmp_path / "f.npz", Recording(frames, t_s, kpa[:, ::-1], ("right", "left")))
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    tx = read_taxels(taxels)
    states, positions = states_npz(tmp_path / "s.npz", tx.xyz_mm)
    sc = scene()
    want, _ = reference_csv(
        frames,
        t_s,
        taxels,
        sc.board,
        sc.detection,
        positions,
        kpa,
        np.array([[0, 0], [5.0, 0], [5.0, 3.0], [9.0, 6.0]]),
    )
    for chunk in (5, 256):
        got, _ = located(tmp_path, sc, tmp_path / "f.npz", taxels, states, chunk=chunk)
        assert got == want


def test_stateful_settings_carry_their_state_across_chunks(tmp_path):
    rng = np.random.default_rng(5)
    frames = touch_frames(300, rng, max_touches=2, noisy_base=True)
    write_npz(tmp_path / "f.npz", Recording(frames, np.arange(300) * 0.02))
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    sc = scene(
        detection={
            "hysteresis_counts": 6.0,
            "debounce_frames": 2,
            "drift_rate": 0.05,
            "track_gate_mm": 30.0,
        }
    )
    whole, res = located(tmp_path, sc, tmp_path / "f.npz", taxels, chunk=10_000, out="w")
    assert res["touches"] > 100
    for chunk in (1, 9):
        got, _ = located(tmp_path, sc, tmp_path / "f.npz", taxels, chunk=chunk)
        assert got == whole


def test_compressed_unsigned_and_float_npz_and_a_log_give_the_same_bytes(tmp_path):
    rng = np.random.default_rng(6)
    frames = touch_frames(300, rng)
    t_s = np.arange(300) * 0.05
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    write_npz(tmp_path / "f.npz", Recording(frames, t_s))
    want, _ = located(tmp_path, scene(), tmp_path / "f.npz", taxels, chunk=32, out="a")
    np.savez_compressed(tmp_path / "c.npz", frames=frames.astype(np.uint16), t_s=t_s)
    np.savez(tmp_path / "d.npz", frames=frames.astype(np.float32), t_s=t_s)
    write_muca_log(tmp_path / "f.log", Recording(frames, t_s))
    for name in ("c.npz", "d.npz", "f.log"):
        got, _ = located(tmp_path, scene(), tmp_path / name, taxels, chunk=32, out="o" + name)
        head, rows = want.split(b"\n", 1)
        assert got == head.replace(b"f.npz", name.encode()) + b"\n" + rows


def test_a_bad_count_late_in_the_recording_names_its_frame_and_writes_nothing(tmp_path):
    frames = np.full((100, R, C), BASE, np.int64)
    frames[40:, 3, 3] += 50
    frames[77, 2, 2] = -3
    write_npz(tmp_path / "f.npz", Recording(np.abs(frames), np.arange(100) * 0.1))
    np.savez(tmp_path / "f.npz", frames=frames, t_s=np.arange(100) * 0.1)
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    with pytest.raises(FrameError, match=r"f.npz: frame 77: negative count"):
        locate_scene(scene(), tmp_path / "f.npz", taxels, None, tmp_path / "o", chunk_frames=16)
    assert not (tmp_path / "o" / "touches.csv").exists()
    assert list((tmp_path / "o").glob("*")) == []  # no temporary file left either
    frames[77, 2, 2] = BASE
    np.savez(tmp_path / "g.npz", frames=frames.astype(float) + 0.5, t_s=np.arange(100) * 0.1)
    with pytest.raises(FrameError, match=r"g.npz: frame 0: non-integer count"):
        locate_scene(scene(), tmp_path / "g.npz", taxels, None, tmp_path / "o", chunk_frames=16)


def test_a_truncated_npz_is_one_error_line(tmp_path):
    frames = np.full((400, R, C), BASE, np.int64)
    write_npz(tmp_path / "f.npz", Recording(frames, np.arange(400) * 0.1))
    data = (tmp_path / "f.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    with pytest.raises(FrameError, match=r"cut.npz: not a readable .npz recording"):
        locate_scene(scene(), tmp_path / "cut.npz", taxels, None, tmp_path / "o")
    rng = np.random.default_rng(8)
    np.savez_compressed(
        tmp_path / "z.npz", frames=rng.integers(0, 900, (400, R, C)), t_s=np.arange(400) * 0.1
    )
    data = bytearray((tmp_path / "z.npz").read_bytes())
    data[len(data) // 3 : len(data) // 3 + 64] = bytes(64)  # inside the compressed frames
    (tmp_path / "z.npz").write_bytes(bytes(data))
    with pytest.raises(FrameError, match=r"z\.npz: "):  # bad data, a bad CRC or zlib error
        locate_scene(scene(), tmp_path / "z.npz", taxels, None, tmp_path / "o", chunk_frames=16)
    assert not (tmp_path / "o" / "touches.csv").exists()
    np.savez(tmp_path / "obj.npz", frames=np.array([None, 1], dtype=object), t_s=np.zeros(2))
    with pytest.raises(FrameError, match=r"obj.npz: not a readable .npz recording"):
        locate_scene(scene(), tmp_path / "obj.npz", taxels, None, tmp_path / "o")


def python_rows(columns, kinds):
    return "".join(
        ",".join(
            str(int(c[r])) if k == "d" else f"{float(c[r]):.6f}"
            for c, k in zip(columns, kinds, strict=True)
        )
        + "\n"
        for r in range(len(columns[0]))
    ).encode()


def test_bulk_rows_equal_python_formatting_on_ties_and_extremes():
    rng = np.random.default_rng(7)
    n = 20_000
    special = np.array(
        [
            0.0,
            -0.0,
            np.nan,
            np.inf,
            -np.inf,
            1e300,
            -1e-300,
            5e-324,
            0.5e-6,
            1.5e-6,
            2.5e-6,
            -2.5e-6,
            0.9999995,
            999999.9999995,
            4503599627.370496,
            4503599627.370495,
            0.0078125,
            1 / 3,
        ]
    )
    pools = [
        rng.uniform(-1e3, 1e3, n),
        rng.normal(0, 1e-5, n),
        rng.integers(-(10**6), 10**6, n) / 128,  # exact binary ties of the sixth decimal
        (rng.integers(0, 10**7, n) + 0.5) / 1e6,  # near ties
        rng.uniform(1e9, 5e9, n),
        10.0 ** rng.uniform(-12, 15, n) * rng.choice([-1, 1], n),
    ]
    vals = np.concatenate(pools + [special])
    rng.shuffle(vals)
    m = vals.size // 3
    cols = [
        rng.integers(-5, 10**9, m),
        vals[:m],
        vals[m : 2 * m],
        rng.integers(0, 12, m),
        vals[2 * m : 3 * m],
    ]
    assert format_rows(cols, "dffdf") == python_rows(cols, "dffdf")
    assert format_rows([np.array([7]), np.array([2.5])], "df") == b"7,2.500000\n"
    assert format_rows([np.zeros(0)], "f") == b""


def test_bulk_rows_write_words_and_non_finite_floats_as_python_does():
    rng = np.random.default_rng(8)
    n = 5000
    x = rng.uniform(-50, 50, n)
    x[rng.random(n) < 0.2] = np.nan
    x[rng.random(n) < 0.05] = np.inf
    x[rng.random(n) < 0.05] = -np.inf
    x[rng.random(n) < 0.05] = -np.nan
    kind = rng.integers(0, 3, n)
    words = ("touch", "hover", "a-longer-word-than-any-number-field")
    cols = [rng.integers(-5, 10**6, n), x, kind, rng.uniform(0, 1, n)]
    want = "".join(
        f"{cols[0][r]},{float(x[r]):.6f},{words[kind[r]]},{cols[3][r]:.6f}\n" for r in range(n)
    ).encode()
    assert format_rows(cols, "dfsf", words) == want
    assert format_rows([np.array([np.nan]), np.array([-np.inf])], "ff") == b"nan,-inf\n"
    for bad in (2, -1):
        with pytest.raises(IndexError, match="word index"):
            format_rows([np.array([0, bad])], "s", ("touch", "hover"))
