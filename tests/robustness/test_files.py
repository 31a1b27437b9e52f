"""The user's files are never overwritten unless they ask."""

from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.output_folder import MARKER


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_generate_artist_keeps_the_users_mesh(tmp_path):
    import trimesh

    mine = tmp_path / "mine.stl"
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(mine)
    before = mine.read_bytes()
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[scene]\nname = "s"\n[geometry]\nartist = "mine.stl"\ngenerate_artist = true\n'
    )
    res = run("run", scene, "--out", tmp_path / "o", "--until", "make-artist")
    assert res.exit_code == 0, res.output
    assert mine.read_bytes() == before


def test_make_artist_refuses_an_existing_file(tmp_path):
    out = tmp_path / "a.stl"
    out.write_text("the user's mesh")
    res = run("make-artist", "--out", out)
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        f"Error: --out {out}: exists; give --overwrite to replace it"
    )
    assert out.read_text() == "the user's mesh"


def test_locate_removes_a_measured_csv_of_another_run(tmp_path):
    import numpy as np

    from fruitcli.sensing.frames.recording import Recording, write_muca_log

    taxels = tmp_path / "t.csv"
    taxels.write_text("id,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,0\n1,1,0,16,0,0\n")
    frames = np.full((20, 21, 12), 1000, np.uint16)
    frames[15:, 0, 0] += 200
    log = tmp_path / "f.log"
    write_muca_log(log, Recording(frames, np.arange(20) / 10.0))
    out = tmp_path / "o"
    out.mkdir()
    (out / MARKER).write_text("{}\n")  # the folder of an earlier run
    (out / "measured.csv").write_text("sample,x_mm,y_mm,z_mm\n0,1,2,3\n")
    res = run("locate", log, "--taxels", taxels, "--out", out)
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "touches.csv"]
    rows = [
        line
        for line in (out / "touches.csv").read_text().splitlines()
        if line and not line.startswith("#")
    ]
    assert len(rows) == 1 + 5  # header, one touch in each of frames 15-19
