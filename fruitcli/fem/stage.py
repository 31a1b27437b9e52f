"""The tetra and simulate stages: scene + files in, files out (mm, kPa, N/mm at the
edge; see `fruitcli.fem.units`).

- `run_tetra(scene, solid_path, out_dir)` -> out_dir/{mesh.npz, mesh.msh, mesh.vtu,
  quality.json}
- `run_simulate(scene, mesh_npz, taxels_xyz, out_dir)` -> out_dir/states.npz (and one
  VTU per state with vtu=True; yarns.csv when the scene has tracks)

`progress`, when given, is called with one-line messages; per state the message
starts with "state i/S".
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import MeshError, SceneError, SolverError
from fruitcli.fem import io, pressure_check
from fruitcli.fem.continuum import ContinuumModel
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements import barycentric, tet4
from fruitcli.fem.elements.lagrange import ELEMENTS
from fruitcli.fem.elements.quadratic import curve_onto_ellipsoid, quadratic_mesh
from fruitcli.fem.loads import pressure
from fruitcli.fem.loads.springs import Jig, nodes_in_box
from fruitcli.fem.materials import build as materials
from fruitcli.fem.materials.models import MATERIAL_MODELS
from fruitcli.fem.meshing import estimate, shells, surface_fit, tetra
from fruitcli.fem.sample_cache import CACHE_FILE, SampleCache, kept_first_state
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import PATH_TOLERANCE, solve_state
from fruitcli.fem.state_load import Load
from fruitcli.fem.units import spring_mn_per_mm
from fruitcli.fsutil import staged_dir, write_json
from fruitcli.geometry.mesh.load import SCENE_UNIT_HINT, UNIT_TO_MM, check_extent
from fruitcli.scene import n_states

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from fruitcli.fem.fem_model import FemModel, LinearSolver
    from fruitcli.fem.solver.options import StateResult
    from fruitcli.scene import Scene


def _noop(msg: str) -> None:
    pass


def body_shells(scene: Scene, solid_path: Path | None) -> tuple[dict, list[dict]]:
    """The outer shell (solid surface or flat pad box) and the chamber shells.

    The scene's own surface files (`solid`, chamber `surface`) are in [geometry].unit,
    and their size must fit it (`geometry.load.check_extent`). Any other `solid_path`
    (reduced.stl from make-tracks) is in mm.
    """
    geo, where = scene.geometry, scene.path.name

    def scene_surface(
        path: str | Path, what: str
    ) -> tuple[np.ndarray, np.ndarray]:  # a file of the scene's, in [geometry].unit
        v, f = shells.load_surface(path, what, scale=UNIT_TO_MM[geo.unit])
        check_extent(v, geo.unit, f"{what}: {Path(path).name}", SCENE_UNIT_HINT)
        return v, f

    own = geo.solid is not None and (
        solid_path is None or Path(solid_path).resolve() == Path(geo.solid).resolve()
    )
    if not own and solid_path is not None:
        v, f = shells.load_surface(solid_path, "solid")
        check_extent(v, "any", f"--solid: {Path(solid_path).name}", "")
        outer = shells.surface_shell(solid_path.name, v, f)
    elif geo.solid is not None:
        v, f = scene_surface(geo.solid, f"{where}: [geometry].solid")
        outer = shells.surface_shell(geo.solid.name, v, f)
    elif geo.pad_size_mm is not None:
        x, y, t = geo.pad_size_mm
        if min(x, y, t) <= 0:
            raise SceneError("[geometry].pad_size_mm: expected positive [x, y, thickness]")
        outer = shells.box_shell("pad", [-x / 2, -y / 2, 0.0], [x / 2, y / 2, t])
    else:
        raise SceneError(
            "[geometry]: the FEM body needs `solid`, `pad_size_mm` or a solid "
            "surface from make-tracks (--solid)"
        )
    chambers = []
    for ch in scene.chambers:
        name = ch.name
        if ch.ellipsoid is not None:
            e = ch.ellipsoid
            chambers.append(shells.ellipsoid_shell(name, e.center_mm, e.radii_mm))
        elif ch.surface is not None:
            v, f = scene_surface(ch.surface, f"{where}: [[geometry.chamber]] '{name}'.surface")
            chambers.append(shells.surface_shell(name, v, f))
        else:
            raise SceneError(
                f"{where}: [[geometry.chamber]] '{name}': needs `ellipsoid` or `surface`"
            )
    return outer, chambers


def run_tetra(
    scene: Scene,
    solid_path: str | Path | None,
    out_dir: Path,
    progress: Callable[[str], None] | None = None,
    taxels_xyz: np.ndarray | None = None,
) -> dict:
    """Tetrahedralize the scene's body with its chambers; write mesh files to out_dir.
    `taxels_xyz` (t, 3) mm, when given, tags the taxels' region of the surface and
    refines the mesh there to [mesh].min_size_mm (see `fruitcli.fem.meshing.tetra`)."""
    progress = progress or _noop
    outer, chambers = body_shells(scene, Path(solid_path) if solid_path else None)
    shells.check_layout(outer, chambers, scene.path.name)
    mesh_cfg = scene.mesh
    size = float(mesh_cfg.size_mm)
    min_size = float(mesh_cfg.min_size_mm or size)
    if not 0 < min_size <= size:
        raise SceneError(f"[mesh].min_size_mm: expected 0 < min_size_mm <= size_mm = {size}")
    tets = estimate.check_mesh_size(outer, size, mesh_cfg.time_limit_s, scene.path.name)
    progress(
        f"tetra: gmsh at size {size:g} mm (min {min_size:g} mm), {len(chambers)} chamber(s), "
        f"about {tets:.3g} tets expected"
    )
    raw = tetra.run_gmsh(
        [outer, *chambers],
        size,
        min_size,
        mesh_cfg.time_limit_s,
        label=outer["name"],
        work_dir=None,
        taxels_xyz=taxels_xyz,
        progress=progress,
    )
    mesh = tetra.assemble_mesh(raw, [c["name"] for c in chambers], size, taxels_xyz)
    report = tetra.quality_report(mesh, mesh_cfg.min_quality)
    # how far the straight-sided boundary lies from the surface it meshes (chord sag):
    # points on that surface lie outside the mesh by up to this much (surface_fit)
    deviation = surface_fit.deviation_mm(
        outer["vertices"], outer["faces"], mesh["nodes"], mesh["surface_tris"]
    )
    mesh["surface_deviation_mm"] = np.float64(deviation)
    report["surface_deviation_mm"] = round(deviation, 4)
    for k, ch in enumerate(chambers):
        if not np.any(mesh["chamber_tri_owner"] == k):
            raise MeshError(
                f"[[geometry.chamber]] '{ch['name']}': no cavity wall in the mesh "
                f"of {outer['name']}"
            )
    if report["sicn_min"] < mesh_cfg.min_quality:
        raise MeshError(
            f"{outer['name']}: mesh too poor: worst SICN {report['sicn_min']:.3f} "
            f"< [mesh].min_quality {mesh_cfg.min_quality:g} "
            f"({report['poor_tets']} poor tets); check the surface or size_mm"
        )
    progress(
        f"tetra: {report['n_tets']} tets, {report['n_nodes']} nodes, "
        f"SICN min {report['sicn_min']:.2f}, boundary within {deviation:.2f} mm of the surface"
    )
    with staged_dir(out_dir) as tmp:
        io.save_npz(tmp / "mesh.npz", mesh)
        (tmp / "mesh.msh").write_bytes(raw["msh_text"])
        io.write_vtu(tmp / "mesh.vtu", mesh["nodes"], mesh["tets"])
        write_json(tmp / "quality.json", report)
    return report


def _jigs(scene: Scene, nodes: np.ndarray) -> list[Jig]:
    out = []
    for n, jig in enumerate(scene.jig):
        idx = nodes_in_box(nodes, jig.region_box_mm)
        if len(idx) == 0:
            raise SceneError(
                f"[[jig]] #{n + 1}.region_box_mm: no mesh node inside {jig.region_box_mm}"
            )
        out.append(
            Jig(
                idx,
                spring_mn_per_mm(jig.stiffness_n_per_mm),
                jig.rotate_deg,
                tuple(jig.axis),
                tuple(jig.pivot_mm),
                tuple(jig.translate_mm),
            )
        )
    return out


def _fixed(scene: Scene, nodes: np.ndarray) -> tuple[np.ndarray, list]:
    """(held node indices, [(moved node indices, displacement mm)]) of [[fixed]]."""
    idx, moved = [], []
    for n, fx in enumerate(scene.fixed):
        inside = nodes_in_box(nodes, fx.box_mm)
        if len(inside) == 0:
            raise SceneError(f"[[fixed]] #{n + 1}.box_mm: no mesh node inside {fx.box_mm}")
        if fx.displacement_mm is not None:
            moved.append((inside, np.asarray(fx.displacement_mm, float)))
        else:
            idx.append(inside)
    return (np.unique(np.concatenate(idx)) if idx else np.zeros(0, np.int64)), moved


def state_loads(scene: Scene, names: list[str]) -> list[Load]:
    """One Load per actuation state (pressure or volume growth per chamber)."""
    act, s = scene.actuation, n_states(scene)
    k = len(names)
    pressure, growth = np.zeros((s, k)), np.zeros((s, k))
    vc = np.zeros(k, bool)
    for key, table, target in (
        ("pressure_kpa", act.pressure_kpa, pressure),
        ("volume_growth_mm3", act.volume_growth_mm3, growth),
    ):
        for cname, values in (table or {}).items():
            if cname not in names:
                raise SceneError(
                    f"[actuation].{key}.{cname}: no such chamber in the mesh "
                    f"(chambers: {', '.join(names) or 'none'})"
                )
            target[:, names.index(cname)] = values
            vc[names.index(cname)] = key == "volume_growth_mm3"
    return [Load(pressure[i], growth[i], vc.copy(), 1.0, 1.0) for i in range(s)]


def check_closed_walls(chambers: dict[str, np.ndarray]) -> None:
    """Refuse, in one MeshError line, a chamber whose wall triangles (t, 3) do not close
    it: every edge shared by exactly two of them (its volume and pressure work are
    otherwise not defined)."""
    from fruitcli.geometry.mesh.load import edge_use

    for name, tris in chambers.items():
        if not len(tris):
            raise MeshError(f"[[geometry.chamber]] '{name}': the mesh has no wall for it")
        open_edges = int(np.count_nonzero(edge_use(tris) != 2))
        if open_edges:
            raise MeshError(
                f"[[geometry.chamber]] '{name}': its wall in the mesh is not closed "
                f"({open_edges} edges not shared by exactly two triangles): the chamber "
                "must lie inside the body with a wall of at least one element; rerun "
                "`fruit tetra` after moving or shrinking it"
            )


def build_model(scene: Scene, mesh: dict) -> Model | ContinuumModel:
    """Model of a scene on a loaded mesh.npz: the paper's corotational `Model` on linear
    tets, or the hyperelastic `ContinuumModel` on the scene's [fem].element (quadratic
    tets built here from the linear mesh, edge nodes on ellipsoid chambers moved onto
    the ellipsoid)."""
    names = [str(n) for n in mesh["chamber_names"]]
    wanted = [c.name for c in scene.chambers]
    if sorted(names) != sorted(wanted):
        raise MeshError(
            f"mesh chambers {names} do not match the scene's {wanted}; rerun `fruit tetra`"
        )
    chambers = io.chamber_dict(mesh)
    check_closed_walls(chambers)
    mat = scene.material
    material = materials.from_scene(mat)
    element = scene.fem.element
    gravity = scene.gravity.vector_m_s2 if scene.has("gravity") else None
    if MATERIAL_MODELS[material.model].corotational:
        nodes = mesh["nodes"]
        fixed, moved = _fixed(scene, nodes)
        return Model.from_arrays(
            nodes,
            mesh["tets"],
            mat.young_modulus_kpa,
            mat.poisson_ratio,
            density_kg_m3=mat.density_kg_m3,
            gravity_m_s2=gravity,
            fixed_nodes=fixed,
            chambers=chambers,
            jigs=_jigs(scene, nodes),
            prescribed=moved,
        )
    nodes, tets = mesh["nodes"], mesh["tets"]
    flip = tet4.signed_volumes(nodes, tets) < 0
    if flip.any():
        tets = tets.copy()
        tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    walls = [pressure.orient_outward(nodes, t) for t in chambers.values()]
    if ELEMENTS[element].order == 2:
        nodes, tets, walls = quadratic_mesh(nodes, tets, walls)
        spec = {c.name: c.ellipsoid for c in scene.chambers}
        for name, wall in zip(chambers, walls, strict=True):
            ellipsoid = spec.get(name)
            if ellipsoid is not None:
                curve_onto_ellipsoid(
                    nodes, tets, np.unique(wall[:, 3:]), ellipsoid.center_mm, ellipsoid.radii_mm
                )
    fixed, moved = _fixed(scene, nodes)
    return ContinuumModel.from_arrays(
        nodes,
        tets,
        material,
        element,
        density_kg_m3=mat.density_kg_m3,
        gravity_m_s2=gravity,
        fixed_nodes=fixed,
        chambers=dict(zip(chambers, walls, strict=True)),
        jigs=_jigs(scene, nodes),
        prescribed=moved,
    )


def state_line(i: int, total: int, solve_ms: list, res: StateResult) -> str:
    """The progress line of state i (0-based) of `total` solved: its Newton iterations
    (and whether it was kept from an earlier run), time and relative residual, and,
    after the second state, the time left at the mean of the states after the first
    (the first, from rest, takes its own load steps)."""
    n = res.iterations
    how = f"after {n} Newton iteration{'' if n == 1 else 's'}"
    if res.kept:
        how = f"kept from an earlier run ({CACHE_FILE}), {how}"
    line = (
        f"state {i + 1}/{total}: equilibrium {how}"
        f" in {res.solve_ms / 1e3:.1f} s (relative force residual {res.residual:.1e})"
    )
    left = total - i - 1
    if left and i >= 1:
        line += f"; about {left * np.mean(solve_ms[1:]) / 1e3:.0f} s left for {left} more"
    return line


def _off_body(mesh: dict) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """off_body(points, outside) -> (t,) mm by which points outside the mesh lie beyond
    its boundary's own distance from the body's surface (`surface_fit`; a mesh.npz
    written before tetra measured that distance allows none): > 0 is off the body."""
    deviation = float(mesh.get("surface_deviation_mm", 0.0))
    nodes = np.asarray(mesh["nodes"], float)
    tris = np.asarray(mesh["surface_tris"])
    edge = float(np.median(np.linalg.norm(nodes[tris[:, 1]] - nodes[tris[:, 0]], axis=1)))
    allowed = surface_fit.tolerance_mm(deviation, edge)

    def off_body(points: np.ndarray, outside: np.ndarray) -> np.ndarray:
        d = surface_fit.outside_mm(nodes, mesh["surface_tris"], points, outside)
        return np.where(d > allowed, d - allowed, 0.0)

    return off_body


def solver_options(scene: Scene, first_state: bool = False, jig: bool = True) -> SolverOptions:
    """The scene's [solver] settings; the state solved from rest (`first_state`) takes
    `jig_steps` load steps under a jig, and at least `first_steps` with the hyperelastic
    model (a nearly incompressible body loaded from rest in one step needs about four
    times the Newton iterations: 65 against 15 on the default Fruit at 8 mm), those
    short of its load converged to `state.PATH_TOLERANCE` only."""
    cfg = scene.solver
    steps = 1
    if first_state:
        steps = cfg.jig_steps if jig else 1
        if not MATERIAL_MODELS[scene.material.model].corotational:
            steps = max(steps, cfg.first_steps)
    return SolverOptions(
        cfg.tolerance,
        cfg.max_iterations,
        cfg.max_subdivisions,
        cfg.linear_solver,
        steps,
        cfg.displacement_tolerance_mm,
        cfg.max_seconds,
        PATH_TOLERANCE if first_state else 0.0,
    )


def run_simulate(
    scene: Scene,
    mesh_npz: str | Path,
    taxels_xyz: ArrayLike | None,
    out_dir: Path,
    progress: Callable[[str], None] | None = None,
    vtu: bool = False,
    tracks_csv: str | Path | None = None,
    pressures: Mapping[str, ArrayLike] | None = None,
    limits_dir: str | Path | None = None,
    taxels_source: str | None = None,
) -> dict:
    """Solve every actuation state, or with `pressures` {chamber: (S,) kPa} those
    pressure vectors; write out_dir/states.npz (see module docstring), and
    out_dir/yarns.csv from the tracks of [tracks] file, else of `tracks_csv`, when any.
    The pressures are checked against the chambers' limits first, unless `limits_dir`
    holds the planner's limits stage output for them (`pressure_check.checked_by`)."""
    progress = progress or _noop
    tracks_csv = scene.tracks.file or tracks_csv
    tracks = None
    if tracks_csv is not None:  # read before solving: a bad file fails fast
        from fruitcli.fem import yarn

        tracks = yarn.read_tracks(tracks_csv)
    mesh = io.load_mesh(Path(mesh_npz))
    model = build_model(scene, mesh)
    for note in model.notes:
        progress(f"simulate: {note}")
    loads = _loads(scene, model, pressures)
    solver = model.make_solver(scene.solver.linear_solver)
    keys = (
        [f"--pressures {c}_kpa" for c in model.chamber_names]
        if pressures is not None
        else pressure_check.pressure_keys(model.chamber_names)
    )
    if model.chamber_tris:
        pressure_check.check_growth(model, loads)
        asked = np.array([np.where(ld.volume_controlled, np.nan, ld.pressure_kpa) for ld in loads])
        if pressures is not None or not pressure_check.checked_by(limits_dir):
            pressure_check.check_pressures(
                model,
                asked,
                keys,
                solver,
                solver_options(scene),
                progress=progress,
                kept=Path(out_dir) / CACHE_FILE,
            )
    first = SampleCache(model, Path(out_dir) / CACHE_FILE, solver_options(scene))
    results = _solve_states(scene, model, loads, keys, solver, progress, first)
    out = _states_arrays(model, mesh, results)
    off_body = _off_body(mesh)
    if taxels_xyz is not None:
        out.update(_taxel_arrays(model, results, taxels_xyz, off_body, taxels_source, progress))
    summary_yarns = None
    if tracks is not None:
        tr = scene.tracks
        yarn_rows, summary_yarns = yarn.follow_tracks(
            model,
            tracks,
            np.stack([r.x for r in results]),
            tr.yarn_max_stretch,
            tr.zigzag_pitch_mm,
            off_body,
            progress,
            source=str(tracks_csv),
        )
    with staged_dir(out_dir) as tmp:
        io.save_npz(tmp / "states.npz", out)
        if tracks is not None:
            yarn.write_yarns_csv(tmp / "yarns.csv", yarn_rows)
        if vtu:
            for i, r in enumerate(results):
                io.write_vtu(
                    tmp / f"state_{i:03d}.vtu",
                    r.x,
                    out["elements"],
                    {"displacement_mm": r.displacement_mm},
                )
    if tracks is None:  # no tracks now: an older yarns.csv would not match these states
        (Path(out_dir) / "yarns.csv").unlink(missing_ok=True)
    return {
        "states": len(results),
        "iterations": out["iterations"].tolist(),
        "solve_ms": out["solve_ms"].tolist(),
        "notes": model.notes,
        "linear_solver": solver.stats | {"method": solver.method},
    } | ({"yarns": summary_yarns} if summary_yarns else {})


def _loads(scene: Scene, model: FemModel, pressures: Mapping[str, ArrayLike] | None) -> list[Load]:
    """The states' loads: the scene's actuation states, or the pressure vectors of
    `pressures` {chamber: (S,) kPa}."""
    if pressures is None:
        return state_loads(scene, model.chamber_names)
    table = np.stack([np.asarray(pressures[c], float) for c in model.chamber_names], 1)
    return [Load.pressures(row) for row in table]


def _solve_states(
    scene: Scene,
    model: FemModel,
    loads: list[Load],
    keys: list[str],
    solver: LinearSolver,
    progress: Callable[[str], None],
    first: SampleCache | None = None,
) -> list[StateResult]:
    """Each load's equilibrium, from the last one's (a failure past a chamber's limit
    named by `pressure_check.explain_failure`); one progress line per state. The first,
    from rest, is taken from `first` when an earlier run kept it there and it is still
    an equilibrium of the model (`kept_first_state`), and kept there once solved."""
    results, x, p, prev = [], None, None, None
    for i, load in enumerate(loads):
        opts = solver_options(scene, first_state=i == 0, jig=bool(model.jigs))
        kept = kept_first_state(model, load, solver, first) if i == 0 else None
        try:
            res = kept or solve_state(
                model,
                load,
                x_start=x,
                load_start=prev,
                pressure_start=p,
                options=opts,
                solver=solver,
                label=f"state {i}",
                progress=lambda msg: progress(f"simulate: {msg}"),
            )
        except SolverError as exc:  # past a limit the check screened out? name it
            pressure_check.explain_failure(
                model, load, keys, solver, solver_options(scene), exc, progress
            )
        if i == 0 and first is not None and res.iterations:  # a state worth keeping
            first.put(load, res, solver.newton_c)
            first.save()
        results.append(res)
        x, p, prev = res.x, res.pressure_kpa, load
        progress(state_line(i, len(loads), [r.solve_ms for r in results], res))
    return results


def _states_arrays(model: FemModel, mesh: dict, results: list[StateResult]) -> dict:
    """The arrays of states.npz but the taxels' (see the module docstring)."""
    n = len(results)
    return {
        "model": np.array("full"),
        "rest_nodes": model.rest,
        "tets": model.tets,
        "surface_tris": mesh["surface_tris"],
        "element": np.array(model.element_name),
        "material_model": np.array(model.material_name),
        "elements": model.elements,
        "displacement_mm": np.stack([r.displacement_mm for r in results]),
        "pressure_kpa": np.stack([r.pressure_kpa for r in results]).reshape(n, -1),
        "chamber_volume_mm3": np.stack([r.chamber_volume_mm3 for r in results]).reshape(n, -1),
        "chamber_names": np.array(model.chamber_names, dtype=str).reshape(-1),
        "chamber_rest_volume_mm3": model.chamber_rest_volume_mm3,
        "iterations": np.array([r.iterations for r in results]),
        "residual": np.array([r.residual for r in results]),
        "solve_ms": np.array([r.solve_ms for r in results]),
        "subdivisions": np.array([r.subdivisions for r in results]),
        "min_det_f": np.array([r.min_det_f for r in results]),
    }


def _taxel_arrays(
    model: FemModel,
    results: list[StateResult],
    taxels_xyz: ArrayLike,
    off_body: Callable[[np.ndarray, np.ndarray], np.ndarray],
    taxels_source: str | None,
    progress: Callable[[str], None],
) -> dict:
    """The taxels' arrays of states.npz: each taxel's tet, barycentric weights, whether
    it lies outside the mesh, and its positions (S, T, 3) mm in every state; a warning
    for each taxel off the body."""
    taxels = np.asarray(taxels_xyz, float).reshape(-1, 3)
    tet, w, outside = barycentric.locate(model.rest, model.tets, taxels)
    beyond = off_body(taxels, outside)
    where = taxels_source or "the taxels"
    for k in np.flatnonzero(beyond > 0):
        progress(
            f"simulate: warning: taxel {k} (row {k + 1} of {where}) lies "
            f"{beyond[k]:.2f} mm farther outside the mesh than the surface it meshes "
            f"does: off the body; it follows by extrapolation (check {where} or "
            "[mesh].size_mm)"
        )
    states_x = np.stack([r.x for r in results])
    return {
        "taxel_tet": tet,
        "taxel_bary": w,
        "taxel_outside": outside,
        "taxels_mm": model.map_points(tet, w, states_x),
    }
