"""Limit pressures (`fruitcli.fem.limits`): the neo-Hookean thick sphere's pressure-volume
curve against its closed form (incompressible) and the radial solution of the
compressible material the FEM uses; suction down to the collapse."""

import json
import os
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
from click.testing import CliRunner
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from fruitcli.cli.main import cli
from fruitcli.errors import SceneError, SolverError
from fruitcli.fem import curve_peak, curve_start, limits, pressure_check, sample_cache
from fruitcli.fem.continuum import ContinuumModel
from fruitcli.fem.limits_stage import run_limits
from fruitcli.fem.materials.build import material
from fruitcli.fem.solver import linsolve, state
from fruitcli.fem.solver.c_output import captured_output
from fruitcli.fem.solver.options import OutOfTime, SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.stage import run_simulate, run_tetra
from fruitcli.fem.state_load import Load
from fruitcli.scene import parse_scene
from fruitcli.studies.parallel import CurveProcesses
from tests.fem.meshing.test_mesh import ball_scene, inflation_pressure, octant_ball

LIMIT_B_OVER_A_2 = 0.8164  # max P / mu of the incompressible sphere, B / A = 2
STRETCH_AT_LIMIT = 1.828


def radial_pressure(mu, kappa, la, a=10.0, b=20.0):
    """Cavity pressure (kPa) at inner stretch la of the compressible neo-Hookean sphere
    (psi = mu/2 (I1bar - 3) + kappa/4 (J^2 - 1 - 2 ln J), the FEM's material), inner
    radius a, outer b (mm), outer surface free: the radial equilibrium dP1/dR + 2 (P1 -
    P2) / R = 0 (nominal stresses P1 radial, P2 hoop) shot from r(a) = la a to P1(b) = 0;
    the Cauchy pressure is -P1(a) / la^2."""

    def nominal(l1, l2, radial):
        j, i1 = l1 * l2 * l2, l1 * l1 + 2 * l2 * l2
        li = l1 if radial else l2
        return mu * j ** (-2 / 3) * (li - i1 / (3 * li)) + 0.5 * kappa * (j * j - 1) / li

    def rhs(r_ref, y):
        r, p1 = y
        l2 = r / r_ref
        l1 = brentq(lambda v: nominal(v, l2, True) - p1, 1e-3, 50.0, xtol=1e-14)
        return [l1, -2 * (p1 - nominal(l1, l2, False)) / r_ref]

    def outer_traction(p1_inner):
        return solve_ivp(rhs, (a, b), [la * a, p1_inner], rtol=1e-10, atol=1e-12).y[1, -1]

    return -brentq(outer_traction, -50 * mu, 0.0, xtol=1e-12) / la**2


def test_radial_reference_is_the_closed_form_when_incompressible():
    """nu = 0.4999: the shooting solution is the closed form within 0.1 % (the closed
    form's peak 0.8164 mu at la = 1.828); at nu = 0.49 the peak is 1.5 % lower."""
    for nu in (0.4999, 0.49):
        mu, kappa = 100 / (2 * (1 + nu)), 100 / (3 * (1 - 2 * nu))
        for la in (1.2, STRETCH_AT_LIMIT, 2.2):
            if nu == 0.4999:
                assert radial_pressure(mu, kappa, la) == pytest.approx(
                    inflation_pressure(mu, la), rel=1e-3
                )
    assert inflation_pressure(1.0, STRETCH_AT_LIMIT) == pytest.approx(LIMIT_B_OVER_A_2, abs=1e-4)
    assert radial_pressure(mu, kappa, STRETCH_AT_LIMIT) / mu == pytest.approx(0.8043, abs=1e-3)


def test_thick_sphere_limit_pressure_and_descending_branch():
    """The hollow ball (A = 10, B = 20 mm, E = 100 kPa, nu = 0.49) on its octant, 2 cells
    per patch edge and 2 layers (144 quadratic tets), default element: the limit
    pressure that `limits.follow` finds by volume control is the incompressible closed
    form's 0.8164 mu within 3 % (measured -1.5 %, all of it compressibility: within 0.5
    % of the compressible radial solution), at a mean stretch within 0.1 of 1.828; on
    the branch past it (la = 2.2) the pressure held is within 3 % of the closed form
    (measured -2.3 %) and 1 % of the radial solution."""
    model = octant_ball(2, 2, nu=0.49)
    mat = model.material
    mu, kappa = mat.shear_modulus_kpa, mat.bulk_modulus_kpa
    curve = limits.follow(model, 0)
    assert curve.end == "past the limit point"
    assert curve.limit_pressure_kpa == pytest.approx(LIMIT_B_OVER_A_2 * mu, rel=0.03)
    assert curve.limit_pressure_kpa == pytest.approx(
        radial_pressure(mu, kappa, STRETCH_AT_LIMIT), rel=0.005
    )
    v0 = model.chamber_rest_volume_mm3[0]
    stretch = (1 + curve.limit_growth_mm3 / v0) ** (1 / 3)
    assert stretch == pytest.approx(STRETCH_AT_LIMIT, abs=0.1)
    assert max(curve.pressure_kpa) <= curve.limit_pressure_kpa
    # the descending branch: volume control on to la = 2.2
    x, prev, p = None, None, None
    for la in np.arange(1.1, 2.25, 0.1):
        load = Load(np.zeros(1), np.array([v0 * (la**3 - 1)]), np.array([True]))
        res = solve_state(
            model, load, x_start=x, load_start=prev, pressure_start=p, options=SolverOptions()
        )
        x, prev, p = res.x, load, res.pressure_kpa
    assert la == pytest.approx(2.2)
    assert p[0] == pytest.approx(inflation_pressure(mu, 2.2), rel=0.03)
    assert p[0] == pytest.approx(radial_pressure(mu, kappa, 2.2), rel=0.01)
    assert p[0] < curve.limit_pressure_kpa


def test_thick_sphere_limit_from_the_vertex_ahead():
    """As `fruit limits` follows a curve (one sample past the peak at most, from the body's
    `Start`): the thick sphere's inflation ends before its peak, at the vertex of the
    parabola through its last three samples (less than PEAK_AHEAD steps ahead), within
    0.5 % of the compressible radial solution's peak (measured -0.13 %; the curve
    followed to a sample past the peak -0.07 %), with fewer samples."""
    model = octant_ball(2, 2, nu=0.49)
    mu, kappa = model.material.shear_modulus_kpa, model.material.bulk_modulus_kpa
    solver = model.make_solver()
    start = curve_start.start_state(model, solver, SolverOptions())
    curve = limits.follow(model, 0, fall_steps=1, solver=solver, start=start)
    assert curve.end.startswith("at the limit point")
    assert curve.limit_pressure_kpa == pytest.approx(
        radial_pressure(mu, kappa, STRETCH_AT_LIMIT), rel=0.005
    )
    assert max(curve.pressure_kpa) <= curve.limit_pressure_kpa
    assert np.all(np.diff(curve.pressure_kpa) > 0)  # no sample past the peak
    assert len(curve.pressure_kpa) < len(limits.follow(model, 0).pressure_kpa)


def test_thick_sphere_suction_collapses():
    """The same octant under suction: the pressure falls below 0 as the cavity shrinks,
    and the curve ends at a named collapse, its pressure the lowest reached."""
    model = octant_ball(2, 2, nu=0.49)
    curve = limits.follow(model, 0, -1)
    assert curve.collapse_pressure_kpa is not None
    assert curve.collapse_pressure_kpa == min(curve.pressure_kpa) < 0
    assert np.all(np.diff(curve.growth_mm3) < 0)
    assert curve.limit_pressure_kpa is None


def test_suction_to_the_end_of_the_range_is_a_collapse(monkeypatch):
    """A cavity sucked down to the range's end (the next sample would be under
    COLLAPSE_VOLUME) without buckling has nearly no volume left: its lowest pressure is
    the collapse, and a suction past it is refused (the range cut to stretch 0.8 here)."""
    monkeypatch.setattr(limits, "MIN_STRETCH", 0.8)
    model = octant_ball(1, 1, nu=0.49)
    curve = limits.follow(model, 0, -1)
    assert len(curve.pressure_kpa) == 3  # rest, stretch 0.9 and 0.8
    assert curve.end == "the cavity is nearly empty, at 0.512 V0"
    assert curve.collapse_pressure_kpa == min(curve.pressure_kpa) < 0
    with pytest.raises(SceneError, match=r"-500 kPa is past this chamber's collapse pressure"):
        pressure_check.check_pressures(
            model, np.array([[-500.0]]), ["k"], model.make_solver(), SolverOptions()
        )


def test_stop_beyond_a_reachable_pressure():
    """Asked whether 10 kPa is reachable, inflation stops at the first sample past it."""
    model = octant_ball(1, 1, nu=0.49)
    curve = limits.follow(model, 0, stop_beyond_kpa=10.0)
    assert curve.pressure_kpa[-1] >= 10.0 > curve.pressure_kpa[-2]
    assert curve.limit_pressure_kpa is None and curve.end.startswith("the pressure asked")


def test_pressures_past_the_limit_or_collapse_are_refused_in_one_line():
    """`check_pressures` on the octant (nu = 0.49, limit 27.0 kPa): 28 kPa is past the
    limit (one line with the key, the pressure and the limit, found by following the
    curve to its peak; without the screen, which lets it through to Newton and
    `explain_failure`, see below); 100 kPa is refused sooner, once the curve is concave, with a
    bound of the limit (`levels_off_bound`: a pressure no equilibrium reaches up to 27
    V0); -500 kPa is past the collapse; 10 kPa and -10 kPa are reachable, and pressures
    too small to come near a limit (linearized growth under SCREEN_GROWTH V0) are not
    followed at all."""
    model = octant_ball(1, 1, nu=0.49)
    options = SolverOptions()
    key = ["[actuation].pressure_kpa.c"]
    with pytest.raises(SceneError) as info:
        pressure_check.check_pressures(
            model, np.array([[5.0], [28.0]]), key, model.make_solver(), options, screen=0.0
        )
    line = str(info.value)
    lim = float(line.split("limit pressure of ")[1].split(" kPa")[0])
    assert lim == pytest.approx(0.8052 * model.material.shear_modulus_kpa, rel=0.01)
    assert line == (
        f"[actuation].pressure_kpa.c: 28 kPa is past this chamber's limit "
        f"pressure of {pressure_check.kpa(lim)} kPa (no equilibrium above it); give "
        "`volume_growth_mm3` to follow the inflation past it"
    )
    told = []
    with pytest.raises(SceneError) as info:
        pressure_check.check_pressures(
            model, np.array([[100.0]]), key, model.make_solver(), options, progress=told.append
        )
    line = str(info.value)
    bound = float(line.split("which is at most ")[1].split(" kPa")[0])
    assert lim < bound < 100.0
    assert line == (
        f"[actuation].pressure_kpa.c: 100 kPa is past this chamber's limit "
        f"pressure, which is at most {pressure_check.kpa(bound)} kPa (a bound: its pressure-volume "
        "curve levels off, and there is no equilibrium above its peak; `fruit limits` "
        "computes the limit); give `volume_growth_mm3` to follow the inflation past it"
    )
    assert len(told) < 5  # refused before the peak (at stretch 1.83: 8 samples)
    with pytest.raises(
        SceneError,
        match=r"^\[actuation\].pressure_kpa.c: -500 kPa is past "
        r"this chamber's collapse( pressure of -\d|: no equilibrium was found beyond -\d)",
    ):
        pressure_check.check_pressures(
            model, np.array([[-500.0]]), key, model.make_solver(), options
        )
    pressure_check.check_pressures(
        model, np.array([[10.0], [-10.0], [np.nan]]), key, model.make_solver(), options
    )
    told = []
    pressure_check.check_pressures(
        model, np.array([[0.5]]), key, model.make_solver(), options, progress=told.append
    )
    assert told == []  # screened out: no sample followed


def test_levels_off_bound_from_one_sample_and_the_slope_at_rest():
    """With one sample past rest, the slope at rest is the first slope compared: a
    secant below it bounds the curve by that secant continued to MAX_STRETCH (inflation)
    or to the end given below the samples (suction, a lower bound); one above it (the
    curve not levelling off), no rest slope, or another material: no bound."""
    model = octant_ball(1, 1, nu=0.49)
    pressure, stretch = np.array([0.0, 8.0]), np.array([1.0, 1.1])
    bound = curve_peak.levels_off_bound(model, pressure, stretch, slope_at_rest=100.0)
    assert bound == pytest.approx(8.0 + 80.0 * (curve_peak.MAX_STRETCH - 1.1))
    assert curve_peak.levels_off_bound(model, pressure, stretch, slope_at_rest=70.0) is None
    assert curve_peak.levels_off_bound(model, pressure, stretch) is None
    yeoh = SimpleNamespace(material_name="yeoh")
    assert curve_peak.levels_off_bound(yeoh, pressure, stretch, slope_at_rest=100.0) is None
    down, shrinking = np.array([0.0, -8.0, -14.0]), np.array([1.0, 0.9, 0.8])
    bound = curve_peak.levels_off_bound(model, down, shrinking, end=0.45)
    assert bound == pytest.approx(-14.0 - 60.0 * (0.8 - 0.45))
    steepening = np.array([0.0, -8.0, -20.0])
    assert curve_peak.levels_off_bound(model, steepening, shrinking, end=0.45) is None


def test_a_suction_that_levels_off_is_refused_with_a_bound_of_its_collapse():
    """An oblate octant shell (z scaled by 0.4: a flat cavity, nu = 0.49) under suction:
    its flat walls bend in and the curve levels off (the sphere's steepens, above), so
    -500 kPa is refused after the first sample, below ONE_SAMPLE_MARGIN times the
    secant's bound continued to MIN_STRETCH, with that bound in its line; the collapse
    followed to the end lies above the bound. -5 kPa is reached."""
    model = octant_ball(2, 2, nu=0.49, flat=0.4)
    key = ["[actuation].pressure_kpa.c"]
    told = []
    with pytest.raises(SceneError) as info:
        pressure_check.check_pressures(
            model,
            np.array([[-500.0]]),
            key,
            model.make_solver(),
            SolverOptions(),
            progress=told.append,
            screen=0.0,
        )
    assert len(told) == 1
    p1 = float(told[0].split("pressure ")[1].split(" kPa")[0])
    s1 = 1.0 - limits.STRETCH_STEP
    line = str(info.value)
    bound = float(line.split("whose pressure is at least ")[1].split(" kPa")[0])
    assert bound == pytest.approx(p1 + p1 / (s1 - 1.0) * (limits.MIN_STRETCH - s1), rel=2e-3)
    assert line == (
        f"[actuation].pressure_kpa.c: -500 kPa is past this chamber's collapse, whose "
        f"pressure is at least {pressure_check.kpa(bound)} kPa (a bound: its "
        "pressure-volume curve levels off before its walls would meet, and self-contact "
        "is not modelled; `fruit limits` computes the collapse); give "
        "`volume_growth_mm3` to follow the suction"
    )
    curve = limits.follow(model, 0, -1)
    assert curve.end.startswith("the cavity is nearly empty")
    assert bound < curve.collapse_pressure_kpa < 0
    pressure_check.check_pressures(
        model, np.array([[-5.0]]), key, model.make_solver(), SolverOptions(), screen=0.0
    )


def test_far_past_the_bound_is_refused_after_the_first_sample():
    """The octant at 2000 kPa: its rest compliance gives the slope at rest (3 V0 / C),
    and the first sample's secant below it bounds the curve; 2000 kPa is more than
    ONE_SAMPLE_MARGIN times that bound, so the check refuses after one sample, with that
    bound in its line. 100 kPa is not (see above: refused once the curve bends)."""
    model = octant_ball(1, 1, nu=0.49)
    solver = model.make_solver()
    compliance = pressure_check.rest_compliance(model, solver)
    slope = curve_peak.rest_slope(model, np.array([1.0]), compliance)
    assert slope == pytest.approx(3 * model.chamber_rest_volume_mm3[0] / compliance[0, 0])
    told = []
    with pytest.raises(SceneError) as info:
        pressure_check.check_pressures(
            model, np.array([[2000.0]]), ["k"], solver, SolverOptions(), progress=told.append
        )
    assert len(told) == 1
    p1 = float(told[0].split("pressure ")[1].split(" kPa")[0])
    s1 = 1.0 + limits.STRETCH_STEP
    assert p1 / (s1 - 1.0) < slope
    bound = float(str(info.value).split("which is at most ")[1].split(" kPa")[0])
    assert bound == pytest.approx(p1 / (s1 - 1.0) * (curve_peak.MAX_STRETCH - 1.0), rel=2e-3)
    assert curve_peak.ONE_SAMPLE_MARGIN * bound < 2000.0


def tolerances_solved(monkeypatch) -> list[float]:
    """The Newton tolerance of each state the curves solve from here on (samples, first
    samples, kept samples moved by Newton)."""
    seen: list[float] = []
    for module in (curve_start, limits, sample_cache):
        real = module.solve_state

        def solve(model, load, *args, real=real, **kw):
            seen.append((kw["options"] if "options" in kw else args[3]).tolerance)
            return real(model, load, *args, **kw)

        monkeypatch.setattr(module, "solve_state", solve)
    return seen


def test_a_first_sample_that_may_refuse_at_once_is_screened(monkeypatch, tmp_path):
    """The octant's first inflation sample in a check is solved to the screen's
    tolerance only. 2000 kPa is then refused after that one solve, with the sample's
    pressure and the bound within 0.1 % of those of the sample converged to the check's
    tolerance; a later check with the samples kept refuses it in the same line without
    solving a state. 100 kPa, which the bound after one sample does not refuse, has the
    first sample converged on from there to the check's tolerance, its pressure that of
    the sample solved so at once."""
    model = octant_ball(1, 1, nu=0.49)
    s1 = 1.0 + limits.STRETCH_STEP
    growth = model.chamber_rest_volume_mm3[0] * (s1**3 - 1.0)
    load = curve_start.chamber_load(model, 0, growth)
    check = SolverOptions(tolerance=limits.CHECK_TOLERANCE)
    exact = curve_start.first_sample(
        model, 0, np.array([1.0]), None, load, growth, check, model.make_solver(), "c"
    )
    p_exact = float(exact.pressure_kpa[0])
    slope_bound = p_exact / (s1 - 1.0) * (curve_peak.MAX_STRETCH - 1.0)

    def refusal(kpa: float, kept=None) -> tuple[str, list[str]]:
        told: list[str] = []
        with pytest.raises(SceneError) as info:
            pressure_check.check_pressures(
                model,
                np.array([[kpa]]),
                ["k"],
                model.make_solver(),
                SolverOptions(),
                progress=told.append,
                kept=kept,
            )
        return str(info.value), told

    seen = tolerances_solved(monkeypatch)
    line, told = refusal(2000.0, tmp_path / "kept.npz")
    assert seen == [curve_start.SCREEN_TOLERANCE] and len(told) == 1
    p1 = float(told[0].split("pressure ")[1].split(" kPa")[0])
    assert p1 == pytest.approx(p_exact, rel=1e-3)
    bound = float(line.split("which is at most ")[1].split(" kPa")[0])
    assert bound == pytest.approx(slope_bound, rel=1e-3)
    seen.clear()
    assert refusal(2000.0, tmp_path / "kept.npz")[0] == line
    assert seen == []
    line, told = refusal(100.0)
    assert line.startswith("k: 100 kPa is past this chamber's limit")
    assert seen[:2] == [curve_start.SCREEN_TOLERANCE, limits.CHECK_TOLERANCE]
    assert set(seen[1:]) == {limits.CHECK_TOLERANCE}
    p1 = float(told[0].split("pressure ")[1].split(" kPa")[0])
    assert p1 == pytest.approx(p_exact, rel=1e-3)


def test_a_screened_first_sample_that_cannot_be_converged_on_is_solved_afresh(monkeypatch):
    """When Newton finds no equilibrium from the loosely solved first sample (forced
    once), the sample is solved afresh to the check's tolerance, as without the screen,
    and the curve goes on: 100 kPa on the octant is refused in the same line as when the
    sample converged on from the loose one."""
    model = octant_ball(1, 1, nu=0.49)

    def refusal() -> str:
        with pytest.raises(SceneError) as info:
            pressure_check.check_pressures(
                model, np.array([[100.0]]), ["k"], model.make_solver(), SolverOptions()
            )
        return str(info.value)

    line = refusal()
    real, failed = curve_start.solve_state, []

    def flaky(model, load, *args, **kw):
        if args and args[1] is load and not failed:  # converging on from the loose sample
            failed.append(load)
            raise SolverError("chamber c: no equilibrium (forced)")
        return real(model, load, *args, **kw)

    monkeypatch.setattr(curve_start, "solve_state", flaky)
    seen = tolerances_solved(monkeypatch)
    assert refusal() == line
    assert failed and seen[:2] == [curve_start.SCREEN_TOLERANCE, limits.CHECK_TOLERANCE]


def test_a_failed_state_past_the_limit_is_named():
    """28 kPa on the octant (limit 27.0 kPa) passes the screen (linearized growth 0.7 V0)
    and Newton finds no equilibrium; `explain_failure` then names the limit in the
    check's line. Below the limit, the original error stands."""
    model = octant_ball(1, 1, nu=0.49)
    key = ["[actuation].pressure_kpa.c"]
    solver = model.make_solver()
    pressure_check.check_pressures(model, np.array([[28.0]]), key, solver, SolverOptions())
    load = Load.pressures([28.0])
    with pytest.raises(SolverError) as failed:
        solve_state(model, load, options=SolverOptions(load_steps=4), solver=solver)
    with pytest.raises(
        SceneError,
        match=r"^\[actuation\].pressure_kpa.c: 28 kPa is past "
        r"this chamber's limit pressure of 27.0 kPa ",
    ):
        pressure_check.explain_failure(model, load, key, solver, SolverOptions(), failed.value)
    original = SolverError("state 0: no equilibrium")
    with pytest.raises(SolverError, match="^state 0: no equilibrium$"):
        pressure_check.explain_failure(
            model, Load.pressures([10.0]), key, solver, SolverOptions(), original
        )


def test_time_budget_names_the_load_fraction():
    """A state past [solver].max_seconds fails with OutOfTime: one line with the load
    fraction reached and the chamber pressures there."""
    model = octant_ball(1, 1, nu=0.49)
    with pytest.raises(OutOfTime) as info:
        solve_state(
            model, Load.pressures([20.0]), options=SolverOptions(max_seconds=1e-9), label="state 0"
        )
    assert str(info.value) == (
        "state 0: stopped after 1e-09 s ([solver].max_seconds) at 0.000 of the load step "
        "(chambers: c 0 kPa); a chamber may be past its limit pressure (`fruit limits` "
        "computes it), or raise [solver].max_seconds"
    )
    assert info.value.fraction == 0.0


def test_time_budget_looks_one_factorization_ahead():
    """A Newton step is not started when the solver's last factorization, taken again,
    would end past the deadline: with a 30 s budget and a last factorization of 60 s the
    state stops at once (OutOfTime at 0.000); with one of 0 s it converges."""
    model = octant_ball(1, 1, nu=0.49)
    solver = model.make_solver("pcg")
    solver.factor_seconds = 60.0
    options = SolverOptions(max_seconds=30.0)
    with pytest.raises(OutOfTime) as info:
        solve_state(model, Load.pressures([5.0]), options=options, solver=solver)
    assert info.value.fraction == 0.0
    solver = model.make_solver("pcg")
    res = solve_state(model, Load.pressures([5.0]), options=options, solver=solver)
    assert res.iterations > 0 and solver.factor_seconds > 0.0


def test_progress_of_a_long_state(monkeypatch):
    """A state running past PROGRESS_SECONDS reports load fraction, Newton step and
    residual through `progress` (here every Newton step: PROGRESS_SECONDS = 0)."""
    monkeypatch.setattr(state, "PROGRESS_SECONDS", 0.0)
    model = octant_ball(1, 1, nu=0.49)
    told = []
    solve_state(
        model,
        Load.pressures([10.0]),
        options=SolverOptions(load_steps=2),
        label="state 3",
        progress=told.append,
    )
    assert told[0].startswith(
        "state 3: 50% of the load, Newton iteration 0, relative force residual "
    )
    assert told[0].endswith(" (tolerance 1e-06)")
    assert any(t.startswith("state 3: 100% of the load, Newton iteration 1, ") for t in told)


def test_c_library_output_is_caught(capfd):
    """What a C library writes to fd 1 or 2 inside `captured_output` is handed back, not
    shown."""
    with captured_output() as said:
        os.write(2, b"CHOLMOD warning: not positive definite\n")
        os.write(1, b"and on stdout\n")
    assert said.text == "CHOLMOD warning: not positive definite\nand on stdout\n"
    assert capfd.readouterr() == ("", "")


def test_cholmod_refusal_is_our_error_not_its_warning(capfd):
    """An indefinite matrix: cholespy's CHOLMOD warning never reaches fd 2; the
    factorization raises (the callers' fallback takes it)."""
    if linsolve._cholesky is None:
        pytest.skip("cholespy not installed")
    k = sp.csc_matrix(np.diag([1.0, -1.0, 2.0]))
    with pytest.raises(RuntimeError, match="not positive definite"):
        linsolve._cholesky(k)
    out = capfd.readouterr()
    assert "CHOLMOD" not in out.err + out.out


@pytest.mark.parametrize("value", ["0", "-1.5"])
def test_max_seconds_must_be_positive(tmp_path, value):
    text = f"[geometry]\npad_size_mm = [10.0, 10.0, 2.0]\n[solver]\nmax_seconds = {value}\n"
    with pytest.raises(
        SceneError,
        match=r"^s.toml: \[solver\].max_seconds: expected a time "
        r"budget > 0 s, got ",
    ):
        parse_scene(text, tmp_path / "s.toml")


@pytest.mark.slow
def test_fruit_limits_cli_and_simulate_refusal(tmp_path):
    """`fruit limits` on a gmsh ball (cavity 10 mm, outer 20 mm, size 8 mm, E = 100 kPa,
    nu = 0.45, default element, free): limits.json, pv.csv and pv.png; the limit
    pressure near the compressible radial solution's (nu = 0.45: 0.762 mu = 26.3 kPa;
    the coarse faceted ball within 5 %), a collapse under suction. Then `run_simulate`
    at 2000 kPa is refused in one line as soon as the curve levels off below it (a bound
    above the limit), nothing written."""
    scene = ball_scene(tmp_path, size=8.0, nu=0.45, p=2000.0)
    out = tmp_path / "lim"
    run_tetra(scene, None, out)
    info = run_limits(scene, out / "mesh.npz", out)
    saved = json.loads((out / "limits.json").read_text())
    assert saved == json.loads(json.dumps(info))
    cav = saved["chambers"]["c"]
    mu = 100 / (2 * 1.45)
    assert cav["limit_pressure_kpa"] == pytest.approx(
        radial_pressure(mu, 100 / 0.3, 1.83), rel=0.05
    )
    assert cav["collapse_pressure_kpa"] < 0 and cav["limit_volume_growth_mm3"] > 0
    assert saved["element"] == "p2" and saved["mesh"]["elements"] > 0
    rows = (out / "pv.csv").read_text().splitlines()
    assert rows[0] == "chamber,volume_growth_mm3,pressure_kpa" and len(rows) > 5
    growth = [float(r.split(",")[1]) for r in rows[1:]]
    assert growth == sorted(growth) and 0.0 in growth
    assert (out / "pv.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(SceneError) as refused:
        run_simulate(scene, out / "mesh.npz", None, tmp_path / "sim")
    line = str(refused.value)
    bound = float(line.split("which is at most ")[1].split(" kPa")[0])
    assert cav["limit_pressure_kpa"] < bound < 2000.0
    assert line == (
        f"[actuation].pressure_kpa.c: 2000 kPa is past this chamber's limit pressure, which "
        f"is at most {pressure_check.kpa(bound)} kPa (a bound: its pressure-volume curve "
        "levels off, and there is no equilibrium above its peak; `fruit limits` computes the "
        "limit); give `volume_growth_mm3` to follow the inflation past it"
    )
    assert not (tmp_path / "sim" / "states.npz").exists()
    # the two curves in two worker processes: the same limits.json, pv.csv and points
    run_limits(scene, out / "mesh.npz", tmp_path / "par", pool=CurveProcesses(2))
    again = json.loads((tmp_path / "par" / "limits.json").read_text())
    assert {**again, "seconds": 0} == {**saved, "seconds": 0}
    assert (tmp_path / "par" / "pv.csv").read_text() == (out / "pv.csv").read_text()


def test_curve_jobs_one_per_curve_and_as_many_as_the_memory_holds(monkeypatch):
    """`fruit limits --jobs`: one process without a pool; at most one worker per curve,
    every core by default, and no more workers than WORKER_BYTES_PER_DOF says the
    memory available holds (at least one)."""
    from fruitcli import memory
    from fruitcli.fem import curve_workers

    per = curve_workers.WORKER_BYTES_PER_DOF * 1000
    monkeypatch.setattr(curve_workers.os, "cpu_count", lambda: 8)
    monkeypatch.setattr(memory, "available_bytes", lambda: int(10 * per / memory.SHARE))
    assert curve_workers.curve_jobs(None, 7, 1000) == (1, "")
    assert curve_workers.curve_jobs(CurveProcesses(), 7, 1000) == (7, "")
    assert curve_workers.curve_jobs(CurveProcesses(3), 7, 1000) == (3, "")
    assert curve_workers.curve_jobs(CurveProcesses(), 20, 1000) == (8, "")
    monkeypatch.setattr(memory, "available_bytes", lambda: int(3.5 * per / memory.SHARE))
    assert curve_workers.curve_jobs(CurveProcesses(), 7, 1000) == (
        3,
        " (the memory available holds 3)",
    )
    monkeypatch.setattr(memory, "available_bytes", lambda: int(0.5 * per / memory.SHARE))
    assert curve_workers.curve_jobs(CurveProcesses(4), 7, 1000) == (
        1,
        " (the memory available holds 1)",
    )


def test_fruit_limits_refuses_a_scene_without_chambers(tmp_path):
    (tmp_path / "s.toml").write_text("[geometry]\npad_size_mm = [10.0, 10.0, 2.0]\n")
    res = CliRunner().invoke(
        cli, ["limits", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o")]
    )
    assert res.exit_code == 1
    assert res.output == (
        f"Error: {tmp_path / 's.toml'}: [[geometry.chamber]]: the scene has no chamber\n"
    )
    assert not (tmp_path / "o").exists()


def test_volume_growth_below_minus_the_rest_volume_is_refused():
    model = octant_ball(1, 1, nu=0.49)
    v0 = model.chamber_rest_volume_mm3[0]
    ok = Load(np.zeros(1), np.array([-0.5 * v0]), np.array([True]))
    pressure_check.check_growth(model, [ok])
    bad = Load(np.zeros(1), np.array([-2 * v0]), np.array([True]))
    with pytest.raises(
        SceneError,
        match=r"^\[actuation\].volume_growth_mm3.c: -\d+(\.\d+)? "
        r"mm\^3 would leave the chamber no volume \(its rest "
        r"volume is \d+(\.\d+)? mm\^3\): expected more than ",
    ):
        pressure_check.check_growth(model, [ok, bad])


def nested_octant_balls(nu=0.49):
    """Two hollow-ball octants (`octant_ball`, 1 cell, 1 layer) with one centre: ball c
    (A = 10, B = 20 mm) and ball d, half its size, inside c's cavity (no contact: d
    grows to 6.4 mm at its limit). Same shape, so the same limit pressure; d's cavity
    volume is c's / 8."""
    parts = [octant_ball(1, 1, nu=nu, a=a, b=2 * a) for a in (10.0, 5.0)]
    n0 = parts[0].n_nodes
    nodes = np.vstack([m.rest for m in parts])
    tets = np.vstack([parts[0].conn, parts[1].conn + n0])
    walls = [parts[0].chamber_tris[0], parts[1].chamber_tris[0] + n0]
    rollers = [
        (np.flatnonzero(np.abs(nodes[:, d]) < 1e-9), np.zeros(3), np.eye(3)[d] > 0)
        for d in range(3)
    ]
    return ContinuumModel.from_arrays(
        nodes,
        tets,
        material("neo-hookean", 100.0, nu),
        "p2",
        chambers={"c": walls[0], "d": walls[1]},
        prescribed=rollers,
    )


def test_chambers_together_along_pressure_ratios():
    """Two balls of one shape (`nested_octant_balls`): alone, each has the octant's limit
    pressure (0.8052 mu, see above); together along pressure ratios (1, 1) the curve's
    limit (the largest chamber pressure at the peak of the volume sum_k r_k V_k) is the
    same; along (1, 0.5) ball c reaches its limit while d holds half of it, so the limit
    is c's again, within 1 %. The pressures stay on the ratio line."""
    model = nested_octant_balls()
    mu = model.material.shear_modulus_kpa
    alone = [limits.follow(model, k).limit_pressure_kpa for k in (0, 1)]
    assert alone == pytest.approx([0.8052 * mu] * 2, rel=0.01)
    for ratio in ((1.0, 1.0), (1.0, 0.5)):
        curve = limits.follow(model, np.array(ratio))
        assert curve.name == limits.TOGETHER
        assert curve.limit_pressure_kpa == pytest.approx(alone[0], rel=0.01)
    res = solve_state(model, Load.together([1.0, 0.5], 100.0))
    assert res.pressure_kpa[1] == pytest.approx(0.5 * res.pressure_kpa[0], rel=1e-12)
    v = model.chamber_rest_volume_mm3
    assert res.chamber_volume_mm3 @ [1.0, 0.5] == pytest.approx(v @ [1.0, 0.5] + 100.0, rel=1e-5)


def test_a_state_past_the_limit_together_is_refused():
    """`check_together` on the nested balls (limit 27.0 kPa alone and together along
    (1, 1)): a state with both at 28 kPa is refused in one line naming both keys and
    the limit along its ratios; (20, 10) kPa is reachable; a state with one chamber
    pressurised is left to the check of that chamber alone."""
    model = nested_octant_balls()
    keys = ["[actuation].pressure_kpa.c", "[actuation].pressure_kpa.d"]
    solver = model.make_solver()
    compliance = pressure_check.rest_compliance(model, solver)
    assert compliance.shape == (2, 2) and abs(compliance[0, 1]) < 1e-9 * compliance[0, 0]
    options = SolverOptions(tolerance=limits.CHECK_TOLERANCE)
    with pytest.raises(SceneError) as info:
        pressure_check.check_together(
            model, np.array([[5.0, 0.0], [28.0, 28.0]]), keys, solver, options, compliance, 0.0
        )
    line = str(info.value)
    lim = float(line.split("pressure is ")[1].split(" kPa")[0])
    assert lim == pytest.approx(0.8052 * model.material.shear_modulus_kpa, rel=0.01)
    assert line == (
        "state 1: [actuation].pressure_kpa.c 28 kPa, [actuation].pressure_kpa.d 28 kPa: "
        "together these are past the chambers' limit along these ratios, where the "
        f"largest chamber pressure is {pressure_check.kpa(lim)} kPa; no equilibrium above it; "
        "lower them or give `volume_growth_mm3`"
    )
    for ok in ([[20.0, 10.0]], [[28.0, 0.0]]):
        pressure_check.check_together(model, np.array(ok), keys, solver, options, compliance, 0.0)


@pytest.mark.parametrize(
    ("extra", "line"),
    [
        (
            "[reduced]\npressure_range_kpa = [nan, 10.0]",
            "[reduced].pressure_range_kpa: expected a list of 2 numbers, got [nan, 10.0]",
        ),
        (
            "[actuation]\npressure_kpa = { c = [1.0, nan] }",
            "[actuation].pressure_kpa.c: expected a non-empty list of numbers, one per state",
        ),
        (
            "[actuation]\nvolume_growth_mm3 = { c = [nan] }",
            "[actuation].volume_growth_mm3.c: expected a non-empty list of numbers, one per state",
        ),
        (
            "[solver]\nmax_seconds = 0",
            "[solver].max_seconds: expected a time budget > 0 s, got 0.0",
        ),
        ("[solver]\nmax_seconds = nan", "[solver].max_seconds: expected a finite number, got nan"),
        (
            "[solver]\ntolerance = 0",
            "[solver].tolerance: expected 0 < tolerance < 1 (a residual relative to the load), "
            "got 0.0",
        ),
        (
            "[solver]\ntolerance = -1e-6",
            "[solver].tolerance: expected 0 < tolerance < 1 (a residual relative to the load), "
            "got -1e-06",
        ),
        ("[solver]\nmax_iterations = 0", "[solver].max_iterations: expected >= 1, got 0"),
        ("[solver]\nfirst_steps = 0", "[solver].first_steps: expected >= 1, got 0"),
        (
            "[solver]\ndisplacement_tolerance_mm = -1",
            "[solver].displacement_tolerance_mm: expected >= 0, got -1.0",
        ),
    ],
)
@pytest.mark.parametrize("command", ["limits", "simulate"])
def test_bad_limit_inputs_are_one_line(tmp_path, command, extra, line):
    """A NaN in a pressure range or table, a budget <= 0 or NaN, a solver option that
    would make a state diverge or never end (a tolerance <= 0, no Newton iteration or
    load step, a negative displacement tolerance): `fruit limits` and `fruit simulate`
    stop with one line naming the key, exit 1, no output folder."""
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[geometry]\npad_size_mm = [10.0, 10.0, 2.0]\n[[geometry.chamber]]\nname = "c"\n'
        "ellipsoid = {center_mm = [0.0, 0.0, 1.0], radii_mm = [2.0, 2.0, 0.5]}\n" + extra + "\n"
    )
    res = CliRunner().invoke(cli, [command, str(scene), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert res.output == f"Error: {scene.name}: {line}\n"
    assert not (tmp_path / "o").exists()


def test_the_limits_stage_is_planned_near_a_limit(tmp_path):
    """The planner runs `limits` when a pressure reaches NEAR_SHEAR_FRACTION of the shear
    modulus (E = 100 kPa, nu = 0.45: mu = 34.5 kPa, the threshold 17.2 kPa)."""
    from fruitcli.fem.limits_stage import near_limit

    assert near_limit(ball_scene(tmp_path, nu=0.45, p=20.0)) == (
        True,
        "pressures up to 20 kPa, 0.58 mu: near a chamber's limit pressure, checked against it once",
    )
    assert near_limit(ball_scene(tmp_path, nu=0.45, p=-10.0)) == (
        False,
        "pressures up to 10 kPa, under 0.5 mu = 17.2 kPa: simulate checks them itself",
    )


@pytest.mark.slow
def test_limits_stage_follows_to_the_limit_and_simulate_reuses_it(tmp_path):
    """The limits stage on the gmsh ball (size 8 mm, nu = 0.45) at 20 kPa: the curve is
    followed on to its limit (the radial solution's 26.3 kPa within 5 %, as `fruit
    limits`), limits.json, pv.csv and pv.png written; simulate given its folder follows
    no curve of its own. At 2000 kPa the stage refuses in one line, nothing written."""
    from fruitcli.fem.limits_stage import run_limits_stage

    scene = ball_scene(tmp_path, size=8.0, nu=0.45, p=20.0)
    run_tetra(scene, None, tmp_path / "tetra")
    mesh = tmp_path / "tetra" / "mesh.npz"
    info = run_limits_stage(scene, mesh, tmp_path / "limits")
    cav = info["chambers"]["c"]
    assert cav["followed"] == ["inflation"] and cav["collapse_pressure_kpa"] is None
    mu = 100 / (2 * 1.45)
    assert cav["limit_pressure_kpa"] == pytest.approx(
        radial_pressure(mu, 100 / 0.3, 1.83), rel=0.05
    )
    assert info["together"] is None
    assert json.loads((tmp_path / "limits" / "limits.json").read_text()) == json.loads(
        json.dumps(info)
    )
    assert (tmp_path / "limits" / "pv.png").exists()
    told = []
    run_simulate(
        scene, mesh, None, tmp_path / "sim", progress=told.append, limits_dir=tmp_path / "limits"
    )
    assert not any(t.startswith("limits:") for t in told)
    assert (tmp_path / "sim" / "states.npz").exists()
    with pytest.raises(SceneError, match=r"^\[actuation\].pressure_kpa.c: 2000 kPa is past"):
        run_limits_stage(ball_scene(tmp_path, size=8.0, nu=0.45, p=2000.0), mesh, tmp_path / "l2")
    assert not (tmp_path / "l2").exists()


def test_a_line_search_that_rejects_every_trial_fails_cleanly(monkeypatch):
    """When every trial step of the line search is rejected before its evaluation (a
    spurious dilatation, `ContinuumModel.dilatation_step`), Newton ends with a named
    SolverError, not an internal error (the state had no trial to report)."""
    from fruitcli.fem import continuum

    monkeypatch.setattr(continuum, "DILATATION_STEP", 1e-12)
    model = octant_ball(1, 1, nu=0.49)
    options = SolverOptions(max_subdivisions=0)
    with pytest.raises(SolverError, match="no equilibrium"):
        solve_state(model, Load.pressures([5.0]), options=options)


def failing_once_at(stretch: float, error: Exception):
    """(a `solve_state` that raises `error` once, at chamber 0's mean stretch `stretch`,
    the list it notes that failure in; clear the list to fail again): put it in place
    of the curves' own with `solving_with`."""
    real = limits.solve_state
    failed = []

    def solve(model, load, *args, **kw):
        v = load.volume_growth_mm3[0] / model.chamber_rest_volume_mm3[0] + 1.0
        if abs(v - stretch**3) < 1e-9 and not failed:
            failed.append(v)
            raise error
        return real(model, load, *args, **kw)

    return solve, failed


def solving_with(monkeypatch, solve) -> None:
    """Have the curves' samples (`limits`) and first samples (`curve_start`) solved by
    `solve` instead of `solve_state`."""
    monkeypatch.setattr(limits, "solve_state", solve)
    monkeypatch.setattr(curve_start, "solve_state", solve)


def test_a_check_going_on_to_the_limit_keeps_a_pressure_it_reached(monkeypatch):
    """The limits stage's check (`check_pressures` with a `found` list) goes on past the
    pressure asked (20 kPa, reached at mean stretch 1.3) to the limit. A sample past it
    that runs out of its time (forced once, at 1.5: a slower machine) is tried again at
    half the step, as `fruit limits` does, and the curve reaches the same limit; the
    pressure asked, which was reached, is not refused."""
    model = octant_ball(1, 1, nu=0.49)
    whole = limits.follow(model, 0)
    slow, failed = failing_once_at(1.5, OutOfTime("chamber c: out of time (forced)", 0.5))
    solving_with(monkeypatch, slow)
    found = []
    pressure_check.check_pressures(
        model,
        np.array([[20.0]]),
        ["k"],
        model.make_solver(),
        SolverOptions(),
        screen=0.0,
        found=found,
    )
    assert failed and len(found) == 1
    ((direction, curve),) = found
    assert direction == 1 and not curve.failed
    assert curve.limit_pressure_kpa == pytest.approx(whole.limit_pressure_kpa, rel=2e-3)


def test_a_first_sample_without_equilibrium_is_refused_as_not_holding(monkeypatch):
    """When the check's first sample (from rest) finds no equilibrium (forced here; a
    body too soft for its own weight in the stability study), the pressure is refused in
    one line that says so, not as a limit: no pressure was reached beyond rest. A curve
    from the body's `Start` whose first sample finds none from the start's linear
    response (forced once) finds it from the start in load steps."""
    model = octant_ball(1, 1, nu=0.49)
    error = SolverError("chamber c: no equilibrium (forced)")
    flaky, failed = failing_once_at(1.1, error)
    solving_with(monkeypatch, flaky)
    with pytest.raises(SceneError) as info:
        pressure_check.check_pressures(
            model, np.array([[5.0]]), ["k"], model.make_solver(), SolverOptions(), screen=0.0
        )
    assert failed
    assert str(info.value) == (
        "k: 5 kPa was not reached: following this chamber's inflation by volume control "
        "found no equilibrium at its first sample (no equilibrium at 1.33 V0): the body "
        "may not hold under its other loads (its weight, jigs); check them, or lower the "
        "pressure"
    )
    failed.clear()
    solver = model.make_solver()
    start = curve_start.start_state(model, solver, SolverOptions())
    curve = limits.follow(model, 0, solver=solver, start=start)
    assert failed and curve.limit_pressure_kpa is not None


def test_inflation_samples_start_from_the_last_one_and_suction_from_the_secant(monkeypatch):
    """An inflation curve's samples from the third on start from the last sample (no
    secant over the kept states: `_start_from_last`); the second starts from the first
    state's tangent; a suction curve keeps the secant from its third sample on."""

    model = octant_ball(1, 1, nu=0.49)
    starts = []
    secant, tangent = state.history_guess, state.sensitivity_guess

    def spy_secant(history, x_start, load):
        guess = secant(history, x_start, load)
        starts.append("secant" if guess is not None else None)
        return guess

    def spy_tangent(solver, x_start, load):
        guess = tangent(solver, x_start, load)
        if guess is not None:
            starts[-1] = "tangent"
        return guess

    monkeypatch.setattr(state, "history_guess", spy_secant)
    monkeypatch.setattr(state, "sensitivity_guess", spy_tangent)
    up = limits.follow(model, 0, 1)
    assert up.limit_pressure_kpa is not None
    assert starts[:2] == [None, "tangent"] and set(starts[2:]) == {None}
    starts.clear()
    limits.follow(model, 0, -1)
    assert starts[:2] == [None, "tangent"] and set(starts[2:]) == {"secant"}


def test_a_chamber_wall_that_is_not_closed_is_refused_in_one_line():
    """A chamber whose wall triangles in the mesh leave an edge open (here an octahedron
    with one face missing) has no volume: one MeshError line naming the chamber."""
    from fruitcli.errors import MeshError
    from fruitcli.fem.stage import check_closed_walls

    octahedron = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    )
    check_closed_walls({"c": octahedron})
    with pytest.raises(MeshError) as info:
        check_closed_walls({"c": octahedron[1:]})
    assert str(info.value).startswith(
        "[[geometry.chamber]] 'c': its wall in the mesh is not closed (3 edges not shared"
    )
    assert "\n" not in str(info.value)
    with pytest.raises(MeshError, match="'c': the mesh has no wall for it"):
        check_closed_walls({"c": octahedron[:0]})


def test_a_failed_sample_is_tried_again_with_half_the_step(monkeypatch):
    """`follow(..., halvings=1)`: a sample that finds no equilibrium (here forced once, at
    mean stretch 1.3) is tried again half as far from the last one; the curve goes on in
    the shorter steps to the same limit. Without halvings the curve ends there, and the
    check refuses the pressure asked in one line (no equilibrium beyond the last)."""
    model = octant_ball(1, 1, nu=0.49)
    flaky, failed = failing_once_at(1.3, SolverError("chamber c: no equilibrium (forced)"))
    whole = limits.follow(model, 0)
    solving_with(monkeypatch, flaky)
    curve = limits.follow(model, 0, halvings=1)
    assert failed
    stretch = (np.array(curve.growth_mm3) / curve.rest_volume_mm3 + 1.0) ** (1 / 3)
    assert np.allclose(stretch[:4], [1.0, 1.1, 1.2, 1.25], atol=2e-3)
    assert curve.limit_pressure_kpa == pytest.approx(whole.limit_pressure_kpa, rel=2e-3)
    failed.clear()
    ended = limits.follow(model, 0)
    assert ended.failed and ended.end == "no equilibrium at 2.20 V0"
    failed.clear()
    with pytest.raises(SceneError) as info:
        pressure_check.check_pressures(
            model, np.array([[26.0]]), ["k"], model.make_solver(), SolverOptions(), screen=0.0
        )
    assert str(info.value).startswith(
        "k: 26 kPa was not reached: following this chamber's inflation by volume control "
        "found no equilibrium beyond "
    )


@pytest.mark.slow
def test_the_stage_check_in_worker_processes_finds_what_one_process_finds():
    """`check_pressures` with a `found` list (the limits stage) on the nested balls, in
    one process and over two worker processes: at (20, 10) kPa the same curves (each
    chamber's inflation on to its limit, then the two together), the pressures to the
    check's four digits; at (28, 28) kPa the same refusal line."""
    model = nested_octant_balls()
    keys = ["[actuation].pressure_kpa.c", "[actuation].pressure_kpa.d"]

    def check(pressures, jobs):
        found: list = []
        pool = CurveProcesses(jobs) if jobs > 1 else None
        solver = model.make_solver()
        options = SolverOptions()
        pressure_check.check_pressures(
            model, np.array(pressures), keys, solver, options, screen=0.0, found=found, pool=pool
        )
        return [(d, c.name, np.array(c.pressure_kpa), c.limit_pressure_kpa) for d, c in found]

    one, two = check([[20.0, 10.0]], 1), check([[20.0, 10.0]], 2)
    assert [(d, name) for d, name, *_ in one] == [(1, "c"), (1, "d"), (1, limits.TOGETHER)]
    assert [(d, name) for d, name, *_ in two] == [(d, name) for d, name, *_ in one]
    for (_, _, p1, lim1), (_, _, p2, lim2) in zip(one, two, strict=True):
        assert p2 == pytest.approx(p1, rel=1e-4) and lim2 == pytest.approx(lim1, rel=1e-4)
    lines = []
    for jobs in (1, 2):
        with pytest.raises(SceneError) as refused:
            check([[28.0, 28.0]], jobs)
        lines.append(str(refused.value))
    assert lines[0] == lines[1] and lines[0].startswith("[actuation].pressure_kpa.c: 28 kPa")
