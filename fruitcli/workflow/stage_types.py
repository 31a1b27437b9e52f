"""The types the planner and the stage table share: a stage, a planned step, and the
context stages run in. The planner and the stage modules import this module; it imports
none of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Stage:
    """One pipeline stage. `needed(scene)` -> (bool, reason); `inputs(scene, ctx)` -> what
    is hashed besides the scene keys it reads (values that are not scene keys);
    `run(scene, ctx, out_dir)` -> summary dict; `outputs(scene)` -> file names.

    The scene keys a stage reads are declared, and its hash covers them (see
    `workflow.scene_hash`): `reads` names whole sections ("material") or keys
    ("geometry.unit"), each with the content of every file a path key names and whether
    the file declares the section; `minus` leaves keys of a read section out (not read);
    `decides` names keys only `needed` reads (they decide whether the stage runs, not what
    it writes: not hashed); `derived` names keys read only through a value `inputs`
    derives from them (hashed as that value). Upstream outputs are covered by the hashes
    of `deps`, which must name every stage whose folder the stage reads."""

    name: str
    deps: list[str]
    module: str
    needed: Callable
    inputs: Callable
    run: Callable
    outputs: Callable
    reads: tuple[str, ...] = ()
    minus: tuple[str, ...] = ()
    decides: tuple[str, ...] = ()
    derived: tuple[str, ...] = ()


@dataclass
class Step:
    """A planned stage: action is 'run', 'reuse' or 'not needed'."""

    stage: str
    action: str
    reason: str
    hash: str = ""


@dataclass
class Context:
    """What stages share while running: the output root and a progress callback."""

    out_root: Path
    progress: Callable[[str], None] = lambda msg: None
    hashes: dict[str, str] = field(default_factory=dict)
    shared: Path | None = None  # a folder whose scenes may lend identical stage outputs
    lent: dict[str, Path] = field(default_factory=dict)  # plan only: stage -> its lender

    def dir(self, stage: str) -> Path:
        """The stage's folder (for a plan, the sibling's it would be copied from)."""
        return self.lent.get(stage, self.out_root / stage)
