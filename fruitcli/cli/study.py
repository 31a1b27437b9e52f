"""`fruit study`: the error-against-run-time, stability, bench and two-finger studies."""

from __future__ import annotations

import contextlib
from pathlib import Path

import click

from fruitcli.cli.options import fruit_errors, jobs_option, out_option, quiet, scheduler_option


def _bar(label: str):
    silent = quiet()

    def progress(done: int, total: int):
        if not silent:
            click.echo(f"\r{label}: {done}/{total} cases", err=True, nl=done == total)

    return progress


@contextlib.contextmanager
def _cases_pool(jobs: int | None, scheduler: str | None, out: Path | None):
    """Local processes (--jobs) or a Dask cluster (--scheduler) whose workers see `out`."""
    from fruitcli.studies.executors import open_executor

    if jobs is not None and scheduler:
        raise click.UsageError("give --jobs or --scheduler, not both")
    pool = open_executor(jobs, scheduler, out)
    try:
        yield pool
    finally:
        pool.close()


@click.group()
def study() -> None:
    """Studies over many independent cases, run in parallel worker processes."""


@study.command()
@out_option(
    "Output folder: stability.md, .csv, .json.", required=False, default="out/study-stability"
)
@click.option(
    "--group",
    "groups",
    multiple=True,
    metavar="NAME",
    help="Run only this group of cases (repeatable), e.g. 'fruit, gmsh'. [default: all]",
)
@jobs_option()
@scheduler_option("the cases")
def stability(out_dir, groups, jobs, scheduler) -> None:
    """Stiff and extreme FEM cases: E 1 kPa..1 GPa, nu 0..0.4999, pressure until elements
    would invert, jig stiffness 1e-3..1e6 N/mm, a sliver tet, an unsupported body; and
    realistic bodies meshed by gmsh (a thick sphere, the default Fruit) from 5 kPa to
    2000 kPa and down to -500 kPa, each state checked against its chambers' limits.

    Each row: converged or the named failure, Newton iterations, load-step subdivisions,
    final residual, max displacement (mm), min det F, time (s).
    """
    from fruitcli.fsutil import staged_dir, write_csv, write_json, write_text
    from fruitcli.studies.machine import machine_line
    from fruitcli.studies.parallel import run_cases
    from fruitcli.studies.stability import (
        HEADER,
        add_scaling_columns,
        default_cases,
        run_case,
        table_markdown,
    )

    with fruit_errors():
        cases = default_cases()
        known = list(dict.fromkeys(c.group for c in cases))
        unknown = [g for g in groups if g not in known]
        if unknown:
            raise click.BadParameter(
                f"'{unknown[0]}' is not a group (groups: {'; '.join(known)})",
                param_hint="--group",
            )
        cases = [c for c in cases if not groups or c.group in groups]
        with _cases_pool(jobs, scheduler, None) as pool:
            rows = run_cases(run_case, cases, progress=_bar("stability"), pool=pool)
        add_scaling_columns(rows)
        text = table_markdown(rows)
        with staged_dir(out_dir) as tmp:
            write_text(tmp / "stability.md", f"# Stability study\n\n{machine_line()}\n\n{text}")
            write_csv(
                tmp / "stability.csv",
                HEADER,
                [[r.get(h) for h in HEADER] for r in rows],
                comments=["units: max_disp_mm in mm, seconds in s"],
            )
            write_json(tmp / "stability.json", rows)
    click.echo(text, nl=False)
    click.echo(f"written to {Path(out_dir)}/")


@study.command()
@click.argument(
    "scene_file",
    metavar="SCENE",
    type=click.Path(dir_okay=False),
    default="pipelines/fruit-deformed.toml",
)
@out_option(
    "Output folder: runtime.md, runtime.json, runtime.png.",
    required=False,
    default="out/study-runtime",
)
@jobs_option()
@scheduler_option("the FEM settings")
def runtime(scene_file, out_dir, jobs, scheduler) -> None:
    """Error against run time on SCENE (default: the Fruit in its jig): FEM mesh size,
    Newton tolerance and iteration cap, linear solver, detection variant.

    For each setting: time per FEM state (ms), time per frame (us), the taxels' position
    error in the deformed state against the finest setting (mm), and the localization
    error on the bench (mm). The plot marks the Pareto front.
    """
    from fruitcli.cli.options import Progress
    from fruitcli.scene import load_scene
    from fruitcli.studies import runtime as rt
    from fruitcli.studies.parallel import run_cases
    from fruitcli.workflow import planner
    from fruitcli.workflow.stage_paths import required_taxels_path, solid_path, states_path

    with fruit_errors(), contextlib.ExitStack() as stack:
        scene = load_scene(scene_file)
        fem = planner.plan(scene, Path(out_dir) / "scene", until="simulate")[-1]
        if fem.action not in ("run", "reuse"):
            raise click.UsageError(
                f"{scene_file}: the scene has no FEM to study (no "
                "deformation or no geometry: see `fruit run --dry-run`)"
            )
        out = Path(out_dir).resolve() if scheduler else Path(out_dir)  # same on workers
        pool = stack.enter_context(_cases_pool(jobs, scheduler, out))
        base = out / "scene"
        # the scene's own stages: copied from the demo's out/<scene> when identical
        planner.run(scene, base, progress=Progress("   "), shared=out.resolve().parent)
        ctx = planner.Context(base)
        solid, taxels = solid_path(scene, ctx), required_taxels_path(scene, ctx)
        work = out / "work"
        work.mkdir(parents=True, exist_ok=True)
        default = scene.mesh.size_mm
        cases = rt.fem_cases(default)
        # meshes first (one per size, in parallel), then the solver variants reuse them
        by_size: dict[float, rt.FemCase] = {}
        for c in cases:
            by_size.setdefault(c.size_mm, c)
        first = list(by_size.values())
        rest = [c for c in cases if c not in first]
        args = [(scene.path, work, solid, taxels, c) for c in first]
        rows = run_cases(rt.run_fem_case, args, progress=_bar("runtime: meshes"), pool=pool)
        args = [(scene.path, work, solid, taxels, c) for c in rest]
        rows += run_cases(
            rt.run_fem_case, args, progress=_bar("runtime: solver settings"), pool=pool
        )
        order = {c.name: n for n, c in enumerate(cases)}
        rows.sort(key=lambda r: order[r["setting"]])
        rt.add_errors(rows)
        det = []
        if scene.has("bench"):
            from fruitcli.sensing.stages import locate_inputs

            det = rt.run_detection_variants(
                locate_inputs(scene), ctx.dir("bench"), taxels, states_path(scene, ctx), work
            )
        rt.write_outputs(out, rows, det, f"size {default:g} mm")
    click.echo((out / "runtime.md").read_text(), nl=False)


def _bench_scene(scene_file: str | Path, out: Path):
    """The scene with a [bench] and its stages up to the bench, run (or copied from the
    demo's out/<scene>) into OUT/scene -> (scene, taxels, states, solid, unit, work)."""
    from fruitcli.cli.options import Progress
    from fruitcli.scene import load_scene
    from fruitcli.workflow import planner
    from fruitcli.workflow.stage_paths import geometry_kind, solid_path, states_path, taxels_path

    scene = load_scene(scene_file)
    if not scene.has("bench"):
        raise click.UsageError(f"{scene_file}: the scene has no [bench] to study")
    base = out / "scene"
    planner.run(
        scene, base, until="simulate", progress=Progress("   "), shared=out.resolve().parent
    )
    ctx = planner.Context(base)
    taxels = taxels_path(scene, ctx)
    if taxels is None:
        raise click.UsageError(f"{scene_file}: the scene has no taxels to study")
    unit = scene.geometry.unit if geometry_kind(scene) == "solid" else "mm"
    work = out / "work"
    work.mkdir(parents=True, exist_ok=True)
    return scene, taxels, states_path(scene, ctx), solid_path(scene, ctx), unit, work


@study.command("bench")
@click.argument(
    "scene_file",
    metavar="SCENE",
    type=click.Path(dir_okay=False),
    default="pipelines/fruit-rest.toml",
)
@out_option(
    "Output folder: bench.md, bench.csv, bench.json, bench.png.",
    required=False,
    default="out/study-bench",
)
@jobs_option()
def bench_study(scene_file, out_dir, jobs) -> None:
    """What the virtual bench's Table I rows of SCENE depend on: the skin model's assumed
    parameters ([skin]: footprint width, counts at contact, gap decay, noise std, taxel
    gain spread), one at a time off its default, same seed; and, with a body surface, the
    default located with [detection].project = "surface".

    For each setting and indenter: n, the mean and std of the error unregistered and
    translation-registered (the paper's protocol, mm), and the registered mean's
    bootstrap 95 % interval. The plot has one panel per parameter.
    """
    from fruitcli.fsutil import staged_dir, write_csv, write_json, write_text
    from fruitcli.studies import virtual_bench_study as bs
    from fruitcli.studies.parallel import run_cases
    from fruitcli.workflow.report import PAPER_TABLE_I

    with fruit_errors():
        out = Path(out_dir)
        scene, taxels, states, solid, unit, work = _bench_scene(scene_file, out)
        args = [
            (scene.path, work, taxels, states, solid, unit, c)
            for c in bs.cases(scene.skin, list(scene.bench.indenters), solid is not None)
        ]
        results = run_cases(bs.run_case, args, jobs, _bar("bench study"))
        rows = [r for res in results for r in res["rows"]]
        text = bs.table_markdown(rows, scene.name, PAPER_TABLE_I)
        with staged_dir(out) as tmp:
            write_text(tmp / "bench.md", text)
            write_csv(
                tmp / "bench.csv",
                bs.HEADER,
                bs.csv_rows(rows),
                comments=[
                    f"bench study of {scene.name}: errors in mm, registered = "
                    "translation (the paper's protocol)"
                ],
            )
            write_json(
                tmp / "bench.json",
                {"scene": scene.name, "skin_defaults": scene.values("skin"), "rows": rows},
            )
            bs.plot(tmp / "bench.png", rows, scene.skin, PAPER_TABLE_I)
    click.echo(text, nl=False)
    click.echo(f"written to {out}/")


@study.command("locate")
@click.argument(
    "scene_file",
    metavar="SCENE",
    type=click.Path(dir_okay=False),
    default="pipelines/fruit-rest.toml",
)
@out_option(
    "Output folder: locate_methods.md, .csv, .json, .png.",
    required=False,
    default="out/study-locate",
)
@jobs_option()
def locate_study(scene_file, out_dir, jobs) -> None:
    """Error against run time of every detection method ([detection].method), and of the
    model method with a 3x3 window and other iteration caps, on SCENE's
    virtual bench, replayed on boards whose skin the locator does not assume: taxel gains
    spread +-20 % with the skin calibrated on another run, an electrostatic board located
    with a calibrated Gaussian and the reverse, a wider and a narrower footprint. Per
    board, method and indenter: the mean error unregistered and translation-registered
    (mm) and the time per frame of `fruit locate`'s loop (us). Use
    pipelines/fruit-deformed.toml for the deformed states.
    """
    from fruitcli.fsutil import staged_dir, write_csv, write_json, write_text
    from fruitcli.studies import locate_methods as lm
    from fruitcli.studies.machine import machine_line
    from fruitcli.studies.parallel import run_cases

    with fruit_errors():
        out = Path(out_dir)
        scene, taxels, states, solid, unit, work = _bench_scene(scene_file, out)
        args = [(scene.path, work, taxels, states, solid, unit, name) for name in lm.BENCH_SKINS]
        results = run_cases(lm.run_case, args, jobs, _bar("locate study"))
        rows = [r for res in results for r in res]
        text = lm.table_markdown(rows, scene.name, machine_line())
        with staged_dir(out) as tmp:
            write_text(tmp / "locate_methods.md", text)
            write_csv(
                tmp / "locate_methods.csv",
                lm.HEADER,
                ([r[k] for k in lm.HEADER] for r in rows),
                comments=[f"detection methods on {scene.name}: errors in mm, time in us"],
            )
            write_json(tmp / "locate_methods.json", {"scene": scene.name, "rows": rows})
            lm.plot(tmp / "locate_methods.png", rows, scene.name)
    click.echo(text, nl=False)
    click.echo(f"written to {out}/")


@study.command("two-fingers")
@out_option(
    "Output folder: two_fingers.md, two_fingers.csv, single_fingers.csv, two_fingers.png.",
    required=False,
    default="out/study-two-fingers",
)
@click.option(
    "--trials",
    type=click.IntRange(min=2),
    default=40,
    show_default=True,
    help="Frames per axis and distance.",
)
@click.option(
    "--seed", type=int, default=0, show_default=True, help="Seed of the skin and the noise."
)
@click.option(
    "--body",
    "bodies",
    type=click.Choice(["rest", "bent", "stretched"]),
    multiple=True,
    help="The grid's body: rest (flat), bent (on a cylinder) or stretched (inflated on a "
    "dome); repeat for several. Default: all three.",
)
def two_fingers(out_dir, trials, seed, bodies) -> None:
    """Two fingers close together on the virtual bench: how often the paper's N9
    multitouch and the two-footprint fit ([detection].method = "fit2") report two touches,
    at 0.5-3 pitches along i, j and the diagonal, on the grid at rest and deformed, and
    their errors (mm); single fingers to check that fit2 does not make them worse. Writes
    a table per body and a plot of the separation rate against distance."""
    from fruitcli.studies.two_fingers import BODIES, write

    with fruit_errors():
        res = write(out_dir, seed, trials, bodies or BODIES)
    for body, m, n, rate, med, p95 in res["singles"]:
        click.echo(
            f"single fingers, {body}, {m}: {rate:.1%} of {n} one touch, error median "
            f"{med:.2f} mm, p95 {p95:.2f} mm",
            err=True,
        )
    click.echo(f"-> {out_dir}/two_fingers.md", err=True)


@study.command("heights")
@out_option(
    "Output folder: hover_heights.md, hover_heights.csv.",
    required=False,
    default="out/study-heights",
)
def heights(out_dir) -> None:
    """Hover heights on virtual-bench descents the skin was not calibrated on (another
    run, other points, the other indenter, a skin whose gains spread): height error per
    band of true height, the largest height still detected, and the position error of
    hovers against touches (mm)."""
    from fruitcli.studies.hover_heights import write

    with fruit_errors():
        res = write(out_dir)
    for name, e in res["extras"].items():
        click.echo(
            f"{name}: detected up to {e['largest_hover_mm']:.2f} mm (median), "
            f"position error hovers {e['hover_position_error_mm']:.2f} mm, touches "
            f"{e['touch_position_error_mm']:.2f} mm",
            err=True,
        )
    click.echo(f"-> {out_dir}/hover_heights.md", err=True)
