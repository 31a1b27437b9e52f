"""The stage planner: which stages a scene needs, in dependency order, and which of
them can reuse their previous outputs.

Each stage writes into `OUT/<stage>/` and leaves a `manifest.json` holding a content
hash of everything that went in (scene parameters, input files, upstream manifests) and
the sha256 of every file it wrote. A stage is reused while that hash is unchanged and
its outputs are all present and unchanged. A stage that runs is built whole in a folder
of its own beside `OUT/<stage>/` and then swapped in, so its folder holds exactly what
a fresh run's would (nothing of an earlier run's), and never half of it.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from fruitcli.errors import FruitError
from fruitcli.fsutil import file_hash_many
from fruitcli.scene import Scene
from fruitcli.workflow.scene_hash import content, scene_inputs
from fruitcli.workflow.stage_types import Context, Stage, Step
from fruitcli.workflow.stages import STAGES

MANIFEST = "manifest.json"
PLANNER_VERSION = 3  # 2: scene inputs from the stages' declared reads, files by content
# 3: the manifest holds its outputs' sha256 ("files")


def _canonical(obj: object):
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


def _folder_of(module: str) -> Path:
    """The folder of an imported module's source file."""
    file = importlib.import_module(module).__file__
    if file is None:  # a namespace package: no file of its own
        raise ImportError(f"{module}: no source file to hash")
    return Path(file).parent


def code_files(module: str) -> list[Path]:
    """The source files `_code_hash` covers for `module` (sorted)."""
    import re

    root = module.split(".")[0]
    pkg_dir, top = _folder_of(module), _folder_of(root)
    files = set(pkg_dir.rglob("*.py"))  # with its subpackages (fem/elements, ...)
    pattern = re.compile(rf"^\s*(?:from|import)\s+{root}\.(\w+)", re.MULTILINE)
    for name in {m for f in list(files) for m in pattern.findall(f.read_text())}:
        if (top / name).is_dir():
            files.update((top / name).rglob("*.py"))
        elif (top / f"{name}.py").exists():
            files.add(top / f"{name}.py")
    return sorted(files)


def output_hashes(folder: Path) -> dict[str, str]:
    """sha256 of every file in a stage folder (path relative to it -> hex digest), its
    manifest and hidden temporary files aside."""
    out = {}
    for path in sorted(Path(folder).rglob("*")):
        rel = path.relative_to(folder)
        if path.is_file() and rel.as_posix() != MANIFEST and not rel.name.startswith("."):
            out[rel.as_posix()] = file_sha256(path)
    return out


def file_sha256(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def _unlike(folder: Path, stage: Stage, scene: Scene, digest: str) -> str | None:
    """None when `folder` holds this stage's manifest with `digest` and all its outputs
    as they were written; else "" (no such run) or which output is missing or changed."""
    try:
        old = json.loads((folder / MANIFEST).read_text())
    except (OSError, json.JSONDecodeError):
        return ""
    if not isinstance(old, dict) or old.get("hash") != digest:
        return ""
    files = old.get("files")
    if not isinstance(files, dict):
        return ""
    for name in [*stage.outputs(scene), *files]:
        if not (folder / name).exists():
            return f"{name} is missing"
    for name, sha in files.items():
        try:
            if file_sha256(folder / name) != sha:
                return f"{name} changed since it was written"
        except OSError:
            return f"{name} cannot be read"
    return None


def _holds(folder: Path, stage: Stage, scene: Scene, digest: str) -> bool:
    """True when `folder` has this stage's manifest with `digest` and all its outputs,
    unchanged."""
    return _unlike(folder, stage, scene, digest) is None


def _swap_in(folder: Path, fill: Callable[[Path], object], kind: str) -> None:
    """Build a stage folder whole beside `folder` under a name of this process (`fill`
    writes it; concurrent runs never share it), then swap it in: the old folder moves
    aside whole and is removed. A run that swapped in the same stage meanwhile wins: its
    folder has the same inputs. `kind` names the temporary folder (".<stage>.<kind>.")."""
    from fruitcli.fsutil import owned_prefix, sweep_orphans

    folder.parent.mkdir(parents=True, exist_ok=True)
    sweep_orphans(folder.parent, f".{folder.name}.{kind}.")
    holder = Path(
        tempfile.mkdtemp(prefix=owned_prefix(f".{folder.name}.{kind}."), dir=folder.parent)
    )
    try:
        fill(holder / folder.name)
        for attempt in range(10):
            try:  # the old folder moved aside whole, then the new one moved in whole
                folder.rename(holder / f"old{attempt}")
            except FileNotFoundError:
                pass
            try:
                (holder / folder.name).rename(folder)
                return
            except OSError:  # another run's folder moved in meanwhile: the same inputs
                if (folder / MANIFEST).exists():
                    return
        raise FruitError(f"{folder}: another run keeps replacing it; run again")
    finally:
        shutil.rmtree(holder, ignore_errors=True)


def _copy_in(source: Path, folder: Path) -> None:
    """Copy the stage folder `source` whole in place of `folder` (`_swap_in`)."""
    _swap_in(folder, lambda target: shutil.copytree(source, target), "copying")


def _run_in(stage: Stage, scene: Scene, ctx: Context, folder: Path, digest: str, reason: str):
    """Run `stage` into a fresh folder swapped in place of `folder` (`_swap_in`); its
    manifest is written last, with the outputs' hashes."""
    from fruitcli.fsutil import write_json

    def fill(target: Path) -> None:
        t0 = time.perf_counter()
        target.mkdir()
        summary = _moved(stage.run(scene, ctx, target) or {}, str(target), str(folder))
        write_json(
            target / MANIFEST,
            {
                "stage": stage.name,
                "hash": digest,
                "reason": reason,
                "seconds": round(time.perf_counter() - t0, 3),
                "outputs": list(stage.outputs(scene)),
                "files": output_hashes(target),
                "summary": summary,
            },
        )

    _swap_in(folder, fill, "partial")


def _moved(obj: object, built: str, final: str):
    """`obj` (a stage's summary) with the paths into the folder it was built in pointing
    into its final folder."""
    if isinstance(obj, dict):
        return {k: _moved(v, built, final) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_moved(v, built, final) for v in obj]
    if isinstance(obj, (str, Path)) and str(obj).startswith(built):
        return type(obj)(final + str(obj)[len(built) :])
    return obj


def _no_link_out(folder: Path, root: Path) -> None:
    """Refuse a stage folder that is a symbolic link leading out of the output folder:
    the planner never writes through it."""
    if folder.is_symlink() and not folder.resolve().is_relative_to(root.resolve()):
        raise FruitError(
            f"{folder}: a symbolic link to {folder.resolve()}, outside {root}; fruit writes "
            "only inside its output folder: remove the link or choose another --out"
        )


def _changed(reason: str, why: str | None) -> str:
    """A stage's reason to run, with the output found changed when that is why."""
    return f"{reason}; rerun: {why}" if why else reason


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
        why = _unlike(ctx.dir(stage.name), stage, scene, digest) if digest else ""
        if why is None:
            steps.append(Step(stage.name, "reuse", reason, digest))
        elif digest and (source := _borrow(stage, scene, ctx, digest)) is not None:
            ctx.lent[stage.name] = source
            steps.append(
                Step(stage.name, "reuse", f"{reason} (same inputs as {source.parent.name})", digest)
            )
        else:
            steps.append(Step(stage.name, "run", _changed(reason, why), digest))
    return steps


def _borrow(
    stage: Stage, scene: Scene, ctx: Context, digest: str, say: Callable[[str], None] | None = None
) -> Path | None:
    """A sibling scene's folder (under ctx.shared) holding this stage with the same hash
    and its outputs unchanged; `say` hears of a sibling whose outputs changed."""
    if ctx.shared is None:
        return None
    for manifest in sorted(ctx.shared.glob(f"*/{stage.name}/{MANIFEST}")):
        folder = manifest.parent
        if folder == ctx.dir(stage.name):
            continue
        why = _unlike(folder, stage, scene, digest)
        if why is None:
            return folder
        if why and say:
            say(f"{stage.name}: {folder}{os.sep}{why}: not copied from there")
    return None


def run(
    scene: Scene,
    out_root: Path,
    until: str | None = None,
    progress: Callable[[str], None] | None = None,
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
            # the plan printed at the end says so; while running, only under -v
            logging.getLogger(__name__).info(f"{stage.name}: not needed ({reason})")
            continue
        digest = fingerprint(stage, scene, ctx)
        ctx.hashes[stage.name] = digest
        folder = ctx.dir(stage.name)
        why = "" if force else _unlike(folder, stage, scene, digest)
        if why is None:
            done.append(Step(stage.name, "reuse", reason, digest))
            ctx.progress(f"{stage.name}: reuse (inputs unchanged)")
            continue
        if why:
            ctx.progress(f"{stage.name}: {folder}{os.sep}{why}: run again")
        _no_link_out(folder, ctx.out_root)
        source = None if force else _borrow(stage, scene, ctx, digest, ctx.progress)
        if source is not None:  # copied whole beside it, then swapped in: never half
            _copy_in(source, folder)
            done.append(
                Step(stage.name, "reuse", f"{reason} (same inputs as {source.parent.name})", digest)
            )
            ctx.progress(f"{stage.name}: reuse (same inputs as {source.parent.name})")
            continue
        ctx.progress(f"{stage.name}: run ({reason})")
        # built whole beside its folder, the manifest last, then swapped in
        _run_in(stage, scene, ctx, folder, digest, reason)
        done.append(Step(stage.name, "run", _changed(reason, why), digest))
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
