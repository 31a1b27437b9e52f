"""Numerical stability study: the FEM on stiff and extreme cases.

Each case is a small structured body (so the whole study runs in seconds) pushed to an
extreme: E from 1 kPa to 1 GPa, nu from 0 to 0.499, a chamber pressure ramped until
elements would invert, jig stiffness from 1e-3 to 1e6 N/mm, a sliver tet, a body with no
support (the paper's model); and with the default element and material (p2,
neo-Hookean): nu up to 0.4999, a chamber pressure past the inflation's limit point
(pressure control fails there, naming it) and the same inflation followed under volume
control. Two realistic bodies meshed by gmsh on the default element, a thick sphere
(cavity 10 mm, outer 20 mm, size 3 mm, free, nu = 0.45) and the default Fruit (the
bundled `fruit-breathing` scene: its mesh, material, gravity and base; chamber c1
pressurised, the others at rest), are pressurised from 5 kPa to 2000 kPa and down to
-500 kPa, and taken to E = 1 kPa, E = 1 GPa and nu = 0.4999 at 5 kPa; each state is
checked against the chambers' limit and collapse pressures first (`fruitcli.fem.limits`)
within a budget of 60 s per row (REALISTIC_SECONDS: the mesh, the check and the state
together, the state's [solver] max_seconds being what is left). Each row says whether it
converged or names the failure in one line, with
Newton iterations, load-step subdivisions, final residual, max displacement, min det F
and time. No NaN reaches a row: a non-finite result is itself a named failure.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import NotRequired, TypedDict

import numpy as np

from fruitcli.errors import FruitError

BEAM_MM = (40.0, 8.0, 8.0)
BEAM_CELLS = (10, 2, 2)
HOLLOW_MM = (30.0, 30.0, 30.0)  # a cube with a centred cubic cavity of 10 mm
HOLLOW_CELLS = (6, 6, 6)
CAVITY_LO_MM = (10.0, 10.0, 10.0)
CAVITY_HI_MM = (20.0, 20.0, 20.0)
DENSITY = 1070.0
GRAVITY = (0.0, 0.0, -9.81)


class ModelChoice(TypedDict):
    """A case's element and material (scene [fem] element and material)."""

    element: str
    material: str


class StabilityRow(TypedDict):
    """One row of the table: what `run_case` measured (HEADER's columns, in that order)."""

    group: str
    case: str
    status: str
    iterations: int
    subdivisions: int
    residual: float | None
    max_disp_mm: float | None
    min_det_f: float | None
    seconds: float
    note: str
    tip_deflection_mm: NotRequired[float]  # the beam cases'


@dataclass(frozen=True)
class Case:
    """One stability case: `group` (what is swept), `name`, and its parameters."""

    group: str
    name: str
    kind: str  # beam_gravity, hollow_pressure, jig, sliver, free_pressure
    E_kpa: float = 100.0
    nu: float = 0.3
    pressure_kpa: float = 0.0
    stiffness_n_per_mm: float = 10.0
    element: str = "p1"
    material: str = "corotational"
    volume_growth: float = 0.0  # times the cavity's rest volume (volume control)
    size_mm: float = 3.0  # gmsh mesh size of the realistic bodies


def default_cases() -> list[Case]:
    cases = [
        Case("E", f"E = {e:g} kPa", "beam_gravity", E_kpa=e)
        for e in (1.0, 10.0, 100.0, 1e3, 1e4, 1e5, 1e6)
    ]
    cases += [
        Case("nu", f"nu = {nu:g}", "beam_gravity", E_kpa=100.0, nu=nu)
        for nu in (0.0, 0.3, 0.45, 0.49, 0.499)
    ]
    cases += [
        Case("pressure", f"p = {p:g} kPa", "hollow_pressure", pressure_kpa=p)
        for p in (5.0, 20.0, 50.0, 100.0, 200.0, 400.0)
    ]
    cases += [
        Case("jig", f"k = {k:g} N/mm", "jig", stiffness_n_per_mm=k)
        for k in (1e-3, 1e-1, 10.0, 1e3, 1e6)
    ]
    p2 = ModelChoice(element="p2", material="neo-hookean")
    cases += [
        Case("nu, p2", f"nu = {nu:g} (p2)", "beam_gravity", nu=nu, **p2)
        for nu in (0.3, 0.45, 0.49, 0.499, 0.4999)
    ]
    cases += [
        Case("pressure, p2", f"p = {p:g} kPa (p2)", "hollow_pressure", pressure_kpa=p, **p2)
        for p in (5.0, 20.0, 50.0, 100.0)
    ]
    cases += [
        Case("volume, p2", f"growth {g:g} V0 (p2)", "hollow_pressure", volume_growth=g, **p2)
        for g in (0.5, 1.0, 2.0)
    ]
    for group, kind, tag, nu in (
        ("sphere, gmsh", "gmsh_sphere", "sphere", 0.45),
        ("fruit, gmsh", "gmsh_fruit", "fruit", FRUIT_NU),
    ):
        cases += [
            Case(group, f"p = {p:g} kPa ({tag})", kind, pressure_kpa=p, nu=nu, **p2)
            for p in (5.0, 20.0, 2000.0, -20.0, -500.0)
        ]
        cases += [
            Case(
                group,
                f"E = {e:g} kPa, p = 5 kPa ({tag})",
                kind,
                E_kpa=e,
                pressure_kpa=5.0,
                nu=nu,
                **p2,
            )
            for e in (1.0, 1e6)
        ]
        cases.append(
            Case(group, f"nu = 0.4999, p = 5 kPa ({tag})", kind, pressure_kpa=5.0, nu=0.4999, **p2)
        )
    cases += [
        Case("sliver", "one sliver tet", "sliver"),
        Case("free", "no support, chamber at 10 kPa", "free_pressure", pressure_kpa=10.0),
    ]
    return cases


def _build(
    case: Case,
    nodes: np.ndarray,
    tets: np.ndarray,
    chambers: dict[str, np.ndarray] | None = None,
    fixed_where: tuple[int, float] | None = None,
    density_kg_m3: float = 0.0,
    gravity_m_s2: tuple[float, float, float] | None = None,
):
    """The case's model: the paper's `Model` (p1, corotational) or the hyperelastic one
    on the case's element (quadratic meshes built from the linear one here). Nodes with
    coordinate `fixed_where` = (axis, value) are held."""
    from fruitcli.fem.corotational_model import Model

    def held(x: np.ndarray):
        return (
            None
            if fixed_where is None
            else np.flatnonzero(np.abs(x[:, fixed_where[0]] - fixed_where[1]) < 1e-9)
        )

    from fruitcli.fem.materials.models import MATERIAL_MODELS

    if MATERIAL_MODELS[case.material].corotational:
        return Model.from_arrays(
            nodes,
            tets,
            case.E_kpa,
            case.nu,
            chambers=chambers,
            fixed_nodes=held(nodes),
            density_kg_m3=density_kg_m3,
            gravity_m_s2=gravity_m_s2,
        )
    from fruitcli.fem.continuum import ContinuumModel
    from fruitcli.fem.elements.quadratic import quadratic_mesh
    from fruitcli.fem.materials.build import material

    names = list(chambers or {})
    walls = [pressure_outward(nodes, w) for w in (chambers or {}).values()]
    if case.element != "p1":
        nodes, tets, walls = quadratic_mesh(nodes, tets, walls)
    return ContinuumModel.from_arrays(
        nodes,
        tets,
        material(case.material, case.E_kpa, case.nu),
        case.element,
        chambers=dict(zip(names, walls, strict=True)),
        fixed_nodes=held(nodes),
        density_kg_m3=density_kg_m3,
        gravity_m_s2=gravity_m_s2,
    )


def pressure_outward(nodes: np.ndarray, tris: np.ndarray) -> np.ndarray:
    from fruitcli.fem.loads.pressure import orient_outward

    return orient_outward(nodes, np.asarray(tris, np.int64))


def _beam(case: Case):
    from fruitcli.fem.meshing.grid import structured_box
    from fruitcli.fem.state_load import Load

    nodes, tets = structured_box((0.0, 0.0, 0.0), BEAM_MM, BEAM_CELLS)
    model = _build(
        case, nodes, tets, density_kg_m3=DENSITY, gravity_m_s2=GRAVITY, fixed_where=(0, 0.0)
    )
    return model, Load.pressures([], gravity=1.0)


def _hollow(case: Case, free: bool = False):
    from fruitcli.fem.meshing.grid import structured_box_with_cavity
    from fruitcli.fem.state_load import Load

    nodes, tets, cavity = structured_box_with_cavity(
        (0.0,) * 3, HOLLOW_MM, HOLLOW_CELLS, CAVITY_LO_MM, CAVITY_HI_MM
    )
    model = _build(
        case, nodes, tets, chambers={"c": cavity}, fixed_where=None if free else (2, 0.0)
    )
    if case.volume_growth:
        growth = case.volume_growth * model.chamber_rest_volume_mm3
        return model, Load(np.zeros(1), growth, np.ones(1, bool), 1.0, 1.0)
    return model, Load.pressures([case.pressure_kpa])


def _jig(case: Case):
    from fruitcli.fem.corotational_model import Model
    from fruitcli.fem.loads.springs import Jig
    from fruitcli.fem.meshing.grid import structured_box
    from fruitcli.fem.state_load import Load
    from fruitcli.fem.units import spring_mn_per_mm

    nodes, tets = structured_box((0.0, 0.0, 0.0), BEAM_MM, BEAM_CELLS)
    fixed = np.flatnonzero(nodes[:, 0] < 1e-9)
    tip = np.flatnonzero(nodes[:, 0] > BEAM_MM[0] - 1e-9)
    jig = Jig(
        tip,
        spring_mn_per_mm(case.stiffness_n_per_mm),
        rotate_deg=30.0,
        axis=(0.0, 0.0, 1.0),
        pivot_mm=(0.0, BEAM_MM[1] / 2, 0.0),
    )
    model = Model.from_arrays(nodes, tets, case.E_kpa, case.nu, fixed_nodes=fixed, jigs=[jig])
    return model, Load.pressures([], jig=1.0)


def _sliver(case: Case):
    from fruitcli.fem.corotational_model import Model
    from fruitcli.fem.state_load import Load

    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1e-4]], float)
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4], [0, 1, 2, 4]])
    model = Model.from_arrays(nodes, tets, case.E_kpa, case.nu, fixed_nodes=[0, 1, 2])
    return model, Load.pressures([])


SPHERE_SCENE = """
[geometry]
solid = "ball.stl"
[[geometry.chamber]]
name = "cavity"
ellipsoid = {{center_mm = [0.0, 0.0, 0.0], radii_mm = [10.0, 10.0, 10.0]}}
[mesh]
size_mm = {size}
[material]
young_modulus_kpa = {e}
poisson_ratio = {nu}
"""


REALISTIC_SECONDS = 60.0
"""Time budget (s) of a realistic body's row: mesh, check and state together."""

ROW_MARGIN_SECONDS = 3.0
"""Of a realistic row's budget, the time kept back for a state's last Newton step to end
(a factorization under way is not interrupted: the Fruit's take about 1.5 s)."""

FRUIT_SCENE = "fruit-breathing"
"""The bundled scene whose body, mesh, material, gravity and base the Fruit rows use."""

FRUIT_NU = 0.49
"""The Fruit's Poisson ratio in the bundled scene (the rows other than the nu row)."""


def _gmsh_sphere(case: Case):
    """The thick sphere meshed by gmsh (`fruitcli.fem.stage.run_tetra`) in a temporary
    folder, its model on the default element and material."""
    import tempfile
    from pathlib import Path

    import trimesh

    from fruitcli.fem import io
    from fruitcli.fem.stage import build_model, run_tetra
    from fruitcli.fem.state_load import Load
    from fruitcli.scene import parse_scene

    with tempfile.TemporaryDirectory() as tmp:
        trimesh.creation.icosphere(3, 20.0).export(Path(tmp) / "ball.stl")
        text = SPHERE_SCENE.format(size=case.size_mm, e=case.E_kpa, nu=case.nu)
        scene = parse_scene(text, Path(tmp) / "sphere.toml")
        run_tetra(scene, None, Path(tmp) / "mesh")
        model = build_model(scene, io.load_mesh(Path(tmp) / "mesh" / "mesh.npz"))
    return model, Load.pressures([case.pressure_kpa])


def _set_line(text: str, key: str, value: str) -> str:
    """`text` (a TOML scene) with the line assigning `key` set to `key = value`."""
    import re

    line = re.compile(rf"^{re.escape(key)}\s*=.*$", re.M)
    if not line.search(text):
        raise FruitError(f"{FRUIT_SCENE}: no `{key} = ...` line to set")
    return line.sub(lambda _: f"{key} = {value}", text, count=1)


def _gmsh_fruit(case: Case):
    """The default Fruit (bundled FRUIT_SCENE exported to a temporary folder, its stages
    run up to the mesh) with the case's material and chamber c1 at the case's pressure
    (the other chambers at rest), gravity and base as in the scene."""
    import tempfile
    from pathlib import Path

    from fruitcli.bundled import export_scene
    from fruitcli.fem import io
    from fruitcli.fem.stage import build_model, state_loads
    from fruitcli.scene import load_scene
    from fruitcli.workflow import planner

    with tempfile.TemporaryDirectory() as tmp:
        path = export_scene(FRUIT_SCENE, Path(tmp))
        text = _set_line(path.read_text(), "young_modulus_kpa", f"{case.E_kpa!r}")
        text = _set_line(text, "poisson_ratio", f"{case.nu!r}")
        text = _set_line(
            text, "pressure_kpa", f"{{ c1 = [{case.pressure_kpa!r}], c2 = [0.0], c3 = [0.0] }}"
        )
        path.write_text(text)
        scene = load_scene(path)
        planner.run(scene, Path(tmp) / "out", until="tetra")
        model = build_model(scene, io.load_mesh(Path(tmp) / "out" / "tetra" / "mesh.npz"))
    return model, state_loads(scene, model.chamber_names)[0]


REALISTIC = ("gmsh_sphere", "gmsh_fruit")
"""The case kinds of the realistic bodies (meshed by gmsh, checked against the limits)."""

BUILDERS = {
    "beam_gravity": _beam,
    "gmsh_sphere": _gmsh_sphere,
    "gmsh_fruit": _gmsh_fruit,
    "hollow_pressure": _hollow,
    "jig": _jig,
    "sliver": _sliver,
    "free_pressure": lambda c: _hollow(c, free=True),
}


def run_case(case: Case) -> StabilityRow:
    """Solve one case; never raises: failures become a one-line `status`."""
    from fruitcli.fem.solver.options import SolverOptions
    from fruitcli.fem.solver.state import solve_state

    row: StabilityRow = {
        "group": case.group,
        "case": case.name,
        "status": "converged",
        "iterations": 0,
        "subdivisions": 0,
        "residual": None,
        "max_disp_mm": None,
        "min_det_f": None,
        "seconds": 0.0,
        "note": "",
    }
    t0 = time.perf_counter()
    try:
        model, load = BUILDERS[case.kind](case)
        row["note"] = "; ".join(model.notes)
        options = SolverOptions()
        if case.kind in REALISTIC:
            from dataclasses import replace

            from fruitcli.fem import pressure_check

            def left() -> float:  # the row's budget left (s), less the margin; >= 1 s
                spent = time.perf_counter() - t0
                return max(REALISTIC_SECONDS - ROW_MARGIN_SECONDS - spent, 1.0)

            options = replace(options, load_steps=4, max_seconds=left())
            solver = model.make_solver()
            keys = pressure_check.pressure_keys(model.chamber_names)
            pressure_check.check_pressures(model, load.pressure_kpa[None, :], keys, solver, options)
            options = replace(options, max_seconds=left())
            row["note"] = ""
        else:
            solver = None
        res = solve_state(model, load, options=options, label=case.name, solver=solver)
        disp = float(np.abs(res.displacement_mm).max())
        values = [res.residual, disp, res.min_det_f]
        if not all(math.isfinite(v) for v in values):
            raise FruitError(
                f"{case.name}: non-finite result (residual {res.residual}, max displacement {disp})"
            )
        row["iterations"] = res.iterations
        row["subdivisions"] = res.subdivisions
        row["residual"] = float(res.residual)
        row["max_disp_mm"] = disp
        row["min_det_f"] = float(res.min_det_f)
        if case.kind == "beam_gravity":
            row["tip_deflection_mm"] = float(-res.displacement_mm[:, 2].min())
        if case.kind in ("hollow_pressure", *REALISTIC) and len(res.pressure_kpa):
            growth = res.chamber_volume_mm3[0] / model.chamber_rest_volume_mm3[0] - 1.0
            row["note"] = (
                row["note"] + "; " if row["note"] else ""
            ) + f"pressure {res.pressure_kpa[0]:.4g} kPa, volume growth {growth:.3g} V0"
        if res.min_det_f <= 0:
            row["status"] = "converged with inverted elements"
    except FruitError as exc:
        row["status"] = f"failed: {exc}"
    row["seconds"] = time.perf_counter() - t0
    return row


def add_scaling_columns(rows: list[StabilityRow]) -> None:
    """E sweep: tip deflection x E (constant while the response is linear); nu sweep: tip
    deflection relative to nu = 0.3 (how much linear tets lock)."""
    e_rows = [r for r in rows if r["group"] == "E" and "tip_deflection_mm" in r]
    for r in e_rows:
        e = float(r["case"].split("=")[1].split()[0])
        r["note"] = (
            r["note"] + "; " if r["note"] else ""
        ) + f"tip x E = {r['tip_deflection_mm'] * e:.4g} mm kPa"
    for group, ref_name in (("nu", "nu = 0.3"), ("nu, p2", "nu = 0.3 (p2)")):
        ref = [r for r in rows if r["group"] == group and r["case"] == ref_name]
        if not (ref and "tip_deflection_mm" in ref[0]):
            continue
        base = ref[0]["tip_deflection_mm"]
        for r in rows:
            if r["group"] == group and "tip_deflection_mm" in r:
                r["note"] = (
                    r["note"] + "; " if r["note"] else ""
                ) + f"tip / tip(nu=0.3) = {r['tip_deflection_mm'] / base:.3f}"


HEADER = [
    "group",
    "case",
    "status",
    "iterations",
    "subdivisions",
    "residual",
    "max_disp_mm",
    "min_det_f",
    "seconds",
    "note",
]


def _fmt(v: object) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def table_markdown(rows: list[StabilityRow]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r.get(h)).replace("|", "/") for h in HEADER) + " |")
    return "\n".join(lines) + "\n"
