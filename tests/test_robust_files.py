"""The user's files are never overwritten unless they ask."""

from click.testing import CliRunner

from fruitcli.cli.main import cli


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_generate_artist_keeps_the_users_mesh(tmp_path):
    import trimesh

    mine = tmp_path / "mine.stl"
    trimesh.creation.box(extents=(40.0, 30.0, 20.0)).export(mine)
    before = mine.read_bytes()
    scene = tmp_path / "s.toml"
    scene.write_text('[scene]\nname = "s"\n[geometry]\nartist = "mine.stl"\n'
                     "generate_artist = true\n")
    res = run("run", scene, "--out", tmp_path / "o", "--until", "make-artist")
    assert res.exit_code == 0, res.output
    assert mine.read_bytes() == before


def test_make_artist_refuses_an_existing_file(tmp_path):
    out = tmp_path / "a.stl"
    out.write_text("the user's mesh")
    res = run("make-artist", "--out", out)
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        f"Error: --out {out}: exists; give --overwrite to replace it")
    assert out.read_text() == "the user's mesh"
