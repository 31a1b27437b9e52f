"""Gravity is a load: a scene whose only load is gravity on a held body is planned with
the FEM, and its states show the sag; gravity on a free body, a massless body or a zero
vector is no load."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.scene import has_deformation, parse_scene
from fruitcli.workflow import planner

L_MM, B_MM, H_MM = 60.0, 10.0, 6.0  # the cantilever: length, width, height
E_KPA, NU, RHO = 5000.0, 0.3, 1070.0

CANTILEVER = f"""
[scene]
name = "cantilever"
[geometry]
pad_size_mm = [{L_MM}, {B_MM}, {H_MM}]
[grid]
count = [2, 1]
spacing_x_mm = {L_MM}
[mesh]
size_mm = 2.0
[fem]
element = "p2"
[material]
young_modulus_kpa = {E_KPA}
poisson_ratio = {NU}
density_kg_m3 = {RHO}
[gravity]
vector_m_s2 = [0.0, 0.0, -9.81]
[[fixed]]                   # the end face x = -L/2 clamped
box_mm = [{-L_MM / 2 - 1}, -6.0, -1.0, {-L_MM / 2 + 0.01}, 6.0, 7.0]
"""


def beam_sag_mm() -> float:
    """Tip sag of a cantilever under its own weight: Euler-Bernoulli q L^4 / (8 E I)
    plus Timoshenko's shear q L^2 / (2 kappa G A) (1 % here, h / L = 0.1)."""
    q = RHO * 9.81 * 1e-9 * B_MM * H_MM  # N/mm (kg/m^3 m/s^2 = N/m^3 = 1e-9 N/mm^3)
    e = E_KPA * 1e-3  # N/mm^2
    bending = q * L_MM**4 / (8 * e * B_MM * H_MM**3 / 12)
    kappa = 10 * (1 + NU) / (12 + 11 * NU)
    shear = q * L_MM**2 / (2 * kappa * e / (2 * (1 + NU)) * B_MM * H_MM)
    return bending + shear


@pytest.mark.parametrize(
    "old, new",
    [
        (CANTILEVER[CANTILEVER.index("[[fixed]]") :], ""),  # a free body would only fall
        ("density_kg_m3 = 1070.0", "density_kg_m3 = 0.0"),  # no mass
        ("vector_m_s2 = [0.0, 0.0, -9.81]", "vector_m_s2 = [0.0, 0.0, 0.0]"),
        ("[gravity]\nvector_m_s2 = [0.0, 0.0, -9.81]\n", ""),  # not declared
    ],
)
def test_gravity_without_a_held_massive_body_is_no_load(tmp_path, old, new):
    assert old in CANTILEVER
    scene = parse_scene(CANTILEVER.replace(old, new), tmp_path / "s.toml")
    assert not has_deformation(scene)
    steps = {s.stage: s for s in planner.plan(scene, tmp_path / "out")}
    assert steps["simulate"].action == "not needed"


def test_a_cantilever_under_gravity_alone_is_simulated_and_sags(tmp_path):
    scene = parse_scene(CANTILEVER, tmp_path / "s.toml")
    assert has_deformation(scene)
    steps = {s.stage: s for s in planner.run(scene, tmp_path / "out")}
    assert steps["tetra"].action == steps["simulate"].action == "run"
    assert "gravity on the held body" in steps["simulate"].reason
    st = np.load(tmp_path / "out" / "simulate" / "states.npz")
    rest, u = st["rest_nodes"], st["displacement_mm"][0]
    tip = np.abs(rest[:, 0] - L_MM / 2) < 1e-9
    sag = u[tip, 2].mean()  # along gravity: negative z
    assert sag < 0
    assert -sag == pytest.approx(beam_sag_mm(), rel=0.03)  # 1.146 mm
    # the tip taxel (top face, x = L/2) follows the body down by the same sag
    taxel = st["taxels_mm"][0][1] - [L_MM / 2, 0.0, H_MM]
    assert taxel[2] == pytest.approx(sag, rel=0.01)
