"""Ranges of the scene keys that `fruitcli.scene.SCHEMA` types but does not bound: seeds,
frame counts, triangle counts and rates. One `SceneError` line names the key, the range
and the value."""

from __future__ import annotations

from fruitcli.errors import SceneError

MAX_FACES = 10_000_000
"""Most triangles a reduced surface may ask for (a 10 M triangle surface is ~1 GB)."""

# (section, key): (lowest, highest or None, what the value is)
RANGES: dict[tuple[str, str], tuple[float, float | None, str]] = {
    ("bench", "seed"): (0, 2**63 - 1, "a seed >= 0"),
    ("reduced", "seed"): (0, 2**63 - 1, "a seed >= 0"),
    ("sensitivity", "noise_frames"): (2, None, "frames >= 2 (a standard deviation needs two)"),
    ("sensitivity", "animation_frames"): (1, None, "frames >= 1"),
    ("detection", "drift_rate"): (0.0, 1.0, "a rate per frame 0 <= rate <= 1"),
    ("detection", "hysteresis_counts"): (0.0, None, "counts >= 0"),
    ("detection", "noise_floor_counts"): (0.0, None, "counts >= 0"),
    ("detection", "debounce_frames"): (0, None, "frames >= 0"),
    ("detection", "track_gate_mm"): (0.0, None, "a distance >= 0 mm"),
    ("tracks", "faces"): (4, MAX_FACES, f"a triangle count 4 <= faces <= {MAX_FACES:,}"),
    ("tracks", "track_radius_mm"): (0.0, None, "a radius > 0 mm"),
    ("tracks", "cover_mm"): (0.0, None, "a thickness >= 0 mm"),
}
OPEN_LOW = {("tracks", "track_radius_mm")}  # the lowest value itself is refused


def check_ranges(scene, where: str) -> None:
    """Raise SceneError for the first key of `RANGES` outside its range, for a scene
    file that declares no section at all (it would run nothing), and for an [[evaluate]]
    label given twice."""
    if not scene.declared:
        raise SceneError(f"{where}: the scene declares no section; expected at least [scene] "
                         "and what to run ([geometry], [[evaluate]], ...)")
    labels = [ev["label"] for ev in scene["evaluate"]]
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise SceneError(f"{where}: [[evaluate]].label: {twice[0]!r} is given twice; expected "
                         "one label per row (it names the row's folder and table line)")
    for (section, key), (lo, hi, what) in RANGES.items():
        value = scene[section][key]
        low_ok = value > lo if (section, key) in OPEN_LOW else value >= lo
        if not low_ok or (hi is not None and value > hi):
            raise SceneError(f"{where}: [{section}].{key}: expected {what}, got {value}")
