"""Stage hashes from the stages' declared reads (`Stage.reads`, `workflow.scene_hash`):

- the declarations are complete: every scene key a stage reads while deciding, hashing,
  running or listing its outputs on small real scenes (the recorder sees reads deep in
  the library) is declared, and every stage folder it opens is one of its `deps`;
- the schema walk: a changed valid value of any key changes the hash of exactly the
  stages whose declaration covers it, and of their dependents; a file a path key names
  counts by its content (edited in place: a new hash; the same bytes elsewhere: the same);
- an unchanged scene reuses every stage on the next run.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fruitcli.scene import (
    ARRAY_SCHEMA,
    ARRAY_SECTIONS,
    SCHEMA,
    _check_value,
    load_scene,
    parse_scene,
)
from fruitcli.workflow import planner
from fruitcli.workflow.scene_hash import covers, split
from fruitcli.workflow.stage_types import Context
from fruitcli.workflow.stages import STAGES
from tests.conftest import ROOT
from tests.workflow.read_recorder import recording

BY_NAME = {s.name: s for s in STAGES}


def test_declarations_name_schema_keys_and_earlier_stages():
    for n, stage in enumerate(STAGES):
        for entry in (*stage.reads, *stage.minus, *stage.decides, *stage.derived):
            split(entry)  # ValueError for a key the schema lacks
        for entry in stage.minus:
            assert covers(stage.reads, entry.split(".")[0]), (stage.name, entry)
        assert set(stage.deps) <= {s.name for s in STAGES[:n]}, stage.name


# ------------------------------------------------------------------ declarations complete
def _covered(entry: str, stage, phase: str) -> bool:
    """Whether the declaration of `stage` allows reading `entry` in `phase`."""
    allowed = {*stage.reads, *stage.derived} | (set(stage.decides) if phase == "needed" else set())
    if entry.startswith("has:"):
        return covers(allowed, entry[4:])
    if entry in stage.minus:  # left out of its section: only when named itself
        return entry in allowed
    section, _, key = entry.partition(".")
    return covers(allowed, section, key)


def pad_scene(d: Path) -> Path:
    """The bundled touchpad at a coarse mesh (reads, not accuracy)."""
    text = (ROOT / "pipelines" / "touchpad-4x4.toml").read_text()
    for old, new in (
        ("size_mm = 2.5", "size_mm = 6.0"),
        ("jig_steps = 12", "jig_steps = 6"),
        ("noise_frames = 300", "noise_frames = 20"),
    ):
        assert old in text
        text = text.replace(old, new)
    (d / "pad.toml").write_text(text)
    return d / "pad.toml"


REDUCED = """
[scene]
name = "reduced-pad"
[geometry]
pad_size_mm = [80.0, 60.0, 10.0]
[[geometry.chamber]]
name = "left"
ellipsoid = {center_mm = [-18.0, 0.0, 4.0], radii_mm = [14.0, 14.0, 2.5]}
[[geometry.chamber]]
name = "right"
ellipsoid = {center_mm = [18.0, 0.0, 4.0], radii_mm = [14.0, 14.0, 2.5]}
[grid]
count = [4, 3]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[fem]
element = "p1"
[material]
model = "corotational"
[mesh]
size_mm = 8.0
[[fixed]]
box_mm = [-50, -50, -0.01, 50, 50, 0.01]
[gravity]
vector_m_s2 = [0.0, 0.0, -9.81]
[actuation]
pressure_kpa = {left = [0.0, 3.0], right = [0.0, 0.0]}
[reduced]
points_per_axis = 2
max_degree = 1
validation = 2
[frames]
recording = "rec.npz"
[sensitivity]
noise_frames = 20
animation_frames = 2
"""


def reduced_scene(d: Path) -> Path:
    """Two chambers, gravity, a reduced model and a recording with pressures (located on
    the reduced model)."""
    from fruitcli.sensing.frames.recording import Recording, write_npz

    rng = np.random.default_rng(5)
    frames = np.full((30, 21, 12), 100, dtype=np.int64)
    frames[15:, 2, 2] += 80
    kpa = rng.uniform(0.0, 3.0, (30, 2))
    write_npz(d / "rec.npz", Recording(frames, np.arange(30) / 30.0, kpa, ("left", "right")))
    (d / "reduced.toml").write_text(REDUCED)
    return d / "reduced.toml"


ARTIST = """
[scene]
name = "tiny-artist"
[geometry]
artist = "fruit_artist.ply"
generate_artist = true
[tracks]
faces = 1500
[bench]
indenters = ["medium"]
samples = "samples.csv"
step_mm = 0.5
[detection]
project = "surface"
[skin]
model = "electrostatic"
gaps_mm = [0.0, 1.0, 2.0]
[sensitivity]
noise_frames = 20
animation_frames = 2
"""


def artist_scene(d: Path) -> Path:
    """The default Fruit generated, reduced to 1500 faces, an electrostatic skin, a
    two-sample bench located on the surface, evaluated, and its sensitivity."""
    (d / "samples.csv").write_text("sample,x_mm,y_mm\n0,4.0,3.0\n1,-12.0,9.0\n")
    (d / "artist.toml").write_text(ARTIST)
    return d / "artist.toml"


def ball_scene(d: Path) -> Path:
    """A hollow ball (E = 100 kPa, nu = 0.45, mesh 8 mm) at 20 kPa, past half its shear
    modulus: the limits stage follows its chamber to the limit before simulate."""
    import trimesh

    from tests.fem.meshing.test_mesh import BALL

    trimesh.creation.icosphere(3, 20.0).export(d / "ball.stl")
    text = BALL.format(size=8.0, half=4.0, element="p2", model="neo-hookean", nu=0.45, p=20.0)
    (d / "ball.toml").write_text('[scene]\nname = "ball"\n' + text)
    return d / "ball.toml"


SCENES = {
    "paper-table": lambda d: ROOT / "pipelines" / "paper-table.toml",
    "touchpad": pad_scene,
    "reduced-pad": reduced_scene,
    "artist": artist_scene,
    "ball": ball_scene,
}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Each small scene run twice by the planner with every read recorded: -> {scene:
    (Reads, first run's steps, second run's steps)}."""
    mp = pytest.MonkeyPatch()
    out = {}
    try:
        with recording(mp) as reads:
            for name, make in SCENES.items():
                d = tmp_path_factory.mktemp(name)
                scene = load_scene(make(d))
                reads.watch(scene)
                stages = reads.wrap(STAGES)
                first = planner.run(scene, d / "out", stages=stages)
                second = planner.run(scene, d / "out", stages=stages)
                out[name] = first, second
    finally:
        mp.undo()
    return reads, out


@pytest.mark.slow
def test_small_scenes_run_every_stage_and_reuse_all_of_it(recorded):
    _, runs = recorded
    ran = {s.stage for first, _ in runs.values() for s in first if s.action == "run"}
    assert ran == set(BY_NAME)  # every stage ran on one of the scenes
    for name, (first, second) in runs.items():
        assert [s.stage for s in second if s.action == "run"] == [], name
        assert [s.action == "reuse" for s in second] == [s.action == "run" for s in first]


@pytest.mark.slow
def test_every_key_a_stage_reads_is_declared(recorded):
    reads, _ = recorded
    missing = {
        (stage, phase, entry)
        for stage, phases in reads.seen.items()
        for phase, entries in phases.items()
        for entry in entries
        if not _covered(entry, BY_NAME[stage], phase)
    }
    assert sorted(missing) == []
    for stage, folders in reads.dirs.items():  # upstream outputs: covered by deps' hashes
        assert folders <= set(BY_NAME[stage].deps), (stage, folders)
    # the recorder sees reads inside the library: simulate reads [fem].element in
    # fruitcli.fem, sensitivity [detection].threshold_counts in fruitcli.sensing
    assert "fem.element" in reads.seen["simulate"]["run"]
    assert "detection.threshold_counts" in reads.seen["sensitivity"]["run"]
    assert "skin.taxel_gain" in reads.seen["locate"]["run"]


def test_the_recorder_fails_an_undeclared_read():
    """A stage declaring less than it reads is caught."""
    sim = BY_NAME["simulate"]
    narrow = replace(sim, reads=tuple(r for r in sim.reads if r != "fem"))
    assert _covered("fem.element", sim, "run") and not _covered("fem.element", narrow, "run")
    assert not _covered("tracks.file", BY_NAME["make-tracks"], "run")  # left out by minus
    assert _covered("reduced.margin", BY_NAME["reduce"], "run")  # derived
    assert not _covered("has:gravity", BY_NAME["pad-grid"], "needed")
    assert _covered("has:gravity", BY_NAME["tetra"], "needed")  # decides only
    assert not _covered("gravity.vector_m_s2", BY_NAME["tetra"], "run")


# ------------------------------------------------------------------ the schema walk
WALK = """
[scene]
name = "walk"
[geometry]
pad_size_mm = [80.0, 60.0, 10.0]
[[geometry.chamber]]
name = "c1"
ellipsoid = {center_mm = [0.0, 0.0, 4.0], radii_mm = [10.0, 10.0, 2.0]}
[actuation]
pressure_kpa = {c1 = [0.0, 2.0]}
[reduced]
pressure_range_kpa = [0.0, 4.0]
[[fixed]]
box_mm = [-50, -50, -1, 50, 50, 0]
[[jig]]
region_box_mm = [30, -50, -1, 50, 50, 11]
[[evaluate]]
label = "row"
truth = "files/a.csv"
measured = "files/a.csv"
"""

LISTS = {  # a changed valid value of each list key
    "grid.count": [5, 4],
    "bench.indenters": ["small"],
    "skin.gaps_mm": [0.0, 0.5, 1.0],
    "report.paper_rows": ["Rest, small"],
}
TABLES = {
    "actuation.pressure_kpa": {"c1": [0.0, 3.0]},
    "actuation.volume_growth_mm3": {"c1": [0.0, 5.0]},
    "skin.footprint_sigma_mm": {"small": 5.0},
    "geometry.chamber.ellipsoid": {"center_mm": [1.0, 0.0, 4.0], "radii_mm": [10.0, 10.0, 2.0]},
}


def _changed(spec, value, dotted: str, other_file: Path):
    """A valid value of `spec` other than `value`."""
    if dotted in LISTS:
        return LISTS[dotted]
    if dotted in TABLES:
        return TABLES[dotted]
    k = spec.kind
    if k == "path":
        return other_file
    if k == "bool":
        return not value
    if k == "str":
        if spec.choices is not None:
            return next(c for c in spec.choices if c != value)
        return (value or "walk") + "x"
    if k in ("num", "int", "range"):
        base = 1.0 if value is None or isinstance(value, list) else value
        for c in (base + 1, base * 2 + 1, base / 2, base + 0.1, base - 0.1, 0.3, 2):
            c = int(round(c)) if k == "int" else float(c)
            if c != value and spec.in_range(c) and (spec.valid is None or spec.valid(c)):
                return c
    if k in ("vec2", "vec3", "box"):
        n = {"vec2": 2, "vec3": 3, "box": 6}[k]
        base = list(value) if value is not None else [float(i) for i in range(n)]
        if k == "box":
            base = [base[0], base[1], base[2], *(v + 1 for v in base[3:])] if value else base
            return [*base[:3], *(max(v, b + 1) for v, b in zip(base[3:], base[:3], strict=True))]
        base[-1] += 1.5
        return base
    raise AssertionError(f"no changed value for {dotted} ({k})")


def _walk_scene(tmp_path) -> object:
    files = tmp_path / "files"
    files.mkdir()
    for name, text in (("a.csv", "a\n"), ("b.csv", "b\n"), ("a-copy.csv", "a\n")):
        (files / name).write_text(text)
    (tmp_path / "samples.csv").write_text("sample,x_mm,y_mm\n0,1,2\n")
    scene = parse_scene(WALK, tmp_path / "walk.toml")
    scene = replace(scene, declared=frozenset(s for s in SCHEMA if s not in ("report",)))
    # every path key of a table section names a file ("a"), for the walk to change
    for section, spec in SCHEMA.items():
        for key, kspec in spec.items():
            if kspec.kind == "path":
                scene = _set(scene, section, key, files / "a.csv")
    return scene


def _set(scene, section, key, value):
    sections = dict(scene.sections)
    sections[section] = replace(sections[section], **{key: value})
    return replace(scene, sections=sections)


def _set_item(scene, array, key, value):
    """The first item of an array of tables ([[fixed]], [[geometry.chamber]]) changed."""
    sections = dict(scene.sections)
    if array == "geometry.chamber":
        geo = sections["geometry"]
        items = geo.chamber
        if key == "ellipsoid":
            value = type(items[0].ellipsoid)(**value)
        sections["geometry"] = replace(geo, chamber=(replace(items[0], **{key: value}),))
    else:
        items = sections[array]
        sections[array] = (replace(items[0], **{key: value}), *items[1:])
    return replace(scene, sections=sections)


def _hashes(scene, out: Path) -> dict[str, str]:
    ctx = Context(out)
    for stage in STAGES:
        ctx.hashes[stage.name] = planner.fingerprint(stage, scene, ctx)
    return dict(ctx.hashes)


def _walk_cases(scene, other_file):
    """(label, changed scene, stages declaring the key, stages deriving from it)."""
    for section, spec in SCHEMA.items():
        if section in ARRAY_SECTIONS:
            continue
        record = scene.sections[section]
        for key, kspec in spec.items():
            if key == "chamber":
                continue
            value = getattr(record, key)
            new = _changed(kspec, value, f"{section}.{key}", other_file)
            _check_value(f"[{section}]", key, kspec, new)  # a valid value
            direct = {
                s.name
                for s in STAGES
                if covers(s.reads, section, key) and f"{section}.{key}" not in s.minus
            }
            derived = {s.name for s in STAGES if covers(s.derived, section, key)}
            yield f"{section}.{key}", _set(scene, section, key, new), direct, derived
    for array, spec in ARRAY_SCHEMA.items():
        # an array is declared whole: [[fixed]], or [geometry].chamber
        where = ("geometry", "chamber") if array == "geometry.chamber" else (array,)
        first = scene.chambers[0] if array == "geometry.chamber" else scene.sections[array][0]
        for key, kspec in spec.items():
            new = _changed(kspec, getattr(first, key), f"{array}.{key}", other_file)
            if key != "ellipsoid":
                _check_value(f"[[{array}]]", key, kspec, new)
            direct = {s.name for s in STAGES if covers(s.reads, *where)}
            derived = {s.name for s in STAGES if covers(s.derived, *where)}
            yield f"{array}.{key}", _set_item(scene, array, key, new), direct, derived


def _propagate(direct: set[str], derived: set[str], got: set[str]) -> set[str]:
    """Declaring stages plus their dependents; a stage deriving from the key: as seen."""
    changed = set()
    for stage in STAGES:
        if (
            stage.name in direct
            or changed & set(stage.deps)
            or (stage.name in derived and stage.name in got)
        ):
            changed.add(stage.name)
    return changed


def test_schema_walk_changes_exactly_the_declaring_stages(tmp_path):
    scene = _walk_scene(tmp_path)
    base = _hashes(scene, tmp_path / "out")
    cases = list(_walk_cases(scene, tmp_path / "files" / "b.csv"))
    n_keys = sum(len(s) for s in SCHEMA.values()) + sum(len(s) for s in ARRAY_SCHEMA.values())
    assert len(cases) == n_keys - 1  # every key but [geometry].chamber (its items are)
    wrong = []
    for label, changed, direct, derived in cases:
        now = _hashes(changed, tmp_path / "out")
        got = {k for k in base if now[k] != base[k]}
        if got != _propagate(direct, derived, got):
            wrong.append((label, sorted(got), sorted(_propagate(direct, derived, got))))
    assert wrong == []
    # declaring a section (with its defaults) counts for the stages reading it
    for section in ("gravity", "reduced", "sensitivity"):
        undeclared = replace(scene, declared=scene.declared - {section})
        got = {k for k, v in _hashes(undeclared, tmp_path / "out").items() if v != base[k]}
        direct = {s.name for s in STAGES if covers(s.reads, section)}
        assert got == _propagate(direct, set(), got), section


@pytest.mark.parametrize(
    "section, key, value, stage",
    [
        ("fem", "element", "p1", "simulate"),  # states.npz said p2 after a change to p1
        ("detection", "threshold_counts", 30.0, "sensitivity"),  # sensitivity.json said 20
    ],
)
def test_the_stale_cases_of_the_issue_change_their_stage(tmp_path, section, key, value, stage):
    scene = _walk_scene(tmp_path)
    before = _hashes(scene, tmp_path / "out")[stage]
    assert _hashes(_set(scene, section, key, value), tmp_path / "out")[stage] != before


def test_path_keys_count_by_content_not_path(tmp_path):
    """The same bytes under another name: no stage changes (make-artist's path is where
    it writes: its hash is the same wherever the mesh goes); a file edited in place: a
    new hash."""
    scene = _walk_scene(tmp_path)
    base = _hashes(scene, tmp_path / "out")
    copy = tmp_path / "files" / "a-copy.csv"
    for section, spec in SCHEMA.items():
        for key, kspec in spec.items():
            if kspec.kind != "path":
                continue
            now = _hashes(_set(scene, section, key, copy), tmp_path / "out")
            got = {k for k in base if now[k] != base[k]}
            assert got == set(), (section, key)
    (tmp_path / "files" / "a.csv").write_text("a, edited\n")  # every path key names it
    now = _hashes(scene, tmp_path / "out")
    reading = {
        s.name
        for s in STAGES
        for section, spec in SCHEMA.items()
        for key, kspec in spec.items()
        if kspec.kind == "path"
        and covers(s.reads, section, key)
        and f"{section}.{key}" not in s.minus
    } | {s.name for s in STAGES if covers(s.reads, "evaluate")}  # its truth and measured
    assert {"make-tracks", "tetra", "simulate", "bench", "locate", "evaluate"} <= reading
    got = {k for k in base if now[k] != base[k]}
    assert got == _propagate(reading, set(), got) and "make-artist" not in got


def test_gains_csv_edited_in_place_reruns_locate(tmp_path):
    """The issue's case: a recording located with measured taxel gains ([skin].taxel_gain,
    divided out); the gains CSV edited in place (same path) reruns the locate stage, whose
    touches then differ."""
    from fruitcli.sensing.frames.recording import Recording, write_npz
    from tests.sensing.skin.test_virtual_bench import pad_taxel_csv

    pad_taxel_csv(tmp_path / "taxels.csv")
    frames = np.full((40, 21, 12), 100, dtype=np.int64)
    frames[20:, 1, 1] += 30  # one touch on taxel (1, 1): above 20 counts at gain 1
    write_npz(tmp_path / "rec.npz", Recording(frames, np.arange(40) / 30.0))
    gains = tmp_path / "gains.csv"
    gains.write_text("id,gain\n" + "".join(f"{k},1.0\n" for k in range(16)))
    (tmp_path / "s.toml").write_text(
        '[grid]\ntaxels = "taxels.csv"\n[frames]\nrecording = "rec.npz"\n'
        '[skin]\ntaxel_gain = "gains.csv"\n[detection]\ndivide_by_gain = true\n'
    )
    scene = load_scene(tmp_path / "s.toml")
    out = tmp_path / "out"
    first = {s.stage: s.action for s in planner.run(scene, out)}
    assert first["locate"] == "run"
    touches = (out / "locate" / "recording" / "touches.csv").read_text()
    assert {s.stage: s.action for s in planner.plan(scene, out)}["locate"] == "reuse"
    gains.write_text("id,gain\n" + "".join(f"{k},3.0\n" for k in range(16)))  # in place
    assert {s.stage: s.action for s in planner.plan(scene, out)}["locate"] == "run"
    planner.run(scene, out)
    assert (out / "locate" / "recording" / "touches.csv").read_text() != touches
