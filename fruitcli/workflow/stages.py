"""The pipeline's stages, in dependency order, as the planner sees them.

Each entry says when a scene needs the stage (and why not, when it does not), what
goes into its content hash, and which library function does the work. The heavy
modules are imported only when a stage runs.
"""

from __future__ import annotations

from pathlib import Path

from fruitcli.scene import Scene, has_deformation, n_states
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


def _has_tracks(scene: Scene) -> bool:
    return scene.tracks.file is not None or _geometry_kind(scene) == "artist"


def tracks_path(scene: Scene, ctx: Context) -> Path | None:
    """Where this scene's yarn track centre lines come from ([tracks] file, or the
    tracks.csv of make-tracks), or None: no yarns.csv."""
    if scene.tracks.file is not None:
        return scene.tracks.file
    return ctx.dir("make-tracks") / "tracks.csv" if _has_tracks(scene) else None


YARN_KEYS = ("yarn_max_stretch", "zigzag_pitch_mm", "file")
"""[tracks] keys read by simulate (yarns.csv), not by make-tracks."""


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


def _tracks_inputs(scene, ctx):
    grid = scene.grid
    return {
        "artist": scene.geometry.artist,
        "unit": scene.geometry.unit,
        "fit_mm": scene.geometry.fit_mm,
        "tracks": {k: v for k, v in scene.values("tracks").items() if k not in YARN_KEYS},
        "grid": {
            "spacing_x_mm": grid.spacing_x_mm,
            "spacing_y_mm": grid.spacing_y_mm,
            "origin_mm": grid.origin_mm,
        },
    }


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


def _pad_inputs(scene, ctx):
    return {"pad": scene.geometry.pad_size_mm, "grid": scene.values("grid")}


def _pad_run(scene, ctx, out_dir):
    from fruitcli.geometry.padgrid import write_pad_taxels

    grid = scene.grid
    n = write_pad_taxels(
        out_dir / "taxels.csv",
        scene.geometry.pad_size_mm,
        grid.count or [4, 4],
        grid.spacing_x_mm,
        grid.spacing_y_mm,
    )
    return {"taxels": n}


# ----------------------------------------------------------------------------- tetra / simulate
def _fem_needed(scene):
    if not has_deformation(scene):
        return False, "no deformation: taxels at rest, no FEM"
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
    if not scene.has("gravity"):
        parts.append("no gravity")
    return "; ".join(parts)


def _tetra_inputs(scene, ctx):
    return {
        "solid": solid_path(scene, ctx),
        "unit": scene.geometry.unit,
        "pad": scene.geometry.pad_size_mm,
        "chambers": scene.values("geometry")["chamber"],
        "mesh": scene.values("mesh"),
        "taxels": taxels_path(scene, ctx),
    }


def _tetra_run(scene, ctx, out_dir):
    from fruitcli.fem.stage import run_tetra
    from fruitcli.tables import read_taxels

    tax = taxels_path(scene, ctx)
    xyz = read_taxels(tax).xyz_mm if tax is not None else None
    return run_tetra(scene, solid_path(scene, ctx), out_dir, progress=ctx.progress, taxels_xyz=xyz)


def _simulate_inputs(scene, ctx):
    tracks = scene.values("tracks")
    return {
        k: scene.values(k) for k in ("material", "gravity", "fixed", "jig", "actuation", "solver")
    } | {
        "has_gravity": scene.has("gravity"),
        "taxels": taxels_path(scene, ctx),
        "mesh": ctx.dir("tetra") / "mesh.npz",
        "tracks": tracks_path(scene, ctx),
        "yarn": {k: tracks[k] for k in YARN_KEYS[:2]},
    }


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
    )


# ----------------------------------------------------------------------------- limits
def _limits_needed(scene):
    from fruitcli.fem.limits_stage import near_limit

    fem, why = _fem_needed(scene)
    return near_limit(scene) if fem else (False, why)


def _limits_inputs(scene, ctx):
    return {
        k: scene.values(k)
        for k in ("material", "fem", "gravity", "fixed", "jig", "actuation", "solver")
    } | {"has_gravity": scene.has("gravity"), "mesh": ctx.dir("tetra") / "mesh.npz"}


def _limits_run(scene, ctx, out_dir):
    from fruitcli.fem.limits_stage import run_limits_stage

    mesh = ctx.dir("tetra") / "mesh.npz"
    return run_limits_stage(scene, mesh, out_dir, progress=ctx.progress)


LIMITS_STAGE = Stage(
    "limits",
    ["tetra"],
    "fruitcli.fem.limits_stage",
    _limits_needed,
    _limits_inputs,
    _limits_run,
    lambda s: ["limits.json"],
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
    cfg = {
        k: v
        for k, v in scene.values("reduced").items()
        if k not in ("pressure_range_kpa", "margin")
    }
    return {
        k: scene.values(k) for k in ("material", "fem", "gravity", "fixed", "jig", "solver")
    } | {
        "has_gravity": scene.has("gravity"),
        "taxels": taxels_path(scene, ctx),
        "mesh": ctx.dir("tetra") / "mesh.npz",
        "range_kpa": _reduce_range(scene),
        "reduced": cfg,
    }


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
    return scene.skin.model == "electrostatic"


def _skin_needed(scene):
    if not electrostatic(scene):
        return False, f"[skin].model = {scene.skin.model!r}: no crossing table"
    users = [s for s in ("bench", "sensitivity") if scene.has(s)]
    if not users:
        return False, "no [bench] or [sensitivity] to use the crossing's table"
    return True, f"electrostatic skin for the {' and '.join(users)}: the crossing's table"


def _skin_inputs(scene, ctx):
    from fruitcli.electrostatics.design import crossing_inputs

    return crossing_inputs(scene).to_dict()


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

    spec = scene.bench.samples  # "quarter" or a CSV, hashed by its content
    samples = spec if spec == "quarter" else Path(resolve_path(scene.path, spec))
    return {
        "bench": scene.values("bench"),
        "samples": samples,
        "board": scene.values("board"),
        "detection": scene.values("detection"),
        "taxels": taxels_path(scene, ctx),
        "states": states_path(scene, ctx),
        "grid": scene.values("grid"),
        "surface": solid_path(scene, ctx),
        "skin": scene.values("skin"),
    } | ({"crossing": ctx.dir("skin") / "crossing.npz"} if electrostatic(scene) else {})


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


def _locate_inputs(scene, ctx):
    return {
        "frames": _frame_sources(scene, ctx),
        "taxels": taxels_path(scene, ctx),
        "states": states_path(scene, ctx),
        "detection": scene.values("detection"),
        "board": scene.values("board"),
        "surface": solid_path(scene, ctx) if scene.detection.project == "surface" else None,
        "reduced": reduced_path(scene, ctx) if locate_uses_reduced(scene) else None,
    }


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


def _sens_inputs(scene, ctx):
    return {
        "sensitivity": scene.values("sensitivity"),
        "bench": scene.values("bench"),
        "skin": scene.values("skin"),
        "taxels": taxels_path(scene, ctx),
        "states": states_path(scene, ctx),
    } | ({"crossing": ctx.dir("skin") / "crossing.npz"} if electrostatic(scene) else {})


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
        lambda s, c: {"artist": str(s.geometry.artist)},
        _artist_run,
        lambda s: [str(s.geometry.artist)],
    ),
    Stage(
        "make-tracks",
        ["make-artist"],
        "fruitcli.geometry.tracks.make_tracks",
        _tracks_needed,
        _tracks_inputs,
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
    ),
    Stage(
        "pad-grid",
        [],
        "fruitcli.geometry.padgrid",
        _pad_needed,
        _pad_inputs,
        _pad_run,
        lambda s: ["taxels.csv"],
    ),
    Stage(
        "tetra",
        ["make-tracks", "pad-grid"],
        "fruitcli.fem.stage",
        _fem_needed,
        _tetra_inputs,
        _tetra_run,
        lambda s: ["mesh.npz", "quality.json"],
    ),
    LIMITS_STAGE,
    Stage(
        "simulate",
        ["tetra", "make-tracks", "pad-grid", "limits"],
        "fruitcli.fem.stage",
        _fem_needed,
        _simulate_inputs,
        _simulate_run,
        lambda s: ["states.npz"] + (["yarns.csv"] if _has_tracks(s) else []),
    ),
    Stage(
        "reduce",
        ["tetra", "make-tracks", "pad-grid"],
        "fruitcli.fem.reduced.build",
        _reduce_needed,
        _reduce_inputs,
        _reduce_run,
        lambda s: ["reduced.npz", "validation.json"],
    ),
    Stage(
        "skin",
        [],
        "fruitcli.electrostatics",
        _skin_needed,
        _skin_inputs,
        _skin_run,
        lambda s: ["crossing.npz", "summary.json"],
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
    ),
    Stage(
        "locate",
        ["bench", "simulate", "reduce"],
        "fruitcli.sensing.stages",
        _locate_needed,
        _locate_inputs,
        _locate_run,
        _locate_outputs,
    ),
    Stage(
        "evaluate",
        ["locate"],
        "fruitcli.evaluation.report",
        _eval_needed,
        lambda s, c: {"rows": _eval_rows(s, c)},
        _eval_run,
        lambda s: ["table.md", "table.csv", "summary.json"],
    ),
    Stage(
        "sensitivity",
        ["simulate", "make-tracks", "pad-grid", "skin"],
        "fruitcli.sensing.stages",
        _sens_needed,
        _sens_inputs,
        _sens_run,
        lambda s: ["sensitivity.json"],
    ),
]
