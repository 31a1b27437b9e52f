"""Running a sweep's variants: one folder each under OUT/variants/, stages shared between
variants run once, a failed variant is a row with its one-line error, a finished variant
is reused by the next run of the same sweep.

Stage sharing: before anything runs, every variant is planned; a stage that two or
more variants would run with the same content hash is run once, as its own task, in the
first such variant's folder, and the others copy it from there (the planner's reuse
across sibling folders, `planner.run(shared=...)`). Each variant's own task waits for
the shared stages it needs.
"""

from __future__ import annotations

import json
import os
import socket
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.studies.executors import Task, run_graph
from fruitcli.studies.sweep import Variant, rebuild

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.studies.executors import DaskPool, LocalPool, Serial

RESULT = "result.json"
# One task at a time per process: a Dask worker with several threads would otherwise run
# variants side by side in one process, and the stages plot with matplotlib, which is not
# thread-safe. Give workers one thread each and more processes instead.
ONE_AT_A_TIME = threading.Lock()
TIMING = ("state_ms", "variant_s")  # columns that vary between runs of the same sweep


@dataclass(frozen=True)
class FigureInputs:
    """What a finished variant's figures read of its scene: its taxel file (None: none),
    ``[skin].counts_per_ff`` (None: the crossing's fitted scale) and
    ``[detection].threshold_counts`` (counts)."""

    taxels: Path | None
    counts_per_ff: float | None
    threshold_counts: float


def figure_inputs(scene: Scene, folder: Path) -> FigureInputs:
    """The `FigureInputs` of a variant's scene whose stages ran into `folder`."""
    from fruitcli.workflow.planner import Context
    from fruitcli.workflow.stage_paths import taxels_path

    return FigureInputs(
        taxels_path(scene, Context(Path(folder))),
        scene.skin.counts_per_ff,
        scene.detection.threshold_counts,
    )


def variant_figures(inputs: FigureInputs, folder: Path) -> dict:
    """The figures of a finished variant's stages: taxel count, tets, FEM states (Newton
    iterations, max displacement mm, median ms per state), Table I rows (n, mean and
    std error mm) and sensitivity (noise std, baseline shift, counts)."""
    from fruitcli.workflow.planner import Context

    ctx = Context(Path(folder))
    out: dict = {}
    tax = inputs.taxels
    if tax is not None and Path(tax).exists():
        lines = [
            ln for ln in Path(tax).read_text().splitlines() if ln.strip() and not ln.startswith("#")
        ]
        out["taxels"] = max(len(lines) - 1, 0)  # less the header
    quality = ctx.dir("tetra") / "quality.json"
    if quality.exists():
        out["tets"] = json.loads(quality.read_text())["n_tets"]
    states = ctx.dir("simulate") / "states.npz"
    if states.exists():
        with np.load(states, allow_pickle=False) as st:
            disp = np.linalg.norm(st["displacement_mm"], axis=-1)
            out.update(
                states=int(len(st["solve_ms"])),
                newton_its=float(np.mean(st["iterations"])),
                max_disp_mm=float(disp.max()) if disp.size else 0.0,
                state_ms=float(np.median(st["solve_ms"])),
            )
    summary = ctx.dir("evaluate") / "summary.json"
    if summary.exists():
        for slug, row in json.loads(summary.read_text()).items():
            out[f"{slug}_n"] = int(row["n"])
            out[f"{slug}_mean_mm"] = float(row["mean_mm"])
            out[f"{slug}_std_mm"] = float(row["std_mm"])
    out.update(skin_figures(inputs, ctx.dir("skin") / "summary.json"))
    sens = ctx.dir("sensitivity") / "sensitivity.json"
    if sens.exists():
        s = json.loads(sens.read_text())["summary"]
        out.update(
            noise_std_max_counts=float(s["std"]["max"]),
            shift_max_counts=float(s["max_shift"]["max"]),
            shift_mean_counts=float(s["max_shift"]["mean"]),
        )
    return out


def skin_figures(inputs: FigureInputs, summary_json: Path) -> dict:
    """The electrostatic crossing's figures (`fruit skin`'s summary.json), in counts of
    ``[skin].counts_per_ff`` when the scene gives it: C0 (fF), each object's activation
    at contact (counts), the bent pad's largest baseline shift (counts, the crossing bent
    as Fig. 9's pad along either yarn, positive towards a false touch) and the bending
    false-touch margin (the threshold less that shift)."""
    if not Path(summary_json).exists():
        return {}
    s = json.loads(Path(summary_json).read_text())
    fitted = float(s["counts_per_ff"])
    scale = inputs.counts_per_ff or fitted
    out = {"c0_ff": float(s["c0_ff"]), "counts_per_ff": scale}
    for name, o in s["objects"].items():
        out[f"contact_counts_{name}"] = float(o["contact_counts"]) * scale / fitted
    shifts = s["deformation_shift_counts"]
    bend = max(float(shifts[f"bend_{a}"][-1]) for a in ("x", "y")) * scale / fitted
    out["bend_shift_max_counts"] = bend
    out["bend_margin_counts"] = inputs.threshold_counts - bend
    return out


def error_line(exc: BaseException) -> str:
    """One line for a failure: a FruitError's own text, else the exception's type too."""
    from fruitcli.errors import FruitError

    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return (
        text
        if isinstance(exc, FruitError) and text
        else f"{type(exc).__name__}: {text}".rstrip(": ")
    )


def _note_attempt(folder: Path, kind: str) -> None:
    """Append who runs this task to folder/attempts.log (one line per start)."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "attempts.log", "a") as f:
        f.write(f"{kind} pid={os.getpid()} host={socket.gethostname()} t={time.time():.3f}\n")


class _Log:
    """The planner's progress lines into folder/log.txt; remembers the stage running."""

    def __init__(self, folder: Path):
        from fruitcli.workflow.stages import STAGES

        self.path, self.stage = folder / "log.txt", ""
        self._names = {s.name for s in STAGES}

    def __call__(self, message: str) -> None:
        head = message.split(":", 1)[0]
        if head in self._names:
            self.stage = head
        with open(self.path, "a") as f:
            f.write(message + "\n")

    def where(self, exc: BaseException) -> str:
        line = error_line(exc)
        return f"{self.stage}: {line}" if self.stage and not line.startswith(self.stage) else line


def _failed_dep(deps: dict) -> str | None:
    return next((r["error"] for r in deps.values() if r.get("error")), None)


def run_stage_task(arg: tuple[str, str, str, str, str], deps: dict) -> dict:
    """On a worker: run a variant's stages up to `stage` (shared with other variants)."""
    text, scene_path, folder, stage, shared = arg
    if (failed := _failed_dep(deps)) is not None:
        return {"error": failed}
    with ONE_AT_A_TIME:
        return _run_stage(text, scene_path, Path(folder), stage, Path(shared))


def _run_stage(text: str, scene_path: str, folder: Path, stage: str, shared: Path) -> dict:
    from fruitcli.workflow import planner

    _note_attempt(folder, f"stage {stage}")
    log = _Log(folder)
    try:
        planner.run(rebuild(text, scene_path), folder, until=stage, shared=shared, progress=log)
    except Exception as exc:
        (folder / "error.log").write_text(traceback.format_exc())
        return {"error": log.where(exc)}
    return {"error": None}


def run_variant_task(arg: tuple[str, str, str, str], deps: dict) -> dict:
    """On a worker: run every stage of one variant (copying the shared ones) and return
    its row: figures, status ("ok" or "failed"), error line, wall time (s)."""
    from fruitcli.fsutil import write_json

    text, scene_path, folder_name, shared = arg
    folder = Path(folder_name)
    if (failed := _failed_dep(deps)) is not None:
        row = {"status": "failed", "error": failed, "variant_s": 0.0}
    else:
        with ONE_AT_A_TIME:
            row = _run_variant(text, scene_path, folder, Path(shared))
    write_json(folder / RESULT, {"scene_text": text, "row": row})
    return row


def _run_variant(text: str, scene_path: str, folder: Path, shared: Path) -> dict:
    from fruitcli.workflow import planner

    t0 = time.perf_counter()
    _note_attempt(folder, "variant")
    log = _Log(folder)
    try:
        scene = rebuild(text, scene_path)
        planner.run(scene, folder, shared=shared, progress=log)
        row = {**variant_figures(figure_inputs(scene, folder), folder), "status": "ok", "error": ""}
    except Exception as exc:
        (folder / "error.log").write_text(traceback.format_exc())
        row = {"status": "failed", "error": log.where(exc)}
    row["variant_s"] = time.perf_counter() - t0
    return row


def finished_row(variant: Variant, folder: Path) -> dict | None:
    """A variant's row from a previous run when it finished with these values and every
    stage would be reused now (no input or code changed); else None."""
    from fruitcli.workflow import planner

    try:
        old = json.loads((folder / RESULT).read_text())
    except (OSError, json.JSONDecodeError):
        return None
    if old.get("scene_text") != variant.text or old.get("row", {}).get("status") != "ok":
        return None
    steps = planner.plan(variant.scene, folder)
    if any(s.action not in ("reuse", "not needed") for s in steps):
        return None
    return {**old["row"], **variant_figures(figure_inputs(variant.scene, folder), folder)}


def build_tasks(variants: list[Variant], variants_dir: Path, todo: list[int]) -> dict:
    """The task graph: ("stage", name, hash) for each stage two or more of the variants
    `todo` would run identically, ("variant", k) for each variant in `todo`."""
    from fruitcli.workflow import planner
    from fruitcli.workflow.stages import STAGES

    deps_of = {s.name: s.deps for s in STAGES}
    runs: dict[int, list[tuple[str, str]]] = {}
    owner: dict[tuple[str, str], int] = {}
    count: dict[tuple[str, str], int] = {}
    for k in todo:
        v = variants[k]
        steps = planner.plan(v.scene, variants_dir / v.name, shared=variants_dir)
        runs[k] = [(s.stage, s.hash) for s in steps if s.action == "run" and s.hash]
        for key in runs[k]:
            owner.setdefault(key, k)
            count[key] = count.get(key, 0) + 1
    shared = {key for key, n in count.items() if n >= 2}
    scene_path = str(variants[todo[0]].scene.path) if todo else ""
    tasks: dict = {}
    for k in todo:  # stage tasks first, in pipeline order within each owner
        for key in runs[k]:
            if key in shared and owner[key] == k:
                upstream = _closure(deps_of, key[0]) - {key[0]}
                deps = tuple(("stage", *j) for j in runs[k] if j in shared and j[0] in upstream)
                v = variants[k]
                tasks[("stage", *key)] = Task(
                    run_stage_task,
                    (v.text, scene_path, str(variants_dir / v.name), key[0], str(variants_dir)),
                    deps,
                )
    for k in todo:
        v = variants[k]
        deps = tuple(("stage", *key) for key in runs[k] if key in shared)
        tasks[("variant", k)] = Task(
            run_variant_task,
            (v.text, scene_path, str(variants_dir / v.name), str(variants_dir)),
            deps,
        )
    return tasks


def _closure(deps_of: dict, name: str) -> set[str]:
    out, todo = set(), [name]
    while todo:
        n = todo.pop()
        if n not in out:
            out.add(n)
            todo.extend(deps_of[n])
    return out


def run_sweep(
    variants: list[Variant],
    out_dir: Path,
    pool: Serial | LocalPool | DaskPool,
    progress: Callable[[int, int, dict | None], None] | None = None,
    on_row: Callable[[list[dict | None]], None] | None = None,
) -> tuple[list[dict], dict[str, int]]:
    """Run (or reuse) every variant on `pool`; returns the rows in variant order and
    counts {"run", "reused", "failed", "shared_stages"}. `progress(done, total, row)`
    after each variant, and with {"stage", "error"} after each shared stage;
    `on_row(rows)` with the rows so far (None: not yet done)."""
    out_dir = Path(out_dir).resolve()
    variants_dir = out_dir / "variants"
    variants_dir.mkdir(parents=True, exist_ok=True)
    rows: list[dict | None] = [None] * len(variants)
    todo = []
    for k, v in enumerate(variants):
        old = finished_row(v, variants_dir / v.name)
        if old is not None:
            rows[k] = _with_values(v, old)
        else:
            todo.append(k)
    reused = len(variants) - len(todo)
    tasks = build_tasks(variants, variants_dir, todo)
    done = reused
    if progress and reused:
        progress(done, len(variants), None)

    def on_done(key: tuple, result: dict):
        nonlocal done
        if key[0] != "variant":
            if progress:
                progress(
                    done,
                    len(variants),
                    {
                        "stage": key[1],
                        "error": result["error"],
                        "variant": Path(tasks[key].arg[2]).name,
                    },
                )
            return
        rows[key[1]] = _with_values(variants[key[1]], result)
        done += 1
        if on_row:
            on_row(rows)
        if progress:
            progress(done, len(variants), rows[key[1]])

    def on_lost(key: tuple, message: str):
        if key[0] == "variant":
            return {"status": "failed", "error": message, "variant_s": 0.0}
        return {"error": f"{key[1]}: {message}"}

    run_graph(pool, tasks, on_done, on_lost)
    finished = [r for r in rows if r is not None]
    assert len(finished) == len(rows), "every variant has its row once the graph has run"
    stats = {
        "run": len(todo),
        "reused": reused,
        "failed": sum(r["status"] != "ok" for r in finished),
        "shared_stages": sum(1 for key in tasks if key[0] == "stage"),
    }
    return finished, stats


def _with_values(v: Variant, row: dict) -> dict:
    return {"variant": v.name, **v.values, **row}
