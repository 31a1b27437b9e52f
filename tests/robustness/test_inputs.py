"""Inputs a user gets wrong: each is one `Error:` line naming the file and what was
expected, exit 1, nothing written; or a correct result where the input is valid."""

import zipfile

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from tests.conftest import PAPER


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def last_line(res):
    return res.output.strip().splitlines()[-1]


def assert_one_line(res, start):
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output and not isinstance(res.exception, AssertionError)
    assert last_line(res).startswith(start), res.output


def test_evaluate_refuses_a_duplicated_header_column(tmp_path):
    measured = tmp_path / "m.csv"
    measured.write_text("sample,x_mm,y_mm,x_mm\n0,1,2,3\n1,2,3,4\n")
    res = run(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        measured,
        "--out",
        tmp_path / "o",
    )
    assert_one_line(res, f"Error: {measured}: row 1: column(s) x_mm appear more than once")
    assert not (tmp_path / "o").exists()


def test_locate_refuses_a_duplicated_taxel_column(tmp_path):
    taxels = tmp_path / "t.csv"
    taxels.write_text("id,i,j,x_mm,y_mm,z_mm,id\n0,0,0,0,0,0,0\n")
    frames = tmp_path / "f.log"
    frames.write_text("")
    res = run("locate", frames, "--taxels", taxels, "--out", tmp_path / "o")
    assert_one_line(res, f"Error: {taxels}: row 1: column(s) id appear more than once")


def test_pressures_with_a_duplicated_column_are_refused(tmp_path):
    from fruitcli.errors import FruitError
    from fruitcli.fem.pressure_table import read_pressures

    path = tmp_path / "p.csv"
    path.write_text("c1_kpa,c1_kpa\n1,2\n")
    try:
        read_pressures(path, ["c1"])
    except FruitError as exc:
        assert str(exc).startswith(f"{path}: row 1: column(s) c1_kpa appear more than once")
    else:
        raise AssertionError("accepted")


def test_reference_length_is_the_diameter_without_all_pairs():
    from scipy.spatial.distance import pdist

    from fruitcli.evaluation.metrics import reference_length

    rng = np.random.default_rng(1)
    sets = [
        rng.normal(size=(500, 3)),
        np.c_[rng.normal(size=(500, 2)), np.zeros(500)],
        np.outer(rng.normal(size=500), [1.0, 2.0, 2.0]),
        rng.normal(size=(500, 2)),
    ]
    for pts in sets:
        assert abs(reference_length(pts) - pdist(pts).max()) < 1e-9
    # 400,000 points in the unit cube and two opposite corners: the diameter is sqrt(3)
    cube = np.r_[rng.uniform(0.01, 0.99, (400_000, 3)), [[0, 0, 0], [1, 1, 1]]]
    assert abs(reference_length(cube) - np.sqrt(3)) < 1e-12


def test_plots_of_many_pairs_show_an_evenly_spaced_subset():
    import matplotlib.pyplot as plt

    from fruitcli.evaluation.plots import PLOT_MAX_PAIRS, pairs

    truth = np.c_[np.arange(3 * PLOT_MAX_PAIRS, dtype=float), np.zeros(3 * PLOT_MAX_PAIRS)]
    fig, ax = plt.subplots()
    pairs(ax, truth, truth + 1.0, title="t")
    assert len(ax.collections[0].get_segments()) == PLOT_MAX_PAIRS
    assert ax.get_title() == f"t ({PLOT_MAX_PAIRS} of {3 * PLOT_MAX_PAIRS} pairs)"
    plt.close(fig)


def flip_a_bit_in_member(path, member):
    """Flip one bit of `member`'s stored bytes (a stored, uncompressed npz)."""
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(member)
    data = bytearray(path.read_bytes())
    at = info.header_offset + 30 + len(info.filename) + len(info.extra) + info.file_size - 3
    data[at] ^= 0x02
    path.write_bytes(bytes(data))


def test_npz_with_a_bad_crc_is_refused(tmp_path):
    from fruitcli.errors import FrameError, FruitError
    from fruitcli.sensing.frames.recording_chunks import open_recording
    from fruitcli.tables import read_npz_arrays

    path = tmp_path / "rec.npz"
    np.savez(path, frames=np.zeros((4, 21, 12), np.uint16), t_s=np.arange(4.0))
    assert read_npz_arrays(path, "recording")["frames"].shape == (4, 21, 12)
    flip_a_bit_in_member(path, "frames.npy")
    for call, error in (
        (lambda: read_npz_arrays(path, ".npz recording"), FruitError),
        (lambda: open_recording(path), FrameError),
    ):
        try:
            call()
        except error as exc:
            assert str(exc) == (
                f"{path}: not a readable .npz recording: member frames.npy "
                "fails its CRC check (the file is damaged)"
            )
        else:
            raise AssertionError("a damaged npz was read")


@pytest.mark.parametrize("chunk, workers", [(5000, 1), (7, 2), (3, 4)])
def test_locate_checks_the_frames_crc_as_it_reads_and_writes_nothing(tmp_path, chunk, workers):
    """fruit locate reads the frames once, checking their CRC-32 on the way (in order,
    from several threads too); a flipped bit is one error and no touches.csv."""
    from fruitcli.errors import FrameError
    from tests.helpers.locate import locate_scene

    rng = np.random.default_rng(1)
    frames = np.full((300, 21, 12), 500, np.int64)
    frames[10:, 5, 5] += rng.integers(30, 90, 290)
    path = tmp_path / "rec.npz"
    np.savez(path, frames=frames, t_s=np.arange(300) / 60.0)
    lines = ["id,i,j,x_mm,y_mm,z_mm"] + [
        f"{n},{n // 12},{n % 12},{16.0 * (n // 12)},{12.0 * (n % 12)},0.0" for n in range(252)
    ]
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    kw = {"chunk_frames": chunk, "workers": workers}
    res = locate_scene(None, path, tmp_path / "t.csv", None, tmp_path / "good", **kw)
    assert res["touches"] == 290
    flip_a_bit_in_member(path, "frames.npy")
    with pytest.raises(FrameError) as err:
        locate_scene(None, path, tmp_path / "t.csv", None, tmp_path / "bad", **kw)
    assert str(err.value) == (
        f"{path}: not a readable .npz recording: member frames.npy "
        "fails its CRC check (the file is damaged)"
    )
    assert not (tmp_path / "bad" / "touches.csv").exists()


def test_frames_read_out_of_order_are_checked_again_at_the_end(tmp_path):
    from fruitcli.errors import FrameError
    from fruitcli.sensing.frames.recording_chunks import open_recording

    path = tmp_path / "rec.npz"
    np.savez(path, frames=np.zeros((40, 21, 12), np.uint16), t_s=np.arange(40.0))
    for damaged in (False, True):
        if damaged:
            flip_a_bit_in_member(path, "frames.npy")
        with open_recording(path, verify="read") as rec:
            rec.read(20, 20)  # a gap: the running CRC cannot cover it
            rec.read(0, 20)
            if damaged:
                with pytest.raises(FrameError, match="frames.npy fails its CRC check"):
                    rec.verify()
            else:
                rec.verify()
    np.savez(path, frames=np.zeros((4, 21, 12), np.uint16), t_s=np.arange(4.0))
    flip_a_bit_in_member(path, "t_s.npy")  # the small members: checked on opening
    with pytest.raises(FrameError, match="member t_s.npy fails its CRC check"):
        open_recording(path, verify="read")
