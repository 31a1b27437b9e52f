"""Atomic file output: write to a temporary file in the same folder, then rename.

A crash or a bad input never leaves a half-written file behind, and a file that
existed before is replaced only once its successor is complete.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to `path`; rename it onto `path` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sweep_orphans(path.parent, f".{path.name}.")  # left by a writer killed with SIGKILL
    fd, tmp = tempfile.mkstemp(
        prefix=owned_prefix(f".{path.name}."), suffix=path.suffix, dir=path.parent
    )
    os.close(fd)
    try:
        yield Path(tmp)
        if Path(tmp).exists():  # mkstemp made it private; give it the usual permissions
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    """The process's file-creation mask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write `text` to `path` atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)


def write_json(path: str | os.PathLike, obj: object) -> None:
    """Write `obj` as indented JSON atomically."""
    write_text(path, json.dumps(obj, indent=2, sort_keys=False, default=_json_default) + "\n")


def _json_default(obj: object):
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


def write_csv(
    path: str | os.PathLike,
    header: list[str],
    rows: Iterable[Sequence[object]],
    comments: Sequence[str] = (),
) -> None:
    """Write a CSV atomically; `comments` become leading `# ` lines (units, provenance)."""
    buf = io.StringIO()
    for line in comments:
        buf.write(f"# {line}\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([_fmt(v) for v in row])
    write_text(path, buf.getvalue())


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6f}"
    return str(value)


def owned_prefix(prefix: str) -> str:
    """A temporary name prefix carrying this process's id: `prefix` + "<pid>-"."""
    return f"{prefix}{os.getpid()}-"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):
        return False
    except PermissionError:  # another user's process
        return True
    return True


def sweep_orphans(folder: Path, prefix: str) -> list[Path]:
    """Remove the temporary files and folders `prefix` + "<pid>-..." in `folder` whose
    process has ended (a run killed with SIGKILL leaves them); a live run's are left
    alone. Returns the entries removed."""
    removed: list[Path] = []
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return removed
    for entry in entries:
        if not entry.name.startswith(prefix):
            continue
        pid, dash, _ = entry.name[len(prefix) :].partition("-")  # "<pid>-<random>"
        if (
            dash
            and pid.isdigit()
            and int(pid) != os.getpid()
            and not _alive(int(pid))
            and not entry.is_symlink()
        ):
            if entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                with contextlib.suppress(FileNotFoundError):
                    entry.unlink()
            removed.append(entry)
    return removed


@contextlib.contextmanager
def staged_dir(final: str | os.PathLike) -> Iterator[Path]:
    """Yield a fresh temporary folder; on success move its files into `final`.

    Outputs of one step appear together or not at all; files already in `final`
    that the step does not produce are kept.
    """
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    sweep_orphans(final.parent, f".{final.name}.")
    tmp = Path(tempfile.mkdtemp(prefix=owned_prefix(f".{final.name}."), dir=final.parent))
    try:
        yield tmp
        final.mkdir(parents=True, exist_ok=True)
        for item in sorted(tmp.rglob("*")):
            rel = item.relative_to(tmp)
            target = final / rel
            if item.is_dir():
                target.mkdir(parents=True, exist_ok=True)
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(item, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def slug(label: str) -> str:
    """A file-system friendly version of a row label ('Rest, small' -> 'rest-small')."""
    return re.sub(r"[^a-z0-9]+", "-", label.lower()).strip("-") or "row"


def file_hash_many(paths: Iterable[str | Path]) -> str:
    """sha256 (hex) of the files' bytes one after the other, in the order given."""
    import hashlib

    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()
