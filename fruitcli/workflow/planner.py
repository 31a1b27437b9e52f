"""The stage planner: which stages a scene needs, in dependency order, and which of
them can reuse their previous outputs.

Each stage writes into `OUT/<stage>/` and leaves a `manifest.json` holding a content
hash of everything that went in (scene parameters, input files, upstream manifests).
A stage is reused while that hash is unchanged and its outputs are all present.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import json
import shutil
import tempfile
import time
from pathlib import Path

from fruitcli.errors import FruitError
from fruitcli.scene import Scene
from fruitcli.workflow.scene_hash import content, scene_inputs
from fruitcli.workflow.stage_types import Context, Stage, Step
from fruitcli.workflow.stages import STAGES

MANIFEST = "manifest.json"
PLANNER_VERSION = 2  # 2: scene inputs from the stages' declared reads, files by content


def _canonical(obj):
    if isinstance(obj, Path):
        return content(obj)
    if isinstance(obj, dict):
        return {str(k): _canonical(v) for k, v in sorted(obj.items())}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    return obj


def fingerprint(stage: Stage, scene: Scene, ctx: Context) -> str:
    """Content hash of a stage's inputs: the scene keys it declares it reads (files by
    content), what its `inputs` adds, its code and its upstream stages' hashes."""
    payload = {
        "planner": PLANNER_VERSION,
        "stage": stage.name,
        "code": _code_hash(stage.module),
        "scene": scene_inputs(scene, stage.reads, stage.minus),
        "inputs": _canonical(stage.inputs(scene, ctx)),
        "upstream": {d: ctx.hashes.get(d, "") for d in stage.deps},
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


@functools.cache
def _code_hash(module: str) -> str:
    """Hash of the stage's package sources (subpackages included) and of the sibling
    packages and modules they import (one level: `from <root>.x ...`), so a code
    change there reruns the stage.
    Computed once per process: the code a process runs is the code it imported, so a
    later edit of the files must not change the fingerprints it writes (and a sweep
    fingerprints every stage of every variant)."""
    return file_hash_many(code_files(module))


def code_files(module: str) -> list[Path]:
    """The source files `_code_hash` covers for `module` (sorted)."""
    import re

    root = module.split(".")[0]
    pkg_dir = Path(importlib.import_module(module).__file__).parent
    top = Path(importlib.import_module(root).__file__).parent
    files = set(pkg_dir.rglob("*.py"))  # with its subpackages (fem/elements, ...)
    pattern = re.compile(rf"^\s*(?:from|import)\s+{root}\.(\w+)", re.MULTILINE)
    for name in {m for f in list(files) for m in pattern.findall(f.read_text())}:
        if (top / name).is_dir():
            files.update((top / name).rglob("*.py"))
        elif (top / f"{name}.py").exists():
            files.add(top / f"{name}.py")
    return sorted(files)


def file_hash_many(paths) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()


def _holds(folder: Path, stage: Stage, scene: Scene, digest: str) -> bool:
    """True when `folder` has this stage's manifest with `digest` and all its outputs."""
    try:
        old = json.loads((folder / MANIFEST).read_text())
    except (OSError, json.JSONDecodeError):
        return False
    return old.get("hash") == digest and all((folder / o).exists() for o in stage.outputs(scene))


def _reusable(stage: Stage, scene: Scene, ctx: Context, digest: str) -> bool:
    return _holds(ctx.dir(stage.name), stage, scene, digest)


def _copy_in(source: Path, folder: Path) -> None:
    """Copy the stage folder `source` whole beside `folder` under a name of this process
    (concurrent runs never share it), then swap it in. A run that swapped in the same
    stage meanwhile wins: its copy has the same inputs."""
    from fruitcli.fsutil import owned_prefix, sweep_orphans

    folder.parent.mkdir(parents=True, exist_ok=True)
    sweep_orphans(folder.parent, f".{folder.name}.copying.")
    holder = Path(
        tempfile.mkdtemp(prefix=owned_prefix(f".{folder.name}.copying."), dir=folder.parent)
    )
    try:
        shutil.copytree(source, holder / folder.name)
        for attempt in range(10):
            try:  # the old folder moved aside whole, then the copy moved in whole
                folder.rename(holder / f"old{attempt}")
            except FileNotFoundError:
                pass
            try:
                (holder / folder.name).rename(folder)
                return
            except OSError:  # another run's copy moved in meanwhile: the same inputs
                if (folder / MANIFEST).exists():
                    return
        raise FruitError(f"{folder}: another run keeps replacing it; run again")
    finally:
        shutil.rmtree(holder, ignore_errors=True)


def plan(
    scene: Scene,
    out_root: Path,
    stages: list[Stage] | None = None,
    until: str | None = None,
    shared: Path | None = None,
) -> list[Step]:
    """Decide run / reuse / not needed for every stage (up to and including `until`),
    in dependency order; with `shared`, a stage `run` would copy from a sibling scene is
    "reuse" too, and the stages after it are judged on the sibling's outputs."""

    stages = STAGES if stages is None else stages
    wanted = _wanted(stages, until)
    ctx = Context(Path(out_root), shared=shared)
    steps = []
    for stage in stages:
        if stage.name not in wanted:
            continue
        needed, reason = stage.needed(scene)
        if not needed:
            steps.append(Step(stage.name, "not needed", reason))
            continue
        try:
            digest = fingerprint(stage, scene, ctx)
        except FileNotFoundError:
            digest = ""
        ctx.hashes[stage.name] = digest
        if digest and _reusable(stage, scene, ctx, digest):
            steps.append(Step(stage.name, "reuse", reason, digest))
        elif digest and (source := _borrow(stage, scene, ctx, digest)) is not None:
            ctx.lent[stage.name] = source
            steps.append(
                Step(stage.name, "reuse", f"{reason} (same inputs as {source.parent.name})", digest)
            )
        else:
            steps.append(Step(stage.name, "run", reason, digest))
    return steps


def _borrow(stage: Stage, scene: Scene, ctx: Context, digest: str) -> Path | None:
    """A sibling scene's folder (under ctx.shared) holding this stage with the same hash."""
    if ctx.shared is None:
        return None
    for manifest in sorted(ctx.shared.glob(f"*/{stage.name}/{MANIFEST}")):
        folder = manifest.parent
        if folder != ctx.dir(stage.name) and _holds(folder, stage, scene, digest):
            return folder
    return None


def run(
    scene: Scene,
    out_root: Path,
    until: str | None = None,
    progress=None,
    force: bool = False,
    stages: list[Stage] | None = None,
    shared: Path | None = None,
) -> list[Step]:
    """Run the needed stages (up to and including `until`), reusing unchanged ones.
    With `shared`, a stage whose identical inputs already ran for another scene under
    that folder is copied from there instead of run again."""
    stages = STAGES if stages is None else stages
    wanted = _wanted(stages, until)
    ctx = Context(Path(out_root), progress or (lambda msg: None), shared=shared)
    done = []
    for stage in stages:
        if stage.name not in wanted:
            continue
        needed, reason = stage.needed(scene)
        if not needed:
            done.append(Step(stage.name, "not needed", reason))
            ctx.progress(f"{stage.name}: not needed ({reason})")
            continue
        digest = fingerprint(stage, scene, ctx)
        ctx.hashes[stage.name] = digest
        if not force and _reusable(stage, scene, ctx, digest):
            done.append(Step(stage.name, "reuse", reason, digest))
            ctx.progress(f"{stage.name}: reuse (inputs unchanged)")
            continue
        folder = ctx.dir(stage.name)
        source = None if force else _borrow(stage, scene, ctx, digest)
        if source is not None:  # copied whole beside it, then swapped in: never half
            _copy_in(source, folder)
            done.append(
                Step(stage.name, "reuse", f"{reason} (same inputs as {source.parent.name})", digest)
            )
            ctx.progress(f"{stage.name}: reuse (same inputs as {source.parent.name})")
            continue
        ctx.progress(f"{stage.name}: run ({reason})")
        t0 = time.perf_counter()
        (folder / MANIFEST).unlink(missing_ok=True)
        summary = stage.run(scene, ctx, folder) or {}
        # the manifest is written last: a stage interrupted before this point reruns
        from fruitcli.fsutil import write_json

        write_json(
            folder / MANIFEST,
            {
                "stage": stage.name,
                "hash": digest,
                "reason": reason,
                "seconds": round(time.perf_counter() - t0, 3),
                "outputs": list(stage.outputs(scene)),
                "summary": summary,
            },
        )
        done.append(Step(stage.name, "run", reason, digest))
    return done


def _wanted(stages: list[Stage], until: str | None) -> set[str]:
    """Names of the stages up to and including `until` (and what it needs), or all."""
    names = [s.name for s in stages]
    if until is None:
        return set(names)
    if until not in names:
        raise FruitError(f"unknown stage '{until}' (stages: {', '.join(names)})")
    return _closure({s.name: s for s in stages}, until)


def _closure(by_name: dict[str, Stage], target: str) -> set[str]:
    out, todo = set(), [target]
    while todo:
        name = todo.pop()
        if name not in out:
            out.add(name)
            todo.extend(by_name[name].deps)
    return out


def format_plan(steps: list[Step]) -> str:
    """One line per stage: name, action, reason."""
    width = max(len(s.stage) for s in steps)
    return "\n".join(f"{s.stage:<{width}}  {s.action:<15} {s.reason}" for s in steps)
