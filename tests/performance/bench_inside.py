"""Benchmark: how to tell inside from outside on the meshes artists have.

For each test mesh of tests/helpers/artist_meshes.py (holes, overlapping parts, an unclosed lid,
an open sheet, a plane, a closed machined part) and 20,000 random points in its box,
farther than 1 mm from the surface, each candidate's answer is compared with the known
solid (the analytic shape the mesh was cut from); prints the wrong fraction and the time:

- ray parity (vertical rays, what make-tracks used before; exact for closed meshes),
- fruit's fast winding number (Barnes-Hut tree, what make-tracks uses on open meshes),
- fruit's exact winding number (every triangle for every point; the reference),
- libigl's fast and exact ones, only if the `libigl` wheel happens to be installed (it
  is not a dependency: the wheel also carries GPL and non-commercial code), with the
  largest difference from fruit's exact one,
- manifold3d (the boolean kernel): whether it accepts the mesh at all.

pymeshfix is not measured: it wraps MeshFix, which is GPL, so it cannot be a dependency.

Run: .venv/bin/python tests/performance/bench_inside.py
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.helpers import artist_meshes as am


def _ellipsoids(p, items):
    return np.any(
        [(((p - np.asarray(c)) / np.asarray(r)) ** 2).sum(1) < 1 for c, r in items], axis=0
    )


def truth(name, p):
    """Inside (k,) bool of the solid each test mesh was cut from (None: no inside)."""
    if name == "sphere_with_holes":
        return np.linalg.norm(p, axis=1) < 40.0
    if name == "head_with_eye_sockets":
        return _ellipsoids(p, [((0, 0, 0), (40, 50, 60))])
    if name == "overlapping_figure":
        return _ellipsoids(
            p,
            [
                ((0, 0, 0), (18, 12, 28)),
                ((0, 0, 40), (11, 11, 11)),
                ((0, 0, 29), (5, 5, 6)),
                ((-24, 0, 8), (16, 6, 6)),
                ((24, 0, 8), (16, 6, 6)),
                ((-9, 0, -38), (7, 7, 18)),
                ((9, 0, -38), (7, 7, 18)),
                ((-9, 6, -56), (6, 10, 4)),
                ((9, 6, -56), (6, 10, 4)),
            ],
        )
    if name == "teapot_with_open_lid":
        return _ellipsoids(p, [((0, 0, 0), (50, 50, 38))]) & (p[:, 2] < 27.0)
    if name == "machined_part":  # closed: ray parity is exact
        m = am.machined_part()
        return _parity(m.vertices, m.faces, p)
    return None


def _parity(v, f, p):
    from fruitcli.geometry.mesh.columns import vertical_hits

    pi, zh = vertical_hits(v, f, p)
    above = np.bincount(pi[zh > p[pi, 2]], minlength=len(p))
    return above % 2 == 1


def _libigl():
    """The libigl module if installed, else None (an optional comparison only)."""
    try:
        import igl
    except ImportError:
        return None
    return igl


def main() -> None:
    from fruitcli.geometry.mesh import load
    from fruitcli.geometry.mesh.distance import SurfaceDistance
    from fruitcli.geometry.mesh.solid_angle import exact_winding
    from fruitcli.geometry.mesh.winding import Winding

    igl = _libigl()
    if igl is None:
        print("(libigl not installed: fruit's own evaluations only)")
    one = (np.eye(3), np.array([[0, 1, 2]]))
    Winding(*one)(np.zeros((1, 3)))  # load the compiled kernels first
    exact_winding(*one, np.zeros((1, 3)))

    rng = np.random.default_rng(0)
    print(
        f"{'mesh':24s} {'faces':>6s}  {'parity wrong':>12s}  {'fast WN wrong':>13s} "
        f"{'exact WN wrong':>14s}  {'fast WN s':>9s} {'exact WN s':>10s}  manifold3d"
    )
    for name, make in am.ALL.items():
        m = make()
        s = load.clean(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
        v, f = s.vertices, s.faces
        lo, hi = v.min(0) - 5, v.max(0) + 5
        p = lo + (hi - lo) * rng.random((60000, 3))
        _, d, _ = SurfaceDistance(v, f).closest(p)
        p = p[d > 1.0][:20000]
        want = truth(name, p)
        t0 = time.perf_counter()
        fast = Winding(v, f)(p)
        t_fast = time.perf_counter() - t0
        t0 = time.perf_counter()
        exact = exact_winding(v, f, p)
        t_exact = time.perf_counter() - t0
        if igl is not None:
            t0 = time.perf_counter()
            bvh = igl.FastWindingNumberBVH()
            bvh.init(v, f)
            igl_fast = bvh.winding_number(p, 2.0)
            t_igl = time.perf_counter() - t0
            igl_exact = igl.winding_number(v, f, p)
            igl_note = (
                f"  libigl fast {t_igl:.3f} s, |fruit fast - exact| max "
                f"{np.abs(fast - exact).max():.4f}, |libigl fast - exact| max "
                f"{np.abs(igl_fast - exact).max():.4f}, |libigl exact - fruit exact| "
                f"max {np.abs(igl_exact - exact).max():.1e}"
            )
        else:
            igl_note = f"  |fast - exact| max {np.abs(fast - exact).max():.4f}"
        par = _parity(v, f, p)
        status = load.to_manifold(v, f).status().name
        if want is None:
            rates = [f"{(x > 0.5).mean() * 100:11.2f}%" for x in (par, fast, exact)]
            note = " (share called inside; has no inside)"
        else:
            rates = [f"{((x > 0.5) != want).mean() * 100:11.2f}%" for x in (par, fast, exact)]
            note = ""
        print(
            f"{name:24s} {len(f):6d}  {rates[0]:>12s}  {rates[1]:>13s} {rates[2]:>14s}  "
            f"{t_fast:9.3f} {t_exact:10.3f}  {status}{note}  w in "
            f"[{fast.min():.2f}, {fast.max():.2f}]{igl_note}"
        )


if __name__ == "__main__":
    main()
