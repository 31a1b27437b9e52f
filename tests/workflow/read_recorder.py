"""A recorder of the scene keys each stage reads: every attribute read of a typed scene
table (`fruitcli.scene.Record`), every `scene.has(section)` and every stage folder a
stage opens (`Context.dir`), attributed to the stage and phase (needed, inputs, run,
outputs) running at the time, however deep in the library the read happens."""

from __future__ import annotations

from collections import defaultdict
from contextlib import contextmanager
from dataclasses import fields, replace

from fruitcli import scene as scene_mod
from fruitcli.workflow.stage_types import Context

PHASES = ("needed", "inputs", "run", "outputs")


def _entries() -> dict[type, tuple[str, bool]]:
    """Record type -> (declaration entry, whether reads are per key)."""
    out = {cls: (name, True) for name, cls in scene_mod.SECTION_TYPES.items()}
    out.update({cls: (name, False) for name, cls in scene_mod.ITEM_TYPES.items()})
    out.update({cls: ("geometry.chamber", False) for cls in scene_mod.SUBTABLE_TYPES.values()})
    return out


class Reads:
    """`seen[stage][phase]`: entries read ("section.key", an array section, or
    "has:section"); `dirs[stage]`: other stages' folders it opened."""

    def __init__(self):
        self.records: set[int] = set()  # ids of the watched scenes' records
        self.scenes: set[int] = set()  # ids of their section dicts (kept by copies)
        self.stage: str | None = None
        self.phase: str | None = None
        self.seen = defaultdict(lambda: defaultdict(set))
        self.dirs = defaultdict(set)

    def watch(self, scene) -> None:
        """Record reads of this scene (and of copies sharing its sections) only: other
        scenes (the schema's defaults, read by library modules) are not the stage's."""
        self.scenes.add(id(scene.sections))
        for value in scene.sections.values():
            for record in value if isinstance(value, tuple) else (value,):
                self.records.add(id(record))
                for item in getattr(record, "chamber", ()):
                    self.records.update({id(item), id(item.ellipsoid)})

    def add(self, entry: str) -> None:
        if self.stage is not None:
            self.seen[self.stage][self.phase].add(entry)

    @contextmanager
    def at(self, stage: str, phase: str):
        outer = self.stage, self.phase
        self.stage, self.phase = stage, phase
        try:
            yield
        finally:
            self.stage, self.phase = outer

    def wrap(self, stages):
        """Copies of `stages` whose callables record under their stage and phase."""

        def phase(stage, name):
            fn = getattr(stage, name)

            def call(*args, **kwargs):
                with self.at(stage.name, name):
                    return fn(*args, **kwargs)

            return call

        return [replace(s, **{p: phase(s, p) for p in PHASES}) for s in stages]


@contextmanager
def recording(monkeypatch):
    """Patch the scene's records, `Scene.has` and `Context.dir` to record into a `Reads`."""
    reads = Reads()
    entries = _entries()
    names = {cls: {f.name for f in fields(cls)} for cls in entries}
    get = object.__getattribute__

    def getattribute(record, name):
        value = get(record, name)
        cls = type(record)
        if cls in entries and name in names[cls] and id(record) in reads.records:
            entry, per_key = entries[cls]
            reads.add(f"{entry}.{name}" if per_key else entry)
        return value

    has, folder = scene_mod.Scene.has, Context.dir
    section_of = scene_mod.Scene.__getattr__

    def section_recorded(scene, name):  # an array of tables is read as a whole
        if name in scene_mod.ARRAY_SECTIONS and watched(scene):
            reads.add(name)
        return section_of(scene, name)

    def watched(scene):
        return id(scene.__dict__.get("sections")) in reads.scenes

    def has_recorded(scene, section):
        if watched(scene):
            reads.add(f"has:{section}")
        return has(scene, section)

    def dir_recorded(ctx, stage):
        if reads.stage is not None and stage != reads.stage:
            reads.dirs[reads.stage].add(stage)
        return folder(ctx, stage)

    monkeypatch.setattr(scene_mod.Record, "__getattribute__", getattribute)
    monkeypatch.setattr(scene_mod.Scene, "has", has_recorded)
    monkeypatch.setattr(scene_mod.Scene, "__getattr__", section_recorded)
    monkeypatch.setattr(Context, "dir", dir_recorded)
    yield reads
