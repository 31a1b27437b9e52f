"""The checks across keys of a scene (one key's type, choices and range are the schema's):
one label and folder per evaluation row, one body source, chambers named once and shaped
once, a material its element can run, actuation tables of matching chambers and lengths,
and the keys that need one another ([skin] gains, [bench] indenters, [printer] origin).
Each check raises `SceneError` with one line naming the file and the keys."""

from __future__ import annotations

from pathlib import Path

from fruitcli.errors import SceneError
from fruitcli.fem.materials.build import from_scene
from fruitcli.fem.materials.models import MATERIAL_MODELS
from fruitcli.fsutil import slug
from fruitcli.scene.key import closest, number
from fruitcli.scene.limits import MAX_STATES
from fruitcli.scene.records import Sections


def _one_folder_per_row(scene: Sections, where: str) -> None:
    """Each bench indenter once, and each evaluation row (an [[evaluate]] label, or
    "<configuration>, <indenter>" of the bench) with a folder name of its own."""
    rows = [(ev.label, "[[evaluate]].label") for ev in scene.evaluate]
    if scene.has("bench"):
        names = list(scene.bench.indenters)
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:
            raise SceneError(
                f"{where}: [bench].indenters: {twice[0]!r} is given twice; expected each "
                "indenter once (it names its folders)"
            )
        config = scene.scene.configuration
        rows += [
            (f"{config}, {name}", "[scene].configuration with [bench].indenters") for name in names
        ]
    seen: dict[str, tuple[str, str]] = {}
    for label, key in rows:
        first = seen.setdefault(slug(label), (label, key))
        if first != (label, key):
            raise SceneError(
                f"{where}: {key} {label!r} and {first[1]} {first[0]!r} both name the folder "
                f"evaluate/{slug(label)}; expected row labels that differ in more than case "
                "and punctuation"
            )


def cross_checks(scene: Sections, where: str, must_exist: bool) -> None:
    """Every check across keys, in this order (the first failing one is reported)."""
    _labels_once(scene, where)
    _one_folder_per_row(scene, where)
    _one_body(scene, where, must_exist)
    names = _chamber_names(scene, where)
    _material_on_element(scene, where)
    _actuation(scene, where, names)
    _needs(scene, where)


def _labels_once(scene: Sections, where: str) -> None:
    """Each [[evaluate]] label once."""
    labels = [ev.label for ev in scene.evaluate]
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise SceneError(
            f"{where}: [[evaluate]].label: {twice[0]!r} is given twice; expected "
            "one label per row (it names the row's folder and table line)"
        )


def _one_body(scene: Sections, where: str, must_exist: bool) -> None:
    """At most one of [geometry].artist, solid, pad_size_mm; an artist mesh on disk
    unless the make-artist stage writes it."""
    geo = scene.geometry
    given = {"artist": geo.artist, "solid": geo.solid, "pad_size_mm": geo.pad_size_mm}
    sources = [k for k, v in given.items() if v is not None]
    if len(sources) > 1:
        raise SceneError(
            f"{where}: [geometry] give one of artist, solid, pad_size_mm, not {sources}"
        )
    if geo.artist is not None and geo.generate_artist:
        pass  # the make-artist stage writes it
    elif geo.artist is not None and must_exist and not Path(geo.artist).exists():
        raise SceneError(f"{where}: [geometry].artist: file not found: {geo.artist}")


def _chamber_names(scene: Sections, where: str) -> list[str]:
    """The chambers' names, each once, each chamber with one of ellipsoid or surface."""
    names: list[str] = []
    for n, ch in enumerate(scene.chambers):
        if (ch.ellipsoid is None) == (ch.surface is None):
            raise SceneError(
                f"{where}: [[geometry.chamber]] #{n + 1} '{ch.name}': give exactly one of "
                "ellipsoid or surface"
            )
        if ch.name in names:
            raise SceneError(f"{where}: [[geometry.chamber]]: duplicate name '{ch.name}'")
        names.append(ch.name)
    return names


def _material_on_element(scene: Sections, where: str) -> None:
    """[material]'s constants valid for its model, and the model runs on [fem].element."""
    try:
        material = from_scene(scene.material)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    element = scene.fem.element
    if not MATERIAL_MODELS[material.model].runs_on(element):
        raise SceneError(
            f'{where}: [material].model = "corotational" is the paper\'s SOFA '
            f'model on linear tets: set [fem].element = "p1" (got '
            f'{element!r}), or use model = "neo-hookean"'
        )


def _actuation(scene: Sections, where: str, names: list[str]) -> None:
    """[actuation] tables of known chambers, as many states for each, each chamber
    controlled by pressure or by volume, not both."""
    act = scene.actuation
    lengths = set()
    for key, table in (
        ("pressure_kpa", act.pressure_kpa),
        ("volume_growth_mm3", act.volume_growth_mm3),
    ):
        for cname, values in (table or {}).items():
            lengths.add(_states(where, key, cname, values, names))
    if len(lengths) > 1:
        raise SceneError(
            f"{where}: [actuation]: every chamber needs the same number of states, "
            f"got {sorted(lengths)}"
        )
    if act.pressure_kpa and act.volume_growth_mm3:
        both = set(act.pressure_kpa) & set(act.volume_growth_mm3)
        if both:
            raise SceneError(
                f"{where}: [actuation]: chamber {sorted(both)[0]} is controlled by "
                "both pressure_kpa and volume_growth_mm3"
            )


def _states(where: str, key: str, cname: str, values: object, names: list[str]) -> int:
    """The number of states of chamber `cname`'s entry in [actuation].`key`."""
    if cname not in names:
        hint = closest(cname, names) if names else " (the scene has no chambers)"
        raise SceneError(f"{where}: [actuation].{key}.{cname}: no such chamber{hint}")
    if not isinstance(values, list) or not values or not all(number(v) for v in values):
        raise SceneError(
            f"{where}: [actuation].{key}.{cname}: expected a non-empty "
            "list of numbers, one per state"
        )
    if len(values) > MAX_STATES:
        raise SceneError(
            f"{where}: [actuation].{key}.{cname}: expected at most {MAX_STATES:,} "
            f"states, got {len(values):,}"
        )
    return len(values)


def _needs(scene: Sections, where: str) -> None:
    """Keys that need others: measured gains without drawn ones, the bench's indenters
    known, a [printer]'s model origin, divided gains that exist."""
    skin = scene.skin
    if skin.taxel_gain is not None and skin.gain_spread > 0:
        raise SceneError(
            f"{where}: [skin].gain_spread: expected 0 with taxel_gain (the gains "
            f"are measured, not drawn), got {skin.gain_spread}"
        )
    if scene.has("bench"):
        bench = scene.bench
        # the paper's indenters (fruitcli.sensing.skin.forward) and those [skin] gives a width
        known = tuple(dict.fromkeys(["small", "medium", *(skin.footprint_sigma_mm or {})]))
        if not bench.indenters or any(i not in known for i in bench.indenters):
            raise SceneError(
                f"{where}: [bench].indenters: expected a non-empty list of "
                f"{', '.join(known)}, got {bench.indenters}"
            )
    if scene.has("printer") and scene.printer.model_origin_mm is None:
        raise SceneError(
            f"{where}: [printer]: missing key 'model_origin_mm' (where the "
            "model's origin is, printer coordinates, mm)"
        )
    if scene.detection.divide_by_gain and skin.taxel_gain is None:
        raise SceneError(
            f"{where}: [detection].divide_by_gain: needs the gains, [skin]."
            'taxel_gain = "gains.csv" (written by fruit calibrate)'
        )
