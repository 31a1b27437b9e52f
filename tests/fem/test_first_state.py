"""`fruit simulate`'s first state kept in the output folder (`sample_cache.CACHE_FILE`,
`kept_first_state`): a later run on the same body takes it as it is while it is an
equilibrium of the model, starts Newton from it when it is off equilibrium, and solves
from rest when the body is another."""

import numpy as np
import pytest

from fruitcli.fem import sample_cache
from fruitcli.fem.stage import run_simulate, run_tetra
from fruitcli.fem.tolerances import ESTIMATE_WINDOW
from fruitcli.scene import parse_scene

PAD = """
[geometry]
pad_size_mm = [40.0, 30.0, 10.0]
[[geometry.chamber]]
name = "a"
ellipsoid = {{center_mm = [0.0, 0.0, 5.0], radii_mm = [8.0, 6.0, 2.5]}}
[mesh]
size_mm = 5.0
[material]
young_modulus_kpa = {e}
poisson_ratio = 0.49
density_kg_m3 = 1070.0
[gravity]
vector_m_s2 = [0.0, 0.0, -9.81]
[[fixed]]
box_mm = [-30.0, -30.0, -1.0, 30.0, 30.0, 0.5]
[actuation]
pressure_kpa = {{ a = [6.0, 8.0] }}
"""


def pad(tmp_path, e=100.0):
    text = PAD.format(e=e)
    (tmp_path / "pad.toml").write_text(text)
    return parse_scene(text, tmp_path / "pad.toml")


@pytest.fixture(scope="module")
def meshed(tmp_path_factory):
    """(scene, mesh.npz) of the pad with its chamber under its weight and 6, then 8 kPa."""
    tmp = tmp_path_factory.mktemp("first")
    scene = pad(tmp)
    run_tetra(scene, None, tmp / "m")
    return scene, tmp / "m" / "mesh.npz"


def simulate(scene, mesh, out):
    """(states.npz as a dict, the progress lines) of a run into `out`."""
    said: list[str] = []
    run_simulate(scene, mesh, None, out, progress=said.append)
    with np.load(out / "states.npz", allow_pickle=False) as st:
        return {k: st[k] for k in st.files}, said


def test_a_later_run_takes_the_kept_first_state(meshed, tmp_path):
    """The second run into the same folder takes the first state as it is (no Newton
    step, told in its line), the same nodes to the last digit; the next state, started
    from it by the predictor as in the first run (the state and its pressure response
    left on the solver), takes no more Newton steps and is the first run's within the
    displacement tolerance."""
    scene, mesh = meshed
    cold, _ = simulate(scene, mesh, tmp_path)
    assert cold["iterations"][0] > 0
    with np.load(tmp_path / sample_cache.CACHE_FILE, allow_pickle=False) as kept:
        # the state, and the Newton constant the next states' linear tolerance starts from
        names = sorted(k.split("_")[-1] for k in kept.files if k != "body")
        assert names == ["c", "ms", "p", "x"]
    warm, said = simulate(scene, mesh, tmp_path)
    assert warm["iterations"][0] == 0
    assert said[-2].startswith("state 1/2: equilibrium kept from an earlier run")
    assert np.array_equal(warm["displacement_mm"][0], cold["displacement_mm"][0])
    # the residual tolerance, or near it the displacement tolerance (newton._close_enough)
    assert (warm["residual"] <= 1e-6 * ESTIMATE_WINDOW).all()
    assert 0 < warm["iterations"][1] <= cold["iterations"][1]
    close = scene.solver.displacement_tolerance_mm  # [solver]'s, 1e-4 mm
    assert np.abs(warm["displacement_mm"][1] - cold["displacement_mm"][1]).max() <= close


def test_a_kept_first_state_off_equilibrium_is_only_a_start(meshed, tmp_path):
    """A kept first state moved by 0.05 mm (an edited file) is not taken as it is:
    Newton starts from it and ends at the equilibrium solved from rest (within the
    displacement tolerance)."""
    scene, mesh = meshed
    cold, _ = simulate(scene, mesh, tmp_path)
    path = tmp_path / sample_cache.CACHE_FILE
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    (key,) = [k for k in arrays if k.endswith("_x")]
    free = np.abs(cold["displacement_mm"][0]).max(axis=1) > 0
    arrays[key] = arrays[key] + 0.05 * free[:, None]
    np.savez(path, **arrays)
    warm, said = simulate(scene, mesh, tmp_path)
    assert warm["iterations"][0] > 0 and "kept from an earlier run" in said[-2]
    close = scene.solver.displacement_tolerance_mm
    assert np.abs(warm["displacement_mm"][0] - cold["displacement_mm"][0]).max() <= close


def test_a_first_state_kept_for_another_body_is_not_used(meshed, tmp_path):
    """The folder's first state was solved for the pad at E = 100 kPa; the pad at 200 kPa
    solves its own from rest (same Newton steps as in an empty folder), about half the
    displacement."""
    scene, mesh = meshed
    cold, _ = simulate(scene, mesh, tmp_path)
    (tmp_path / "stiff").mkdir()
    stiff = pad(tmp_path / "stiff", 200.0)
    alone, _ = simulate(stiff, mesh, tmp_path / "alone")
    warm, said = simulate(stiff, mesh, tmp_path)
    assert not any("kept from an earlier run" in line for line in said)
    assert warm["iterations"][0] == alone["iterations"][0] > 0
    assert np.array_equal(warm["displacement_mm"][0], alone["displacement_mm"][0])
    ratio = np.abs(warm["displacement_mm"][0]).max() / np.abs(cold["displacement_mm"][0]).max()
    assert 0.4 < ratio < 0.6
