"""make-mold: the molds of a scene's pieces from its make-tracks outputs (files in, files out).

Writes into the output folder, all together or nothing: one binary STL per mold part (mm,
ready for a slicer), mold.json (which parts cast which piece, volumes, silicone, pour and
vents, undercuts) and preview.png (each mold exploded).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.fabrication.mold import MoldOptions, assembled_cavity, make_mold, undercut_area

if TYPE_CHECKING:
    import manifold3d as mf

    from fruitcli.fabrication.mold import Mold

CLI_NAMES = {k: "--" + k.replace("_", "-") for k in MoldOptions.__dataclass_fields__}
SCENE_NAMES = {k: f"[mold].{k}" for k in MoldOptions.__dataclass_fields__}
ELLIPSOID_SEGMENTS = 64


def load_solid(path: str | Path, what: str) -> mf.Manifold:
    """A closed surface file in mm as a float64 Manifold."""
    from fruitcli.geometry.mesh import load
    from fruitcli.geometry.tracks.reduce import to_manifold64

    surf = load.load_mesh(path)
    if not surf.closed:
        raise GeometryError(f"{what}: {path} is not one closed surface")
    m = to_manifold64(surf.vertices, surf.faces)
    import manifold3d as mf

    if m.status() != mf.Error.NoError or m.is_empty():
        raise GeometryError(f"{what}: {path} is not a valid solid ({m.status().name})")
    return m


def scene_chambers(scene) -> list:  # noqa: ANN001 (a Scene: fabrication may not import it)
    """[(name, Manifold)] of the scene's chambers (mm)."""
    import manifold3d as mf

    from fruitcli.geometry.mesh.load import UNIT_TO_MM

    out = []
    for ch in scene.chambers:
        if ch.ellipsoid is not None:
            e = ch.ellipsoid
            m = (
                mf.Manifold.sphere(1.0, ELLIPSOID_SEGMENTS)
                .scale(tuple(float(r) for r in e.radii_mm))
                .translate(tuple(float(c) for c in e.center_mm))
            )
        else:
            m = load_solid(ch.surface, f"[[geometry.chamber]] '{ch.name}'.surface")
            m = m.scale((UNIT_TO_MM[scene.geometry.unit],) * 3)
        out.append((ch.name, m))
    return out


def run_make_mold(
    tracks_dir: str | Path,
    out_dir: str | Path,
    chambers: list,
    density_kg_m3: float,
    opts: MoldOptions,
    names: dict | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Build the top and bottom molds from a make-tracks folder; write `out_dir`."""
    import manifold3d as mf

    from fruitcli.fsutil import staged_dir, write_json
    from fruitcli.geometry.mesh import export
    from fruitcli.geometry.tracks.reduce import manifold_arrays

    say = progress or (lambda msg: None)
    opts.check(names or CLI_NAMES)
    tracks_dir = Path(tracks_dir)
    zp, r_track = _parting_plane(tracks_dir)
    tracks_xy = _track_points(tracks_dir / "tracks.csv")
    t0 = time.perf_counter()
    top = load_solid(tracks_dir / "tracked_top.stl", "make-tracks")
    reduced = load_solid(tracks_dir / "reduced.stl", "make-tracks")
    bottom = reduced.trim_by_plane((0.0, 0.0, -1.0), -zp)
    if bottom.is_empty():
        raise GeometryError(f"{tracks_dir}: nothing of the body lies below the split plane")
    # the STL's float32 base may sit a hair off the plane: snap the pieces onto it
    top = _snap(top, zp, +1)
    bottom = _snap(bottom, zp, -1)
    for cname, ch in chambers:
        if (ch - reduced).volume() > 1e-4 * ch.volume():
            raise GeometryError(
                f"[[geometry.chamber]] '{cname}': the chamber pokes out of the "
                f"reduced body ({tracks_dir / 'reduced.stl'})"
            )
    say(f"pieces: {time.perf_counter() - t0:.2f} s")
    molds, entries = [], []
    for name, piece, side in (("top", top, +1), ("bottom", bottom, -1)):
        t0 = time.perf_counter()
        mold = make_mold(
            name, piece, zp, side, chambers, opts, tracks_xy if name == "top" else None, r_track
        )
        entries.append(_mold_entry(name, mold, piece, zp, side, opts, density_kg_m3))
        sil = mold.silicone.volume()
        molds.append(mold)
        say(
            f"{name} mold: {len(mold.parts)} parts, {sil / 1000:.1f} ml, "
            f"{time.perf_counter() - t0:.2f} s"
        )
    report = {
        "molds": entries,
        "density_kg_m3": density_kg_m3,
        "options_mm": {k: getattr(opts, k) for k in MoldOptions.__dataclass_fields__},
        "source": str(tracks_dir),
    }
    with staged_dir(out_dir) as tmp:
        tmp = Path(tmp)
        for mold in molds:
            for pname, part in mold.parts.items():
                v, f = manifold_arrays(part)
                closed, bodies = export.write_stl(tmp / f"{pname}.stl", v, f)
                if not closed or bodies != 1:
                    raise GeometryError(
                        f"{pname}.stl does not reload as one closed part ("
                        f"{'closed' if closed else 'open'}, {bodies} bodies)"
                    )
        _preview(tmp / "preview.png", molds, zp)
        write_json(tmp / "mold.json", report)
    del mf
    return report


def _parting_plane(tracks_dir: Path) -> tuple[float, float]:
    """(the parting plane's z, the tracks' radius) mm from make-tracks' report.json."""
    rep_path = tracks_dir / "report.json"
    if not rep_path.exists():
        raise GeometryError(f"{tracks_dir}: no report.json (run make-tracks first)")
    try:
        tr_rep = json.loads(rep_path.read_text())
        zp, r_track = float(tr_rep["split_z_mm"]), float(tr_rep["track_radius_mm"])
    except (ValueError, KeyError, TypeError):
        raise GeometryError(
            f"{rep_path}: no split_z_mm or track_radius_mm (expected make-tracks' report)"
        ) from None
    return zp, r_track


def _mold_entry(
    name: str,
    mold: Mold,
    piece: mf.Manifold,
    zp: float,
    side: int,
    opts: MoldOptions,
    density_kg_m3: float,
) -> dict:
    """mold.json's entry of a mold: its parts, volumes (mm^3), pull directions,
    undercuts, silicone (ml, g), pour hole and vents."""
    cavity = assembled_cavity(mold)
    sil = mold.silicone.volume()
    extra = (cavity - mold.silicone).volume()
    missing = (mold.silicone - cavity).volume()
    return {
        "piece": name,
        "parts": [f"{p}.stl" for p in mold.parts],
        "cores": mold.cores,
        "part_volumes_mm3": {f"{p}.stl": round(m.volume(), 3) for p, m in mold.parts.items()},
        "pull_direction": {f"{p}.stl": d for p, d in mold.pull.items()},
        "undercut_area_mm2": {
            f"{p}.stl": a for p, a in undercut_area(piece, zp, side, mold.pull).items()
        },
        "piece_volume_mm3": round(sil, 3),
        "cavity_volume_mm3": round(cavity.volume(), 3),
        "channels_volume_mm3": round(mold.channels.volume(), 3),
        "cavity_outside_piece_mm3": round(extra, 3),
        "piece_outside_cavity_mm3": round(missing, 3),
        "cavity_vs_piece": round(cavity.volume() / sil, 5),
        "silicone_ml": round(sil / 1000.0, 2),
        "silicone_g": round(sil / 1000.0 * density_kg_m3 / 1000.0, 1),
        "pour_hole_mm": mold.pour_mm,
        "vents_mm": mold.vents_mm,
        "pour_diameter_mm": opts.pour_diameter_mm,
        "vent_diameter_mm": opts.vent_diameter_mm,
        "parting_plane_z_mm": zp,
        "box_mm": [round(v, 3) for v in mold.box_mm],
    }


def _track_points(path: str | Path) -> np.ndarray:
    """Track centre points (k, 3) mm from make-tracks' tracks.csv."""
    from fruitcli.tables import read_table

    if not Path(path).exists():
        raise GeometryError(f"{path}: not found (make-tracks writes it; run it again)")
    t = read_table(path, ["x_mm", "y_mm", "z_mm"], error=GeometryError)
    return np.c_[t["x_mm"], t["y_mm"], t["z_mm"]]


def _snap(piece: mf.Manifold, zp: float, side: int):
    """Move the piece's flat face exactly onto z = zp (it is within float32 of it)."""
    b = piece.bounding_box()
    dz = zp - (b[2] if side > 0 else b[5])
    if abs(dz) > 1e-3:
        raise GeometryError(
            f"the piece's flat face is {abs(dz):.4f} mm off the split plane z = {zp:.3f} mm"
        )
    return piece.translate((0.0, 0.0, dz))


def _preview(path: str | Path, molds: list[Mold], zp: float) -> None:
    """Each mold's parts side by side, each turned with its parting face up (the shell of
    the top piece upside down: its inner face with the track ridges shows), cut at the
    box's centre y so that the cavity shows in section; cores stay on their plate."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from fruitcli.geometry.tracks.preview import draw_perspective
    from fruitcli.geometry.tracks.reduce import manifold_arrays

    fig = Figure(figsize=(14, 5.0 * len(molds)), dpi=110)
    for k, mold in enumerate(molds):
        ax = fig.add_subplot(len(molds), 1, k + 1)
        b = mold.box_mm
        yc, width = 0.5 * (b[1] + b[4]), b[3] - b[0]
        shift = 0.0
        for pname in mold.parts:
            if "_core_" in pname:
                continue
            up = mold.pull[pname][2] > 0 if mold.pull[pname] else True
            group = [mold.parts[pname]] + (
                [mold.parts[c] for c in mold.parts if "_core_" in c]
                if pname.endswith("_plate")
                else []
            )
            for part in group:
                if up:  # parting face down: turn it over
                    part = (
                        part.mirror((0.0, 0.0, 1.0))
                        .mirror((0.0, 1.0, 0.0))
                        .translate((0.0, 2 * yc, 2 * zp))
                    )
                v, f = manifold_arrays(part.trim_by_plane((0.0, 1.0, 0.0), yc))
                if len(f):
                    draw_perspective(ax, v + (shift, 0.0, 0.0), f, [], np.zeros((0, 3)), flat=True)
            shift += 1.3 * width
        ax.set_title(
            f"{mold.piece} mold: {', '.join(mold.parts)} (each with its parting "
            f"face up, cut at y = {yc:.0f} mm)",
            fontsize=9,
        )
    fig.tight_layout()
    fig.savefig(path)
