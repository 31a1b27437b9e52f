"""The pressure check's samples kept in the output folder (`fruitcli.fem.sample_cache`)
on the octant of the thick sphere (nu = 0.49, limit 27.0 kPa): a later check of the same
body takes them from the file and refuses, or passes, the same pressures; a file of
another body, an edited sample, a sample whose supports moved and a file that is not an
npz are not trusted."""

import numpy as np
import pytest

from fruitcli.errors import SceneError
from fruitcli.fem import curve_start, limits, pressure_check, sample_cache
from fruitcli.fem.curve_start import chamber_load
from fruitcli.fem.limits import STRETCH_STEP
from fruitcli.fem.sample_cache import SampleCache, body_key, load_key
from fruitcli.fem.solver.options import SolverOptions
from tests.fem.meshing.test_mesh import octant_ball

KEY = ["[actuation].pressure_kpa.c"]
CHECK = SolverOptions(tolerance=limits.CHECK_TOLERANCE, load_steps=1, max_subdivisions=2)


def counted(monkeypatch) -> list:
    """The loads of the states solved from here on (by the curves and by Newton from a
    kept sample)."""
    solved = []
    for module in (curve_start, limits, sample_cache):
        real = module.solve_state

        def solve(model, load, *args, real=real, **kw):
            solved.append(load)
            return real(model, load, *args, **kw)

        monkeypatch.setattr(module, "solve_state", solve)
    return solved


def check(model, kpa: float, kept, told=None) -> str:
    """The check of chamber c at kpa with its samples kept in `kept`: its refusal, or ''."""
    try:
        pressure_check.check_pressures(
            model,
            np.array([[kpa]]),
            KEY,
            model.make_solver(),
            SolverOptions(),
            progress=None if told is None else told.append,
            kept=kept,
        )
    except SceneError as exc:
        return str(exc)
    return ""


def test_a_later_check_of_the_same_body_takes_the_kept_samples(tmp_path, monkeypatch):
    """100 kPa is refused with the limit's bound after three samples; a later check of the
    same body (a model built anew) refuses it in the same line without solving a state,
    the samples told as kept; 10 kPa, within the limit, passes both times."""
    path = tmp_path / sample_cache.CACHE_FILE
    cold_told: list[str] = []
    cold = check(octant_ball(1, 1, nu=0.49), 100.0, path, cold_told)
    assert cold.startswith("[actuation].pressure_kpa.c: 100 kPa is past this chamber's limit")
    assert path.exists() and len(cold_told) == 3
    solved = counted(monkeypatch)
    warm_told: list[str] = []
    assert check(octant_ball(1, 1, nu=0.49), 100.0, path, warm_told) == cold
    assert solved == []
    assert [t.split(" (")[0] for t in warm_told] == [t.split(" (")[0] for t in cold_told]
    assert all(
        t.endswith("(0 Newton steps from the sample an earlier run kept)") for t in warm_told
    )
    monkeypatch.undo()
    assert check(octant_ball(1, 1, nu=0.49), 10.0, path) == ""
    assert check(octant_ball(1, 1, nu=0.49), 10.0, path) == ""


def first_sample(model):
    """(load, kept x (n, 3) mm, kept pressures (K,) kPa, the file's entry key) of the
    curve's first inflation sample."""
    load = chamber_load(
        model, 0, model.chamber_rest_volume_mm3[0] * ((1.0 + STRETCH_STEP) ** 3 - 1)
    )
    return load, load_key(load, CHECK.tolerance)


def test_samples_of_another_body_or_edited_are_not_trusted(tmp_path, monkeypatch):
    """The file of the octant at nu = 0.49 is not used for nu = 0.45 (another body key:
    its three samples solved anew, the first to the screen's tolerance and on from
    there, the file then the new body's); a kept sample moved off its
    equilibrium is only Newton's start (the same pressure within the tolerance, after
    Newton steps); one whose rollers moved, or that inverts elements, is not used; a file
    that is not an npz is ignored and written anew."""
    path = tmp_path / sample_cache.CACHE_FILE
    model = octant_ball(1, 1, nu=0.49)
    check(model, 100.0, path)
    other = octant_ball(1, 1, nu=0.45)
    assert body_key(other) != body_key(model)
    solved = counted(monkeypatch)
    assert check(other, 100.0, path).startswith("[actuation].pressure_kpa.c: 100 kPa is past")
    growths = [float(load.volume_growth_mm3[0]) for load in solved]
    assert len(set(growths)) == 3 and growths[0] == growths[1]  # the first: screened, then on
    with np.load(path) as data:
        assert str(data["body"]) == body_key(other)
    monkeypatch.undo()

    check(model, 100.0, path)  # the file the octant's at nu = 0.49 again
    load, key = first_sample(model)
    kept = SampleCache(model, path, CHECK)
    x, p, _ = kept.entries[key]
    solver = model.make_solver()
    as_kept = kept.get(load, solver)
    assert as_kept is not None and as_kept.kept and as_kept.iterations == 0
    free = model.pattern.free
    rng = np.random.default_rng(5)

    def edited(y):
        cache = SampleCache(model, path, CHECK)
        cache.entries[key] = (y, p, 1.0)
        return cache.get(load, solver)

    moved = x.copy()
    moved.reshape(-1)[free] += 0.05 * rng.standard_normal(len(free))
    polished = edited(moved)
    assert polished is not None and polished.iterations > 0
    assert polished.pressure_kpa[0] == pytest.approx(p[0], rel=10 * CHECK.tolerance)
    rollers = x.copy()
    held = np.setdiff1d(np.arange(x.size), free)
    rollers.reshape(-1)[held[0]] += 0.01
    assert edited(rollers) is None
    loose = np.isin(3 * model.conn[:, :4, None] + np.arange(3), free).all(axis=2)
    e, a = np.argwhere(loose)[0]  # a corner free in x, y and z, and one of its tets
    node, face = model.conn[e, a], x[np.delete(model.conn[e, :4], a)]
    normal = np.cross(face[1] - face[0], face[2] - face[0])
    normal /= np.linalg.norm(normal)
    inverted = x.copy()
    inverted[node] -= 2.0 * np.dot(x[node] - face[0], normal) * normal  # through the face
    assert model.min_det_f(inverted).min() <= 0.0
    assert edited(inverted) is None

    path.write_bytes(b"not an npz")
    assert SampleCache(model, path, CHECK).entries == {}
    assert check(model, 100.0, path).startswith("[actuation].pressure_kpa.c: 100 kPa is past")
    with np.load(path) as data:
        assert str(data["body"]) == body_key(model)
