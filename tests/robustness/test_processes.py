"""Child processes end with their parent; temporary folders carry their owner's process id,
are swept once that process is gone, and are never shared by concurrent runs."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from tests.conftest import ROOT


def _gone(pid: int, wait_s: float = 20.0) -> bool:
    end = time.monotonic() + wait_s
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        # a zombie (ended, not yet reaped by init) counts as gone
        try:
            if Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] == "Z":
                return True
        except OSError:
            return True
        time.sleep(0.1)
    return False


PARENT = """
import os, subprocess, sys, time
env = dict(os.environ, FRUIT_GMSH_PARENT=str(os.getpid()))
child = subprocess.Popen([sys.executable, "-c", "import os, sys, time\\n"
    "from fruitcli.fem.meshing.child_process import PARENT_ENV, die_with_parent\\n"
    "die_with_parent(int(os.environ[PARENT_ENV]))\\n"
    "print('ready', flush=True)\\n"
    "time.sleep(120)"], env=env, start_new_session=True, stdout=subprocess.PIPE, text=True)
assert child.stdout.readline().strip() == "ready"
print(child.pid, flush=True)
time.sleep(120)
"""


def test_gmsh_child_ends_when_its_parent_is_killed():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        child = int(parent.stdout.readline())
        os.kill(child, 0)  # running
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        assert _gone(child), "the child outlived its parent"
    finally:
        parent.kill()
        parent.wait()


def test_orphaned_temporary_folders_are_swept(tmp_path):
    from fruitcli.fsutil import owned_prefix, staged_dir, sweep_orphans

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    orphan = tmp_path / f".make-tracks.{dead.pid}-abc"
    orphan.mkdir()
    (orphan / "reduced.stl").write_text("half")
    live = tmp_path / f".make-tracks.{os.getppid()}-def"  # a process that is running
    live.mkdir()
    other = tmp_path / "make-tracks"
    with staged_dir(other) as tmp:
        assert tmp.name.startswith(owned_prefix(".make-tracks."))
        (tmp / "taxels.csv").write_text("x")
    assert not orphan.exists() and live.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [live.name, "make-tracks"]
    gmsh = tmp_path / f"fruit-gmsh-{dead.pid}-xyz"
    gmsh.mkdir()
    assert sweep_orphans(tmp_path, "fruit-gmsh-") == [gmsh] and not gmsh.exists()


def test_concurrent_copies_of_a_borrowed_stage_do_not_collide(tmp_path):
    from concurrent.futures import ThreadPoolExecutor

    from fruitcli.workflow.planner import MANIFEST, _copy_in

    source = tmp_path / "other" / "tetra"
    source.mkdir(parents=True)
    (source / "mesh.npz").write_bytes(os.urandom(200_000))
    (source / MANIFEST).write_text("{}")
    target = tmp_path / "mine" / "tetra"
    with ThreadPoolExecutor(4) as pool:
        list(pool.map(lambda _: _copy_in(source, target), range(8)))
    assert (target / "mesh.npz").read_bytes() == (source / "mesh.npz").read_bytes()
    assert sorted(p.name for p in target.parent.iterdir()) == ["tetra"]


def test_killing_an_ended_gmsh_group_is_no_error():
    from fruitcli.fem.meshing.child_process import kill_group

    proc = subprocess.Popen([sys.executable, "-c", "pass"], start_new_session=True)
    proc.wait()
    kill_group(proc.pid)  # "No such process" before


def test_orphaned_temporary_files_are_swept_when_the_file_is_written_again(tmp_path):
    """A writer killed with SIGKILL between creating its temporary file and renaming it
    leaves `.<name>.<pid>-...`; the next write of that file removes it, not a live
    writer's."""
    from fruitcli.fsutil import atomic_path, owned_prefix, write_text

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    orphan = tmp_path / f".noise_std.png.{dead.pid}-abc.png"
    orphan.write_text("half")
    live = tmp_path / f".noise_std.png.{os.getppid()}-def.png"
    live.write_text("being written")
    with atomic_path(tmp_path / "noise_std.png") as tmp:
        assert tmp.name.startswith(owned_prefix(".noise_std.png."))
        tmp.write_text("whole")
    write_text(tmp_path / "other.txt", "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == [live.name, "noise_std.png", "other.txt"]
