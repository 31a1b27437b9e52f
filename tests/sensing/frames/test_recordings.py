"""Recording formats (npz, MuCa ASCII log) round trips, and `fruit locate` end to end."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.sensing.frames.recording import (
    Recording,
    parse_line,
    read_muca_log,
    read_npz,
    read_recording,
    write_muca_log,
    write_npz,
)
from fruitcli.tables import read_table, read_taxels


def rec(n=12, seed=0, pressure=False, sample=False):
    rng = np.random.default_rng(seed)
    frames = rng.integers(0, 1000, size=(n, 21, 12))
    t = np.cumsum(rng.uniform(0.01, 0.02, n)) + 1e5 / 3
    r = Recording(frames, t, meta={"board": "muca", "state": 0})
    if pressure:
        r.pressure_kpa = rng.uniform(0, 5, (n, 2))
        r.chamber_names = ("left", "right")
    if sample:
        r.sample = np.where(np.arange(n) % 4 == 3, np.arange(n) // 4, -1)
    return r


def test_npz_round_trip_exact(tmp_path):
    r = rec(pressure=True, sample=True)
    write_npz(tmp_path / "a.npz", r)
    back = read_npz(tmp_path / "a.npz")
    assert np.array_equal(back.frames, r.frames) and back.frames.dtype == np.int64
    assert np.array_equal(back.t_s, r.t_s)
    assert np.array_equal(back.pressure_kpa, r.pressure_kpa)
    assert back.chamber_names == ("left", "right")
    assert np.array_equal(back.sample, r.sample)
    assert back.meta == r.meta


def test_npz_round_trip_of_bench_positions_and_pressure_times(tmp_path):
    r = rec(pressure=True, sample=True)
    r.printer_mm = np.random.default_rng(1).uniform(0, 220, (12, 3))
    r.pressure_t_s = np.r_[np.nan, np.cumsum(np.full(11, 0.013))]
    write_npz(tmp_path / "a.npz", r)
    back = read_npz(tmp_path / "a.npz")
    assert np.array_equal(back.printer_mm, r.printer_mm)
    assert np.array_equal(back.pressure_t_s, r.pressure_t_s, equal_nan=True)
    np.savez(tmp_path / "b.npz", frames=r.frames, t_s=r.t_s, printer_mm=np.zeros((3, 3)))
    with pytest.raises(FrameError, match=r"b\.npz: printer_mm: expected \(12, 3\) finite mm"):
        read_npz(tmp_path / "b.npz")


def test_log_round_trip_exact(tmp_path):
    r = rec()
    write_muca_log(tmp_path / "a.log", r)
    back = read_muca_log(tmp_path / "a.log")
    assert np.array_equal(back.frames, r.frames) and np.array_equal(back.t_s, r.t_s)
    write_muca_log(tmp_path / "b.log", r, timestamps=False)
    back = read_recording(tmp_path / "b.log")
    assert np.array_equal(back.frames, r.frames)
    assert np.array_equal(back.t_s, np.arange(12.0))


def test_log_skips_board_lines_and_cut_lines_and_reads_empty_fields_as_zero(tmp_path):
    vals = np.arange(252) % 7
    line = ",".join("" if v == 0 else str(v) for v in vals)
    text = (
        "\r\n".join(
            [
                "[Muca] Set TEST mode",
                "[Muca] Gain set to 10",
                line,
                line[: len(line) // 2],
                "Calibration performed 3/20",
                line,
            ]
        )
        + "\r\n"
    )
    (tmp_path / "a.log").write_text(text)
    back = read_muca_log(tmp_path / "a.log")
    assert back.skipped_lines == 4 and len(back) == 2
    assert np.array_equal(back.frames[0].ravel(), vals)
    assert back.frames[0, 1, 0] == vals[12]  # value k is Tx k // 12, Rx k % 12


@pytest.mark.parametrize(
    "bad, msg",
    [
        ("x", "line 2: field 5: expected an integer count, got 'x'"),
        ("-3", "line 2: field 5: negative count -3"),
        ("nan", "line 2: field 5: expected an integer count, got 'nan'"),
        ("1.5", "line 2: field 5: expected an integer count, got '1.5'"),
    ],
)
def test_log_bad_values_in_a_file_are_errors(tmp_path, bad, msg):
    fields = ["1"] * 252
    fields[4] = bad
    (tmp_path / "a.log").write_text("[Muca] hi\n" + ",".join(fields) + "\n")
    with pytest.raises(FrameError, match=msg.replace("(", r"\(").replace(")", r"\)")):
        read_muca_log(tmp_path / "a.log")
    assert parse_line(",".join(fields), 252)[0] is None  # live: skipped


def test_npz_bad_inputs(tmp_path):
    p = tmp_path / "a.npz"
    np.savez(p, frames=np.zeros((0, 21, 12), int), t_s=np.zeros(0))
    with pytest.raises(FrameError, match="empty recording"):
        read_npz(p)
    f = np.zeros((2, 21, 12))
    f[1, 3, 3] = np.nan
    np.savez(p, frames=f, t_s=np.zeros(2))
    with pytest.raises(FrameError, match="frame 1: NaN"):
        read_npz(p)
    np.savez(p, frames=-np.ones((2, 21, 12), int), t_s=np.zeros(2))
    with pytest.raises(FrameError, match="frame 0: negative count"):
        read_npz(p)
    np.savez(p, frames=np.ones((2, 21), int), t_s=np.zeros(2))
    with pytest.raises(FrameError, match=r"expected shape \(N, rows, cols\)"):
        read_npz(p)
    np.savez(p, frames=np.ones((2, 21, 12), int), t_s=np.zeros(3))
    with pytest.raises(FrameError, match="t_s: expected 2 finite times"):
        read_npz(p)


def write_taxels(path, rows=4, cols=5, shift_i=0):
    lines = ["# taxels, mm", "id,i,j,x_mm,y_mm,z_mm"]
    k = 0
    for i in range(rows):
        for j in range(cols):
            lines.append(f"{k},{i + shift_i},{j},{16.0 * j},{12.0 * i},{1.0 * i}")
            k += 1
    path.write_text("\n".join(lines) + "\n")
    return path


def touch_recording(n_base=10):
    frames = np.full((n_base + 3, 21, 12), 400, dtype=np.int64)
    frames[n_base, 1, 2] += 60
    frames[n_base, 1, 3] += 20
    frames[n_base + 2, 2, 2] += 25
    return Recording(
        frames, np.arange(n_base + 3) * 0.1, sample=np.r_[-np.ones(n_base, int), 0, -1, 1], meta={}
    )


def test_locate_cli_writes_touches_and_measured(tmp_path):
    write_npz(tmp_path / "f.npz", touch_recording())
    write_taxels(tmp_path / "t.csv")
    res = CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "f.npz"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 0, res.output
    t = read_table(
        tmp_path / "o" / "touches.csv",
        ["frame", "t_s", "touch", "i", "j", "x_mm", "y_mm", "z_mm", "peak"],
    )
    assert t["frame"].tolist() == [10, 12]
    assert t["j"][0] == pytest.approx(2.25) and t["x_mm"][0] == pytest.approx(36.0)
    assert t["peak"].tolist() == [60, 25]
    m = read_table(tmp_path / "o" / "measured.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    assert m["sample"].tolist() == [0, 1] and m["y_mm"].tolist() == [12.0, 24.0]


def test_locate_cli_reads_a_log_with_same_result(tmp_path):
    write_muca_log(tmp_path / "f.log", touch_recording())
    write_taxels(tmp_path / "t.csv")
    res = CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "f.log"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 0, res.output
    t = read_table(tmp_path / "o" / "touches.csv", ["frame", "i", "j"])
    assert t["frame"].tolist() == [10, 12]


@pytest.mark.parametrize(
    "case, msg",
    [
        ("few", "13 frames, fewer than the 20 baseline frames"),
        ("outside", "maps to frame cell (21, 0), outside the 21 x 12 frame"),
        ("shape", "frames of shape (20, 12), expected 21 x 12 per [board]"),
        ("fields", "line 1: field 3: expected an integer count, got 'a'"),
        ("missing", "file not found"),
    ],
)
def test_locate_cli_bad_input_one_line_exit_1(tmp_path, case, msg):
    write_npz(tmp_path / "f.npz", touch_recording())
    write_taxels(tmp_path / "t.csv", shift_i=18 if case == "outside" else 0)
    frames = tmp_path / "f.npz"
    args = []
    if case == "few":
        args = ["--baseline-frames", "20"]
    if case == "shape":
        r = touch_recording()
        r.frames = r.frames[:, :20]
        write_npz(frames, r)
    if case == "fields":
        frames = tmp_path / "f.log"
        frames.write_text("1,2,a" + ",0" * 249 + "\n")
    if case == "missing":
        frames = tmp_path / "nope.npz"
    res = CliRunner().invoke(
        cli,
        [
            "locate",
            str(frames),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--out",
            str(tmp_path / "o"),
            *args,
        ],
    )
    assert res.exit_code == 1
    assert msg in res.output and "Traceback" not in res.output
    errors = [ln for ln in res.output.splitlines() if ln.startswith("Error: ")]
    assert len(errors) == 1 and msg in errors[0]


def test_locate_cli_bad_flag_exit_2(tmp_path):
    res = CliRunner().invoke(
        cli, ["locate", "f.npz", "--taxels", "t.csv", "--out", "o", "--threshold", "-1"]
    )
    assert res.exit_code == 2


def test_meta_is_json(tmp_path):
    write_npz(tmp_path / "f.npz", rec())
    with np.load(tmp_path / "f.npz", allow_pickle=False) as z:
        assert json.loads(str(z["meta"]))["board"] == "muca"


def test_taxels_with_a_duplicate_id_are_refused(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("id,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,0\n1,0,1,0,1,0\n0,1,0,1,0,0\n")
    with pytest.raises(
        FrameError,
        match=r"t\.csv: data row 3: duplicate taxel id 0 "
        r"\(also on data row 1\)",
    ):
        read_taxels(path, FrameError)


def test_emulate_board_refuses_frames_larger_than_21_by_12(tmp_path):
    r = rec()
    r.frames = np.concatenate([r.frames, r.frames[:, :1]], axis=1)
    write_npz(tmp_path / "f.npz", r)
    res = CliRunner().invoke(cli, ["emulate-board", "--from", str(tmp_path / "f.npz")])
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert (
        "f.npz: frames of 22 x 12, expected at most 21 x 12 (the MuCa board's Tx x Rx" in res.output
    )
