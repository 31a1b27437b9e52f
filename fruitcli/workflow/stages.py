"""The pipeline's stages, in dependency order, as the planner sees them.

Each entry says when a scene needs the stage (and why not, when it does not), which
library function does the work, and which scene keys it reads: `reads` (whole sections
or `section.key`, hashed with the content of every file a path key names), `minus`
(keys of a read section it does not read), `decides` (keys only `needed` reads) and
`derived` (keys hashed through a value its `inputs` derives). `inputs` adds only what
is not a scene key; upstream outputs are covered by the hashes of `deps`.
tests/workflow/test_stage_hashes.py records what each stage reads on small scenes and
fails on a read its declaration lacks. The heavy modules are imported only when a stage
runs.
"""

from __future__ import annotations

from pathlib import Path

from fruitcli.scene import Scene, gravity_left_out, has_deformation, has_gravity, n_states
from fruitcli.sensing.skin.models import SKIN_MODELS
from fruitcli.workflow.stage_types import Context, Stage


# ----------------------------------------------------------------------------- helpers
def _geometry_kind(scene: Scene) -> str:
    geo = scene.geometry
    if geo.artist is not None:
        return "artist"
    if geo.solid is not None:
        return "solid"
    if geo.pad_size_mm is not None:
        return "pad"
    return "none"


def taxels_path(scene: Scene, ctx: Context) -> Path | None:
    """Where this scene's taxel table comes from."""
    if scene.grid.taxels is not None:
        return scene.grid.taxels
    kind = _geometry_kind(scene)
    if kind == "artist":
        return ctx.dir("make-tracks") / "taxels.csv"
    if kind == "pad":
        return ctx.dir("pad-grid") / "taxels.csv"
    return None


def solid_path(scene: Scene, ctx: Context) -> Path | None:
    kind = _geometry_kind(scene)
    if kind == "artist":
        return ctx.dir("make-tracks") / "reduced.stl"
    if kind == "solid":
        return scene.geometry.solid
    return None


def _pad_tracks(scene: Scene) -> bool:
    """Whether pad-grid writes the taxels and so the pad's grid lines (tracks.csv)."""
    return _geometry_kind(scene) == "pad" and scene.grid.taxels is None


def _has_tracks(scene: Scene) -> bool:
    return scene.tracks.file is not None or _geometry_kind(scene) == "artist" or _pad_tracks(scene)


def tracks_path(scene: Scene, ctx: Context) -> Path | None:
    """Where this scene's yarn track centre lines come from ([tracks] file, or the
    tracks.csv of make-tracks or pad-grid), or None: no yarns.csv."""
    if scene.tracks.file is not None:
        return scene.tracks.file
    if _pad_tracks(scene):
        return ctx.dir("pad-grid") / "tracks.csv"
    return ctx.dir("make-tracks") / "tracks.csv" if _has_tracks(scene) else None


YARN_KEYS = ("tracks.yarn_max_stretch", "tracks.zigzag_pitch_mm", "tracks.file")
"""[tracks] keys read by simulate (yarns.csv), not by make-tracks."""
GEOMETRY_KIND = ("geometry.artist", "geometry.solid", "geometry.pad_size_mm")
"""The keys `_geometry_kind` reads."""
DEFORMS = ("actuation", "fixed", "jig", "gravity", "material.density_kg_m3")
"""The keys `has_deformation` reads (whether states.npz exists)."""


def no_inputs(scene: Scene, ctx: Context) -> dict:
    """A stage whose hash is its declared scene keys and upstream hashes alone."""
    return {}


def states_path(scene: Scene, ctx: Context) -> Path | None:
    return ctx.dir("simulate") / "states.npz" if has_deformation(scene) else None


def indenters(scene: Scene) -> list[str]:
    return list(scene.bench.indenters)


# ----------------------------------------------------------------------------- make-artist
def _artist_needed(scene):
    geo = scene.geometry
    if geo.artist is None:
        kind = _geometry_kind(scene)
        return False, (
            "no geometry: evaluation only" if kind == "none" else f"no artist mesh: {kind} geometry"
        )
    if not geo.generate_artist:
        return False, "artist mesh given"
    return True, "default fruit generated on first use"


def _artist_run(scene, ctx, out_dir):
    from fruitcli.geometry.artist import write_artist

    out_dir.mkdir(parents=True, exist_ok=True)
    artist = scene.geometry.artist
    if Path(artist).exists():  # "if missing": a mesh at `artist` is the user's, kept
        ctx.progress(f"{artist}: exists, kept (generate_artist writes it only when missing)")
        return {"artist": str(artist), "generated": False}
    write_artist(artist)
    return {"artist": str(artist), "generated": True}


# ----------------------------------------------------------------------------- make-tracks
def _tracks_needed(scene):
    kind = _geometry_kind(scene)
    if kind == "artist":
        return True, "artist mesh: reduce, carve yarn tracks, export taxels"
    if kind == "pad":
        return False, "flat pad: no artist mesh, no tracks"
    if kind == "solid":
        return False, "solid given: used as is, no reduction or tracks"
    return False, "no geometry: evaluation only"


def _tracks_run(scene, ctx, out_dir):
    from fruitcli.geometry.tracks.make_tracks import SCENE_NAMES, make_tracks

    geo, tr, grid = scene.geometry, scene.tracks, scene.grid
    report = make_tracks(
        geo.artist,
        out_dir,
        unit=geo.unit,
        cover_mm=tr.cover_mm,
        faces=tr.faces,
        spacing_x_mm=grid.spacing_x_mm,
        spacing_y_mm=grid.spacing_y_mm,
        origin_mm=grid.origin_mm,
        track_radius_mm=tr.track_radius_mm,
        split_z_mm=tr.split_z_mm,
        fit_mm=geo.fit_mm,
        progress=ctx.progress,
        names=SCENE_NAMES,
    )
    return {"taxels": report["taxels"], "hausdorff_mm": report["offset_error"]["hausdorff_mm"]}


# ----------------------------------------------------------------------------- pad-grid
def _pad_needed(scene):
    if _geometry_kind(scene) != "pad":
        return False, "not a flat pad"
    if scene.grid.taxels is not None:
        return False, "taxels given"
    return True, "flat pad: taxels on a regular grid on its top face"


def _pad_run(scene, ctx, out_dir):
    from fruitcli.geometry.padgrid import check_pad_size, write_pad_taxels, write_pad_tracks

    grid = scene.grid
    args = (scene.geometry.pad_size_mm, grid.count or [4, 4], grid.spacing_x_mm, grid.spacing_y_mm)
    check_pad_size(args[0], args[1], scene.path.name)
    n = write_pad_taxels(out_dir / "taxels.csv", *args)
    return {"taxels": n, "tracks": write_pad_tracks(out_dir / "tracks.csv", *args)}


# ----------------------------------------------------------------------------- tetra / simulate
def _fem_needed(scene):
    if not has_deformation(scene):
        dropped = gravity_left_out(scene)
        return False, "no deformation: taxels at rest, no FEM" + (f"; {dropped}" if dropped else "")
    if _geometry_kind(scene) == "none":
        return False, "no geometry to mesh"
    return True, _fem_reason(scene)


def _fem_reason(scene):
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


def _tetra_run(scene, ctx, out_dir):
    from fruitcli.fem.stage import run_tetra
    from fruitcli.tables import read_taxels

    tax = taxels_path(scene, ctx)
    xyz = read_taxels(tax).xyz_mm if tax is not None else None
    return run_tetra(scene, solid_path(scene, ctx), out_dir, progress=ctx.progress, taxels_xyz=xyz)


def _simulate_run(scene, ctx, out_dir):
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
def _limits_needed(scene):
    from fruitcli.fem.limits_stage import near_limit

    fem, why = _fem_needed(scene)
    return near_limit(scene) if fem else (False, why)


def _limits_run(scene, ctx, out_dir):
    from fruitcli.fem.limits_stage import run_limits_stage

    mesh = ctx.dir("tetra") / "mesh.npz"
    return run_limits_stage(scene, mesh, out_dir, progress=ctx.progress)


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


def _reduce_needed(scene):
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


def locate_uses_reduced(scene) -> bool:
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


def _reduce_range(scene) -> dict:
    from fruitcli.fem.reduced.build import pressure_box

    names = [c.name for c in scene.chambers]
    lo, hi = pressure_box(scene, names)
    return {n: [float(a), float(b)] for n, a, b in zip(names, lo, hi, strict=True)}


def _reduce_inputs(scene, ctx):
    # the pressure box from [actuation] and [reduced] pressure_range_kpa, margin, not
    # those keys: new states inside the same box keep the model
    return {"range_kpa": _reduce_range(scene)}


def _reduce_run(scene, ctx, out_dir):
    from fruitcli.fem.reduced.build import run_reduce
    from fruitcli.tables import read_taxels

    tax = taxels_path(scene, ctx)
    xyz = read_taxels(tax).xyz_mm if tax is not None else None
    return run_reduce(scene, ctx.dir("tetra") / "mesh.npz", xyz, out_dir, progress=ctx.progress)


def reduced_path(scene: Scene, ctx: Context) -> Path:
    return ctx.dir("reduce") / "reduced.npz"


# ----------------------------------------------------------------------------- skin
def electrostatic(scene: Scene) -> bool:
    """Whether the scene's skin is the computed crossing's (`skin.models.SkinModel.computed`)."""
    return SKIN_MODELS[scene.skin.model].computed


def _skin_needed(scene):
    if not electrostatic(scene):
        return False, f"[skin].model = {scene.skin.model!r}: no crossing table"
    users = [s for s in ("bench", "sensitivity") if scene.has(s)]
    if not users:
        return False, "no [bench] or [sensitivity] to use the crossing's table"
    return True, f"electrostatic skin for the {' and '.join(users)}: the crossing's table"


def _skin_run(scene, ctx, out_dir):
    from fruitcli.electrostatics import design

    table, summary = design.run_crossing(design.crossing_inputs(scene), progress=ctx.progress)
    design.write_outputs(out_dir, table, summary)
    return {
        "c0_ff": summary["c0_ff"],
        "counts_per_ff": summary["counts_per_ff"],
        "contact_counts": {k: v["contact_counts"] for k, v in summary["objects"].items()},
    }


def crossing_dir(scene: Scene, ctx: Context) -> Path | None:
    """The skin stage's folder (crossing.npz, summary.json) for an electrostatic skin."""
    return ctx.dir("skin") if electrostatic(scene) else None


# ----------------------------------------------------------------------------- sensing
def _bench_needed(scene):
    if not scene.has("bench"):
        return False, "no [bench]: no virtual 3D-printer bench"
    return True, f"virtual bench, indenters: {', '.join(indenters(scene))}"


def _bench_inputs(scene, ctx):
    from fruitcli.scene import resolve_path

    # [bench].samples is a string key ("quarter" or a CSV path): the CSV by its content
    spec = scene.bench.samples
    return {} if spec == "quarter" else {"samples": Path(resolve_path(scene.path, spec))}


def _bench_run(scene, ctx, out_dir):
    from fruitcli.sensing.stages import run_bench

    solid = solid_path(scene, ctx)
    unit = scene.geometry.unit if _geometry_kind(scene) == "solid" else "mm"
    return run_bench(
        scene,
        taxels_path(scene, ctx),
        states_path(scene, ctx),
        out_dir,
        progress=ctx.progress,
        surface_path=solid,
        surface_unit=unit,
        crossing_dir=crossing_dir(scene, ctx),
    )


def _frame_sources(scene, ctx) -> dict[str, Path]:
    if scene.has("bench"):
        return {ind: ctx.dir("bench") / ind / "frames.npz" for ind in indenters(scene)}
    if scene.frames.recording is not None:
        return {"recording": scene.frames.recording}
    return {}


def _locate_needed(scene):
    if scene.has("bench"):
        return True, "detect touches in the bench frames, map them to 3D"
    if scene.frames.recording is not None:
        return True, "detect touches in the recording, map them to 3D"
    return False, "no frames: no recording and no bench"


def _locate_run(scene, ctx, out_dir):
    from fruitcli.sensing.stages import run_locate

    out = {}
    unit = scene.geometry.unit if _geometry_kind(scene) == "solid" else "mm"
    reduced = None
    if locate_uses_reduced(scene):
        from fruitcli.fem.reduced.model import load

        reduced = load(reduced_path(scene, ctx))
    for name, frames in _frame_sources(scene, ctx).items():
        out[name] = run_locate(
            scene,
            frames,
            taxels_path(scene, ctx),
            states_path(scene, ctx),
            out_dir / name,
            progress=ctx.progress,
            surface_path=solid_path(scene, ctx),
            surface_unit=unit,
            reduced=reduced,
            crossing_dir=crossing_dir(scene, ctx),
        )
    return out


def _locate_outputs(scene):
    if scene.has("bench"):
        return [f"{ind}/touches.csv" for ind in indenters(scene)]
    return ["recording/touches.csv"]


# ----------------------------------------------------------------------------- evaluate
def _eval_rows(scene, ctx) -> list[dict]:
    rows = scene.values("evaluate")
    if scene.has("bench"):
        config = scene.scene.configuration
        for ind in indenters(scene):
            rows.append(
                {
                    "label": f"{config}, {ind}",
                    "truth": ctx.dir("bench") / ind / "truth.csv",
                    "measured": ctx.dir("locate") / ind / "measured.csv",
                    "reference_length_mm": scene.bench.reference_length_mm,
                    "register": scene.bench.register,
                }
            )
    return rows


def _eval_needed(scene):
    if scene.has("bench"):
        return True, "bench ground truth against located touches"
    if scene.evaluate:
        return True, "evaluation only: measured points given"
    return False, "no ground truth"


def _eval_run(scene, ctx, out_dir):
    from fruitcli.evaluation.report import evaluate_pair, write_many

    results = [
        evaluate_pair(
            r["truth"], r["measured"], r["reference_length_mm"], r["label"], r["register"]
        )
        for r in _eval_rows(scene, ctx)
    ]
    summaries = write_many(out_dir, results)
    return {
        s["label"]: {
            k: round(v, 4) if isinstance(v, float) else v for k, v in s.items() if k != "label"
        }
        for s in summaries
    }


# ----------------------------------------------------------------------------- sensitivity
def _sens_needed(scene):
    if not scene.has("sensitivity"):
        return False, "no [sensitivity]"
    return True, "noise std at rest and baseline shift over the states"


def _sens_run(scene, ctx, out_dir):
    from fruitcli.sensing.stages import run_sensitivity

    return run_sensitivity(
        scene,
        taxels_path(scene, ctx),
        states_path(scene, ctx),
        out_dir,
        progress=ctx.progress,
        crossing_dir=crossing_dir(scene, ctx),
    )


STAGES: list[Stage] = [
    Stage(
        "make-artist",
        [],
        "fruitcli.geometry.artist",
        _artist_needed,
        # nothing but the code: the mesh it writes is the same wherever it goes, so a scene
        # copied elsewhere (`fruit demo`'s OUT/scenes/) keeps every later stage's hash; a
        # path without the file fails the outputs check and the stage runs again
        no_inputs,
        _artist_run,
        lambda s: [str(s.geometry.artist)],
        reads=("geometry.generate_artist",),
        decides=GEOMETRY_KIND,
        derived=("geometry.artist",),
    ),
    Stage(
        "make-tracks",
        ["make-artist"],
        "fruitcli.geometry.tracks.make_tracks",
        _tracks_needed,
        no_inputs,
        _tracks_run,
        lambda s: [
            "reduced.stl",
            "tracked_top.stl",
            "tracks.stl",
            "taxels.csv",
            "tracks.csv",
            "report.json",
            "preview.png",
        ],
        reads=(
            "geometry.artist",
            "geometry.unit",
            "geometry.fit_mm",
            "tracks",
            "grid.spacing_x_mm",
            "grid.spacing_y_mm",
            "grid.origin_mm",
        ),
        minus=YARN_KEYS,
        decides=GEOMETRY_KIND,
    ),
    Stage(
        "pad-grid",
        [],
        "fruitcli.geometry.padgrid",
        _pad_needed,
        no_inputs,
        _pad_run,
        lambda s: ["taxels.csv", "tracks.csv"],
        reads=("geometry.pad_size_mm", "grid"),
        minus=("grid.taxels",),
        decides=(*GEOMETRY_KIND, "grid.taxels"),
    ),
    Stage(
        "tetra",
        ["make-tracks", "pad-grid"],
        "fruitcli.fem.stage",
        _fem_needed,
        no_inputs,
        _tetra_run,
        lambda s: ["mesh.npz", "quality.json"],
        reads=("geometry", "mesh", "grid.taxels"),
        decides=DEFORMS,
    ),
    LIMITS_STAGE,
    Stage(
        "simulate",
        ["tetra", "make-tracks", "pad-grid", "limits"],
        "fruitcli.fem.stage",
        _fem_needed,
        no_inputs,
        _simulate_run,
        lambda s: ["states.npz"] + (["yarns.csv"] if _has_tracks(s) else []),
        reads=(*DEFORMS, "geometry", "fem", "material", "solver", "grid") + YARN_KEYS,
    ),
    Stage(
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
    ),
    Stage(
        "skin",
        [],
        "fruitcli.electrostatics",
        _skin_needed,
        no_inputs,
        _skin_run,
        lambda s: ["crossing.npz", "summary.json"],
        reads=(  # design.crossing_inputs
            "skin.model",
            "skin.yarn_radius_mm",
            "skin.insulation_mm",
            "skin.permittivity",
            "skin.gaps_mm",
            "tracks.cover_mm",
            "tracks.track_radius_mm",
            "grid.spacing_x_mm",
            "grid.spacing_y_mm",
            "mesh.time_limit_s",
        ),
        decides=("bench", "sensitivity"),
    ),
    Stage(
        "bench",
        ["simulate", "make-tracks", "pad-grid", "skin"],
        "fruitcli.sensing.stages",
        _bench_needed,
        _bench_inputs,
        _bench_run,
        lambda s: (
            [f"{i}/frames.npz" for i in indenters(s)] + [f"{i}/truth.csv" for i in indenters(s)]
        ),
        reads=(*DEFORMS, "bench", "board", "skin", "grid", "geometry")
        + ("detection.threshold_counts", "scene.name"),
    ),
    Stage(
        "locate",
        ["bench", "simulate", "reduce", "skin", "make-tracks", "pad-grid"],
        "fruitcli.sensing.stages",
        _locate_needed,
        no_inputs,
        _locate_run,
        _locate_outputs,
        reads=(*DEFORMS, "frames", "bench", "board", "detection", "skin", "grid", "geometry"),
    ),
    Stage(
        "evaluate",
        ["locate", "bench"],
        "fruitcli.evaluation.report",
        _eval_needed,
        no_inputs,
        _eval_run,
        lambda s: ["table.md", "table.csv", "summary.json"],
        reads=("evaluate", "bench", "scene.configuration"),
    ),
    Stage(
        "sensitivity",
        ["simulate", "make-tracks", "pad-grid", "skin"],
        "fruitcli.sensing.stages",
        _sens_needed,
        no_inputs,
        _sens_run,
        lambda s: ["sensitivity.json"],
        reads=(*DEFORMS, "sensitivity", "bench", "skin", "detection", "grid", "geometry"),
    ),
]
