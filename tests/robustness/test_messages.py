"""Messages that name the input, not a consequence: ids beyond an integer, a binary STL
whose header lies, counts beyond the board's range, a long value cut to a readable line."""

import struct

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli, main
from fruitcli.errors import FrameError, FruitError, echo, one_line


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def last_line(res) -> str:
    return res.output.strip().splitlines()[-1]


def test_sample_ids_beyond_an_exact_integer_name_the_column(tmp_path):
    truth = tmp_path / "t.csv"
    truth.write_text("sample,x_mm,y_mm\n1e20,0,0\n2e20,1,1\n3e20,2,2\n")
    res = run("evaluate", "--truth", truth, "--measured", truth, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res) == (
        f"Error: {truth}: data row 1: column sample: expected an integer within "
        "+-9007199254740992 (2^53, exact in a CSV), got 1e+20"
    )


def test_taxel_ids_beyond_an_exact_integer_name_the_column(tmp_path):
    from fruitcli.tables import read_taxels

    path = tmp_path / "taxels.csv"
    path.write_text("id,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,0\n1,1,0,16,0,0\n2,1e19,1,0,12,0\n")
    with pytest.raises(FruitError) as err:
        read_taxels(path)
    assert str(err.value) == (
        f"{path}: data row 3: column i: expected an integer within +-9007199254740992 "
        "(2^53, exact in a CSV), got 1e+19"
    )


@pytest.mark.parametrize("count", [0, 1000])
def test_a_binary_stl_whose_header_count_is_wrong_says_so(tmp_path, count):
    import trimesh

    data = trimesh.exchange.stl.export_stl(trimesh.creation.box([10.0, 10.0, 10.0]))
    path = tmp_path / "lie.stl"
    path.write_bytes(data[:80] + struct.pack("<I", count) + data[84:])
    res = run("make-tracks", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res) == (
        f"Error: {path}: binary STL header says {count:,} triangles "
        f"({84 + 50 * count:,} bytes), the file has 684 bytes (room for 12): truncated, "
        "or its header's count is wrong"
    )
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "frames, got",
    [
        (np.full((2, 3, 4), 5e32), "5e+32"),
        (np.full((2, 3, 4), 2**63, np.uint64), "9223372036854775808"),
        (np.full((2, 3, 4), 70_000, np.int32), "70000"),
    ],
)
def test_counts_beyond_the_boards_range_name_the_file(frames, got):
    from fruitcli.sensing.frames.recording import check_frames

    with pytest.raises(FrameError) as err:
        check_frames(frames, "rec.npz")
    assert str(err.value) == (
        f"rec.npz: frame 0: count {got} beyond the board's range (expected counts 0 to 65535)"
    )


def test_an_ascii_count_beyond_64_bits_says_the_boards_range():
    from fruitcli.sensing.frames.muca_line import parse_line

    counts, _, why = parse_line("1,2," + "9" * 30 + ",4", 4)
    assert counts is None and why == "value: field 3: count beyond the board's range (0 to 65535)"


def test_a_value_echoed_is_cut():
    assert echo("x" * 10) == repr("x" * 10)
    cut = echo(list(range(10**5)))
    assert len(cut) == 80 and cut.startswith("[0, 1, 2") and cut.endswith("…")
    line = one_line("a.toml: [k]: " + "y" * 10**6 + " expected z")
    assert len(line) == 2000 and line.startswith("a.toml: [k]: ") and line.endswith("expected z")


def test_a_huge_value_in_a_scene_is_one_short_line(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text("[scene]\nname = " + '"' + "n" * 5_000_000 + '/"\n')
    with pytest.raises(SystemExit) as done:
        main(["run", str(path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert done.value.code == 1 and err.count("\n") == 1 and len(err) < 250
    assert err.startswith("Error: s.toml: [scene].name: expected a plain folder name")
