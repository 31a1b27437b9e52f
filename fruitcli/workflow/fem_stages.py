"""The FEM stages: tetra (the volume mesh), limits (each chamber's pressures against its
limit), simulate (the states and the taxels they carry) and reduce (the reduced model of
the chamber pressures). The heavy modules are imported only when a stage runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.scene import Scene, gravity_left_out, has_deformation, has_gravity, n_states
from fruitcli.workflow.stage_paths import (
    DEFORMS,
    YARN_KEYS,
    geometry_kind,
    has_tracks,
    no_inputs,
    solid_path,
    taxels_path,
    tracks_path,
)
from fruitcli.workflow.stage_types import Stage

if TYPE_CHECKING:
    from fruitcli.workflow.stage_types import Context


# ----------------------------------------------------------------------------- tetra / simulate
def _fem_needed(scene: Scene):
    if not has_deformation(scene):
        dropped = gravity_left_out(scene)
        return False, "no deformation: taxels at rest, no FEM" + (f"; {dropped}" if dropped else "")
    if geometry_kind(scene) == "none":
        return False, "no geometry to mesh"
    return True, _fem_reason(scene)


def _fem_reason(scene: Scene):
    parts = []
    k = len(scene.chambers)
    act = scene.actuation
    if k and (act.pressure_kpa or act.volume_growth_mm3):
        parts.append(
            f"{k} chamber(s), pressure as Lagrange multipliers over {n_states(scene)} state(s)"
        )
    elif k:
        parts.append(f"{k} chamber(s) as empty cavities, no actuation: no pressure constraint")
    else:
        parts.append("no chambers: no pressure constraint")
    if scene.jig:
        parts.append(f"{len(scene.jig)} jig spring region(s)")
    if not scene.fixed:
        parts.append("no fixed region: rigid modes removed")
    if has_gravity(scene):
        parts.append("gravity on the held body")
    elif not scene.has("gravity"):
        parts.append("no gravity")
    else:
        parts.append(gravity_left_out(scene) or "gravity vector zero: no gravity")
    return "; ".join(parts)


def _tetra_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.fem.stage import run_tetra
    from fruitcli.tables import read_taxels

    tax = taxels_path(scene, ctx)
    xyz = read_taxels(tax).xyz_mm if tax is not None else None
    return run_tetra(scene, solid_path(scene, ctx), out_dir, progress=ctx.progress, taxels_xyz=xyz)


def _simulate_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.fem.stage import run_simulate
    from fruitcli.tables import read_taxels

    tax = taxels_path(scene, ctx)
    xyz = read_taxels(tax).xyz_mm if tax is not None else None
    if tax is None:
        ctx.progress(
            "simulate: no taxels to follow (a [geometry].solid scene takes them "
            "from [grid].taxels, a CSV of id,i,j,x_mm,y_mm,z_mm)"
        )
    return run_simulate(
        scene,
        ctx.dir("tetra") / "mesh.npz",
        xyz,
        out_dir,
        progress=ctx.progress,
        tracks_csv=tracks_path(scene, ctx),
        limits_dir=ctx.dir("limits") if _limits_needed(scene)[0] else None,
        taxels_source=None if tax is None else str(tax),
    )


# ----------------------------------------------------------------------------- limits
def _limits_needed(scene: Scene):
    from fruitcli.fem.limits_stage import near_limit

    fem, why = _fem_needed(scene)
    return near_limit(scene) if fem else (False, why)


def _limits_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.fem.limits_stage import run_limits_stage
    from fruitcli.studies.parallel import CurveProcesses

    mesh = ctx.dir("tetra") / "mesh.npz"
    return run_limits_stage(scene, mesh, out_dir, progress=ctx.progress, pool=CurveProcesses())


LIMITS_STAGE = Stage(
    "limits",
    ["tetra"],
    "fruitcli.fem.limits_stage",
    _limits_needed,
    no_inputs,
    _limits_run,
    lambda s: ["limits.json"],
    reads=(*DEFORMS, "geometry", "fem", "material", "solver"),
)
"""Each chamber's pressures against its limit and collapse, once per mesh, material and
actuation (`fruitcli.fem.limits_stage`); `simulate` reads it (`_simulate_run`)."""


# ----------------------------------------------------------------------------- reduce
def wanting_reduced(scene: Scene) -> Scene:
    """The scene as if it declared [reduced] (its defaults): the reduce stage is then
    needed. `fruit live --online` and `fruit simulate --model reduced` build the
    reduced model on demand this way; `fruit run` builds it for scenes that declare
    [reduced]."""
    from dataclasses import replace

    return replace(scene, declared=scene.declared | {"reduced"})


def _reduce_needed(scene: Scene):
    if not scene.chambers:
        return False, "no chambers: no pressures to reduce"
    meshed, why = _fem_needed(scene)
    if not meshed:
        return False, why
    if not scene.has("reduced"):
        if locate_uses_reduced(scene):
            return True, (
                "the recording carries chamber pressures: its taxels come from "
                'the reduced model ([frames].model = "full": the states)'
            )
        return False, (
            "no [reduced]: built on demand (fruit live --online, fruit simulate "
            "--model reduced, fruit locate --scene)"
        )
    return True, (
        f"{len(scene.chambers)} chamber(s): response surfaces fitted to full "
        "solves over the pressure range, held-out validation"
    )


def locate_uses_reduced(scene: Scene) -> bool:
    """Whether the locate stage takes the recording's taxels from the reduced model: a
    scene with chambers whose [frames].recording carries chamber pressures, unless
    [frames].model = "full" (then along the simulated states, as bench frames are)."""
    from fruitcli.sensing.frames.recording_chunks import has_pressures

    rec = scene.frames.recording
    if rec is None or scene.has("bench") or not scene.chambers or scene.frames.model != "reduced":
        return False
    try:
        return has_pressures(rec, scene.board)
    except (OSError, ValueError):
        return False  # the locate stage reports the unreadable recording itself


def _reduce_range(scene: Scene) -> dict:
    from fruitcli.fem.reduced.build import pressure_box

    names = [c.name for c in scene.chambers]
    lo, hi = pressure_box(scene, names)
    return {n: [float(a), float(b)] for n, a, b in zip(names, lo, hi, strict=True)}


def _reduce_inputs(scene: Scene, ctx: Context):
    # the pressure box from [actuation] and [reduced] pressure_range_kpa, margin, not
    # those keys: new states inside the same box keep the model
    return {"range_kpa": _reduce_range(scene)}


def _reduce_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.fem.reduced.build import run_reduce
    from fruitcli.tables import read_taxels

    tax = taxels_path(scene, ctx)
    xyz = read_taxels(tax).xyz_mm if tax is not None else None
    return run_reduce(scene, ctx.dir("tetra") / "mesh.npz", xyz, out_dir, progress=ctx.progress)


# ----------------------------------------------------------------------------- the table's entries
TETRA_STAGE = Stage(
    "tetra",
    ["make-tracks", "pad-grid"],
    "fruitcli.fem.stage",
    _fem_needed,
    no_inputs,
    _tetra_run,
    lambda s: ["mesh.npz", "quality.json"],
    reads=("geometry", "mesh", "grid.taxels"),
    decides=DEFORMS,
)


SIMULATE_STAGE = Stage(
    "simulate",
    ["tetra", "make-tracks", "pad-grid", "limits"],
    "fruitcli.fem.stage",
    _fem_needed,
    no_inputs,
    _simulate_run,
    lambda s: ["states.npz"] + (["yarns.csv"] if has_tracks(s) else []),
    reads=(*DEFORMS, "geometry", "fem", "material", "solver", "grid") + YARN_KEYS,
)


REDUCE_STAGE = Stage(
    "reduce",
    ["tetra", "make-tracks", "pad-grid"],
    "fruitcli.fem.reduced.build",
    _reduce_needed,
    _reduce_inputs,
    _reduce_run,
    lambda s: ["reduced.npz", "validation.json"],
    reads=("geometry", "fem", "material", "gravity", "fixed", "jig", "solver", "reduced")
    + ("grid.taxels",),
    minus=("reduced.pressure_range_kpa", "reduced.margin"),
    decides=("frames", "board", "bench"),  # locate_uses_reduced
    derived=("actuation", "reduced.pressure_range_kpa", "reduced.margin"),
)
