"""The online FEM of `fruit live --online`: taxels at the measured pressures, solved from
the last equilibrium (synchronously and in its thread), a pressure past what the body
carries kept out of the output, and the live loop using the online positions."""

import re
import threading
import time

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import SolverError
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements import barycentric
from fruitcli.fem.meshing.grid import structured_box_with_cavity
from fruitcli.fem.online import OnlineSolver
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load
from tests.sensing.live.test_serial import PressureSource, live_lines, touch_frames
from tests.sensing.skin.test_virtual_bench import pad_taxel_csv

OPTS = SolverOptions(tolerance=1e-8)


def cube_with_cavity():
    """30 mm cube on a fixed base, a 10 mm cavity (the stability study's body), and three
    'taxels' on its top face."""
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [30, 30, 30], (6, 6, 6), [10, 10, 10], [20, 20, 20]
    )
    m = Model.from_arrays(
        nodes, tets, 100.0, 0.3, chambers={"c": cav}, fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0)
    )
    taxels = np.array([[15.0, 15.0, 29.9], [7.0, 21.0, 29.9], [24.0, 5.0, 29.9]])
    tet, w, _ = barycentric.locate(m.rest, m.tets, taxels)
    return m, tet, w


def fresh_taxels(m, tet, w, kpa):
    res = solve_state(m, Load.pressures([kpa]), options=OPTS)
    return barycentric.apply(res.x, m.tets, tet, w)


def test_online_states_match_fresh_solves_and_skip_small_changes():
    """Each new pressure is solved from the last equilibrium and gives the fresh solution
    (1e-6 of the displacement); a change below MIN_CHANGE_KPA is not solved again."""
    m, tet, w = cube_with_cavity()
    online = OnlineSolver(m, tet, w, OPTS)
    assert np.allclose(online.taxels_mm, barycentric.apply(m.rest, m.tets, tet, w))
    for kpa in (5.0, 12.0, 8.0):
        assert online.update([kpa])
        expect = fresh_taxels(m, tet, w, kpa)
        scale = np.abs(expect - barycentric.apply(m.rest, m.tets, tet, w)).max()
        assert scale > 0.05
        assert np.abs(online.taxels_mm - expect).max() < 1e-6 * scale
    before = online.taxels_mm
    assert not online.update([8.0 + 0.5 * online.min_change])
    assert online.taxels_mm is before and len(online.solve_ms) == 3
    assert "3 states solved" in online.summary() and "0 failed" in online.summary()


def test_online_pressure_past_the_limit_keeps_the_last_positions():
    """400 kPa inverts elements of this cube (limit about 44 kPa): the update fails
    without raising, the positions stay those of the last solved pressure, the failure is
    counted and named, and the next reachable pressure is solved again."""
    m, tet, w = cube_with_cavity()
    online = OnlineSolver(m, tet, w, OPTS)
    online.update([10.0])
    at_10 = online.taxels_mm
    assert not online.update([400.0])
    assert online.taxels_mm is at_10 and online.failures == 1
    assert "about to invert" in online.last_error and "400.0" in online.last_error
    assert online.update([15.0])
    assert np.abs(online.taxels_mm - fresh_taxels(m, tet, w, 15.0)).max() < 1e-4
    with pytest.raises(SolverError, match="expected 1 chamber pressures"):
        online.update([1.0, 2.0])


def test_online_thread_follows_the_pressure_source():
    m, tet, w = cube_with_cavity()
    online = OnlineSolver(m, tet, w, OPTS)
    kpa = {"now": np.array([6.0])}
    stop = threading.Event()
    th = online.run(lambda: kpa["now"], stop)
    try:
        deadline = time.monotonic() + 30
        while len(online.solve_ms) < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        kpa["now"] = np.array([9.0])
        while len(online.solve_ms) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        stop.set()
        th.join(5)
    assert not th.is_alive() and len(online.solve_ms) == 2
    assert np.abs(online.taxels_mm - fresh_taxels(m, tet, w, 9.0)).max() < 1e-5


def test_online_thread_stops_on_an_unexpected_error_and_says_so():
    """A source that raises ends the thread; the summary names the error instead of
    claiming that nothing failed."""
    m, tet, w = cube_with_cavity()
    online = OnlineSolver(m, tet, w, OPTS)
    calls = []

    def source():
        calls.append(1)
        if len(calls) > 1:
            raise ValueError("pressure sensor unplugged")
        return np.array([4.0])

    th = online.run(source, threading.Event())
    th.join(30)
    assert not th.is_alive() and len(online.solve_ms) == 1 and online.failures == 1
    assert "stopped early (ValueError: pressure sensor unplugged)" in online.summary()
    assert not online.update(None)  # nothing measured: nothing to solve


PAD_SCENE = """
[scene]
name = "online-pad"
[geometry]
pad_size_mm = [80.0, 80.0, 10.0]
[[geometry.chamber]]
name = "bend"
ellipsoid = {center_mm = [0.0, 0.0, 4.0], radii_mm = [20.0, 20.0, 2.5]}
[grid]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[fem]                   # the paper's model: fast enough to follow the frames here
element = "p1"
[material]
model = "corotational"
[mesh]
size_mm = 6.0
[[fixed]]
box_mm = [-50, -50, -0.01, 50, 50, 0.01]
[actuation]
pressure_kpa = {bend = [0.0, 3.0]}
[detection]
baseline_frames = 5
"""


def top_taxel_csv(path):
    """The 4 x 4 pad taxels (16 mm apart) on the 10 mm pad's top face."""
    pad_taxel_csv(path)
    path.write_text(path.read_text().replace(",3.0\n", ",10.0\n"))
    return path


def test_live_online_solves_the_measured_pressure(tmp_path, monkeypatch):
    """`fruit live --online` with a pressure port: the FEM thread solves the measured
    pressure on the scene's mesh (meshed into out/<scene> on first use) and the touches
    come out on the inflated pad; the summary line counts the solves."""
    from fruitcli.sensing.live.board_emulator import BoardEmulator

    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(PAD_SCENE)
    taxels = top_taxel_csv(tmp_path / "t.csv")
    src = PressureSource(3.0)
    frames = touch_frames(noise=False)
    # touches in frames 40..49, at 3.3 s: the solve in the FEM thread (well under a
    # second on a quiet machine) must be done by frame 50; 12 fps leaves it 4 s, as a
    # machine loaded 5x over needed (at 50 fps the test failed there)
    frames = np.concatenate([frames[:10]] * 3 + [frames])
    em = BoardEmulator(frames, fps=12, wait_for_reader=True)
    th = em.start()
    try:
        res = CliRunner().invoke(
            cli,
            [
                "live",
                str(tmp_path / "s.toml"),
                "--port",
                em.path,
                "--taxels",
                str(taxels),
                "--pressure-port",
                src.path,
                "--online",
                "--model",
                "full",
                "--frames",
                "60",
            ],
        )
    finally:
        th.join(5)
        src.close()
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "online-pad" / "tetra" / "mesh.npz").exists()
    # solved once: at the first pressure line (3 kPa), not at rest before it
    assert "online FEM (full model): 1 state solved" in res.output and "0 failed" in res.output
    skipped = re.search(r"pressure lines: \d+ taken, (\d+) skipped", res.output)
    assert skipped and int(skipped.group(1)) > 0  # the source's 'noise' lines
    lines = live_lines(res.output)
    assert [d["frame"] for d in lines] == list(range(40, 51))
    z = [d["touches"][0]["z_mm"] for d in lines[:-1]]
    assert all(10.0 <= v < 13.0 for v in z)  # at rest until the first solve, then up
    assert z[-1] > 10.05


def test_live_online_bad_inputs(tmp_path, monkeypatch):
    """--online without a pressure port, on a scene without chambers, and on a scene
    whose actuation never moves it (so it is not meshed): one line each, exit 1."""
    monkeypatch.chdir(tmp_path)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    flat = PAD_SCENE.replace(
        '[[geometry.chamber]]\nname = "bend"\n'
        "ellipsoid = {center_mm = [0.0, 0.0, 4.0], radii_mm = [20.0, 20.0, 2.5]}\n",
        "",
    )
    flat = flat.replace("[actuation]\npressure_kpa = {bend = [0.0, 3.0]}\n", "")
    still = PAD_SCENE.replace("[0.0, 3.0]", "[0.0, 0.0]")
    cases = [
        (PAD_SCENE, [], "--online: needs --pressure-port"),
        (flat, ["--pressure-port", "y"], "--online: the scene has no [[geometry.chamber]]"),
        (still, ["--pressure-port", "y"], "--online: the scene is not meshed (no deformation"),
    ]
    for n, (text, extra, message) in enumerate(cases):
        (tmp_path / f"s{n}.toml").write_text(text)
        res = CliRunner().invoke(
            cli,
            [
                "live",
                str(tmp_path / f"s{n}.toml"),
                "--port",
                "x",
                "--taxels",
                str(taxels),
                "--online",
                *extra,
            ],
        )
        assert res.exit_code == 1 and message in res.output, res.output
        assert res.output.count("Error") == 1


def test_live_online_uses_the_reduced_model_by_default(tmp_path, monkeypatch):
    """`fruit live --online` without --model: the scene's reduced model (built into
    out/<scene>/reduce on first use, here before the board emulator starts, which would
    not wait for it) is reused, the touches come out on the inflated pad at once (no
    Newton solve to wait for: every frame after the first pressure line is up), and
    the summary names the reduced model."""
    from fruitcli.scene import load_scene
    from fruitcli.sensing.live.board_emulator import BoardEmulator
    from fruitcli.workflow.reduced_model import ensure_reduced

    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(PAD_SCENE)
    taxels = top_taxel_csv(tmp_path / "t.csv")
    built = ensure_reduced(load_scene(tmp_path / "s.toml"), tmp_path / "out" / "online-pad", taxels)
    assert built.validation()["within_bound"]
    src = PressureSource(3.0)
    frames = touch_frames(noise=False)
    frames = np.concatenate([frames[:10]] * 3 + [frames])
    em = BoardEmulator(frames, fps=50, wait_for_reader=True)
    th = em.start()
    try:
        res = CliRunner().invoke(
            cli,
            [
                "live",
                str(tmp_path / "s.toml"),
                "--port",
                em.path,
                "--taxels",
                str(taxels),
                "--pressure-port",
                src.path,
                "--online",
                "--frames",
                "60",
            ],
        )
    finally:
        th.join(5)
        src.close()
    assert res.exit_code == 0, res.output
    assert "reduce: reuse" in res.output
    assert re.search(
        r"online reduced model \(degree \d.*\): \d+ pressure vectors, \d+ us "
        "median",
        res.output,
    )
    lines = live_lines(res.output)
    assert [d["frame"] for d in lines] == list(range(40, 51))
    z = np.array([d["touches"][0]["z_mm"] for d in lines[:-1]])
    assert z.min() > 10.05  # the pressures arrived long before the touches
    # at 3 kPa the reduced model's taxels, as the live loop used them
    assert np.abs(built.taxels([3.0])[:, 2].max() - 10.0) > 0.05
