"""Benchmark: make-tracks on the default artist mesh (each step's wall and CPU time, peak
RSS), make-mold on its output, the winding number on the default Fruit's grid (crossing
counts, as make-tracks does on a closed mesh, against the Barnes-Hut tree), and the
winding-number step alone on a 100,000-triangle scan-like mesh.

Run: .venv/bin/python tests/performance/bench_geometry.py
(On a shared machine wall times follow the load; the CPU time of this process is the
steadier figure: on an idle machine the two agree for these single-threaded steps.)
"""

import resource
import tempfile
import time
from pathlib import Path

import numpy as np


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def scan_like(n_target: int = 100_000):
    """A scanned figure as scans come: a bumpy closed-ish body of about `n_target`
    triangles with holes in its base (vertices mm)."""
    import trimesh

    n = int(np.sqrt(n_target / 4))
    m = trimesh.creation.uv_sphere(radius=1.0, count=[n, n])
    v = np.asarray(m.vertices) * (60.0, 45.0, 75.0)
    v *= 1.0 + 0.03 * np.sin(5 * v[:, [0]] / 60) * np.cos(4 * v[:, [2]] / 75)
    c = v[m.faces].mean(axis=1)
    keep = ~((c[:, 2] < -60) & (np.abs(np.sin(c[:, 0] / 4) * np.sin(c[:, 1] / 4)) > 0.8))
    return v, np.asarray(m.faces)[keep]


def _load_avg() -> str:
    import os

    return "load average " + " ".join(f"{x:.1f}" for x in os.getloadavg())


def fruit_grid_step(art: Path) -> None:
    """The winding number on the grid make-tracks samples on the default Fruit: the exact
    crossing count (a closed mesh) against the tree at the same points (the near band
    evaluated, the rest interpolated, as for an open mesh), and the exact sum at a
    sample of the band's points."""
    from fruitcli.geometry.mesh import load, winding
    from fruitcli.geometry.mesh.solid_angle import exact_winding
    from fruitcli.geometry.tracks import reduce

    s = load.load_mesh(art)
    h = reduce.grid_for_faces(s.vertices, s.faces, 5000)
    lo, hi = s.vertices.min(0) - 2 * h, s.vertices.max(0) + 2 * h
    axes = [lo[k] + h * np.arange(int(np.ceil((hi[k] - lo[k]) / h)) + 1) for k in range(3)]
    shape = tuple(len(a) for a in axes)
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    from scipy.spatial import cKDTree

    r = winding.EXACT_BAND_SPACINGS * h
    near = (cKDTree(s.vertices).query(pts, distance_upper_bound=r)[0] < r).reshape(shape)
    wn = winding.Winding(s.vertices, s.faces)
    t0, c0 = time.perf_counter(), time.process_time()
    w_count = winding.column_winding(wn, axes)
    t1, c1 = time.perf_counter(), time.process_time()
    wn.closed = False  # as for an open mesh: the tree
    w_tree = winding.grid_winding(wn, axes, near)
    t2, c2 = time.perf_counter(), time.process_time()
    pick = np.random.default_rng(0).choice(np.nonzero(near.ravel())[0], 300, replace=False)
    exact = exact_winding(s.vertices, s.faces, pts[pick])
    flips = int(((w_tree > 0.5) != (w_count > 0.5)).sum())
    print(
        f"winding number on the default Fruit's grid ({len(pts)} points, {len(s.faces)} "
        f"triangles; {_load_avg()}):"
    )
    print(
        f"  crossing count (exact, closed mesh; what make-tracks uses): {t1 - t0:.2f} s "
        f"({c1 - c0:.2f} s CPU)"
    )
    print(
        f"  tree (build, {int(near.sum())} near points evaluated, the rest from the "
        f"coarse grid): {t2 - t1:.2f} s ({c2 - c1:.2f} s CPU); inside/outside differs at "
        f"{flips} points; |tree - count| max {np.abs(w_tree - w_count).max():.4f}; at "
        f"300 band points |tree - exact sum| max "
        f"{np.abs(w_tree.ravel()[pick] - exact).max():.4f}, |count - exact sum| max "
        f"{np.abs(w_count.ravel()[pick] - exact).max():.1e}"
    )
    try:  # an optional comparison: libigl is not a dependency
        import igl
    except ImportError:
        return
    band = pts[near.ravel()]
    c0 = time.process_time()
    bvh = igl.FastWindingNumberBVH()
    bvh.init(s.vertices, s.faces)
    w_igl = bvh.winding_number(band, winding.ACCURACY)
    c1 = time.process_time()
    w_own = wn(band)
    c2 = time.process_time()
    count = w_count.ravel()[near.ravel()]
    igl_pick = bvh.winding_number(pts[pick], winding.ACCURACY)
    print(
        f"  libigl (installed) on the {len(band)} band points: {c1 - c0:.2f} s CPU with its "
        f"tree, fruit's {c2 - c1:.2f} s (its tree built above); at the 300 band points "
        f"|libigl - exact sum| max "
        f"{np.abs(igl_pick - exact).max():.4f}; inside/outside against the count: libigl "
        f"differs at {int(((w_igl > 0.5) != (count > 0.5)).sum())} points, fruit's tree at "
        f"{int(((w_own > 0.5) != (count > 0.5)).sum())}"
    )


def winding_step(v, f) -> None:
    """Time what make-tracks does for the inside on a mesh that is not closed."""
    from fruitcli.geometry.mesh import load, winding
    from fruitcli.geometry.tracks import reduce
    from fruitcli.geometry.tracks.densify import densify

    t0, c0 = time.perf_counter(), time.process_time()
    s = load.clean(v, f)
    h = reduce.grid_for_faces(s.vertices, s.faces, 5000)
    dv, df, _ = densify(s.vertices, s.faces, 3 * h)
    t1, c1 = time.perf_counter(), time.process_time()
    one_sheet = s.parts == 1 and s.non_manifold_edges == 0  # as make-tracks decides
    inside = reduce.Inside(dv, df, all_faces_bound=False, holes=True)
    inside.wn(dv[:1])  # builds the tree
    t_bvh = time.perf_counter() - t1
    bound = winding.boundary_faces(inside.wn, dv, df)  # make-tracks: parts > 1 only
    t2, c2 = time.perf_counter(), time.process_time()
    lo, hi = dv.min(0) - 2 * h, dv.max(0) + 2 * h
    axes = [lo[k] + h * np.arange(int(np.ceil((hi[k] - lo[k]) / h)) + 1) for k in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    assert inside.tree is not None  # built above
    near = (
        inside.tree.query(pts, distance_upper_bound=winding.EXACT_BAND_SPACINGS * h)[0]
        < winding.EXACT_BAND_SPACINGS * h
    )
    w = winding.grid_winding(inside.wn, axes, near.reshape(tuple(len(a) for a in axes)))
    t3, c3 = time.perf_counter(), time.process_time()
    print(
        f"scan ({_load_avg()}): {len(f)} triangles, {s.holes} holes (largest "
        f"{s.largest_hole_perimeter_mm:.0f} mm around); load checks {t1 - t0:.2f} s "
        f"({c1 - c0:.2f} s CPU)"
    )
    print(
        f"  winding number tree ({len(df)} triangles): {t_bvh:.2f} s; both sides of every "
        f"face (which faces bound the inside; {len(df)} faces, {int((~bound).sum())} "
        f"dropped; make-tracks does this only for several parts, here "
        f"{'skipped' if one_sheet else 'done'}): "
        f"{t2 - t1 - t_bvh:.2f} s; together {c2 - c1:.2f} s CPU"
    )
    print(
        f"  winding number on the {len(pts)}-point grid ({int(near.sum())} evaluated, the "
        f"rest interpolated), w in [{w.min():.2f}, {w.max():.2f}]: {t3 - t2:.2f} s "
        f"({c3 - c2:.2f} s CPU; {1e6 * (c3 - c2) / max(int(near.sum()), 1):.1f} us CPU per "
        "evaluated point, the KD-tree query for the band included)"
    )


def mold_step(tracks_dir: Path, out_dir: Path) -> None:
    """make-mold on the default Fruit with the three chambers of fruit-breathing.toml."""
    from fruitcli.fabrication.mold import MoldOptions
    from fruitcli.fabrication.stage import run_make_mold, scene_chambers
    from fruitcli.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "pipelines" / "fruit-breathing.toml")
    cpu = [time.process_time()]

    def say(m):
        now = time.process_time()
        print(f"  {m}  ({now - cpu[0]:.2f} s CPU)")
        cpu[0] = now

    t0, c0 = time.perf_counter(), time.process_time()
    rep = run_make_mold(
        tracks_dir, out_dir, scene_chambers(scene), 1070.0, MoldOptions(), progress=say
    )
    print(
        f"make-mold total: {time.perf_counter() - t0:.2f} s wall, "
        f"{time.process_time() - c0:.2f} s CPU (target < 10 s), peak RSS {rss_mb():.0f} MB"
    )
    for m in rep["molds"]:
        print(
            f"  {m['piece']}: {len(m['parts'])} parts, {m['silicone_ml']} ml, cavity / piece "
            f"{m['cavity_vs_piece']:.4f}"
        )


def main() -> None:
    from fruitcli.geometry.artist import write_artist
    from fruitcli.geometry.tracks.make_tracks import make_tracks

    with tempfile.TemporaryDirectory() as tmp:
        art = Path(tmp) / "fruit.stl"
        t0 = time.perf_counter()
        info = write_artist(art)
        print(
            f"make-artist: {time.perf_counter() - t0:.2f} s, {info['triangles']} triangles, "
            f"peak RSS {rss_mb():.0f} MB"
        )

        def say(m):
            print(f"  {m}  (peak RSS {rss_mb():.0f} MB)")

        print(f"make-tracks ({_load_avg()}):")
        t0, c0 = time.perf_counter(), time.process_time()
        report = make_tracks(art, Path(tmp) / "out", progress=say)
        total, ctot = time.perf_counter() - t0, time.process_time() - c0
        print(
            f"make-tracks total: {total:.2f} s wall, {ctot:.2f} s CPU (target < 5 s), "
            f"peak RSS {rss_mb():.0f} MB (target <= 1024 MB); {_load_avg()}"
        )
        print(
            f"taxels {report['taxels']}, reduced {report['triangles']['reduced']} triangles, "
            f"Hausdorff {report['offset_error']['hausdorff_mm']:.3f} mm"
        )
        mold_step(Path(tmp) / "out", Path(tmp) / "mold")
        fruit_grid_step(art)
    winding_step(*scan_like())


if __name__ == "__main__":
    main()
