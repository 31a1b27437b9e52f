"""What a bench frame can tell of a touch's position: the Cramer-Rao bound of each bench
sample's contact point under the bench's own Gaussian law, for the locate study's Fruit.

For each Gaussian bench skin of `fruit study locate` (calibrated, wider, narrower) and
each indenter, taxel k of the sample's detection frame reads A g_k exp(-|c - P_k|^2 / 2
sigma^2) plus noise of std e_k: the bench's own gains g_k, noise e_k, footprint sigma and
taxel positions P_k (the study's board, drawn from the scene's seed as `fruit bench`
draws it), the point c moving in the body's tangent plane at the true contact point
(the surface's nearest face) and A, the amplitude, free (the gap at detection is not
known). A is set so that the strongest taxel reads the threshold, as at detection. The
bound is the 1-sigma radius sqrt(C_uu + C_vv) of the inverse Fisher information of (u,
v, A): no unbiased estimator, this project's or any other, that is handed the bench's
own law places the sample with a smaller spread from one frame (from n frames of the
same touch: the radius over sqrt(n)). Printed per skin and indenter: the median bound
and largest bound inside the outline (the taxels' convex hull from above) and each
bound outside it.

Run: python tests/performance/locate_bound.py --study DIR, DIR the study's output for the
Fruit at rest (`fruit study locate pipelines/fruit-rest.toml --out DIR`, or
tests/performance/locate_methods_docs.py's DIR/rest).
"""

from __future__ import annotations

import argparse
import os
import sys
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
GAUSSIAN_BENCHES = ("calibrated", "wider", "narrower")
UNPLACED_MM = 100.0  # a bound past this: the frame does not place the sample at all


def tangent_frames(surface, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (m, 3) each spanning the tangent plane of `surface` (a trimesh)
    at its face nearest each point (by face centre)."""
    from scipy.spatial import cKDTree

    _, face = cKDTree(surface.triangles_center).query(points)
    n = surface.face_normals[face]
    seed = np.where(np.abs(n[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(n, seed)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(n, e1)


def bound_radius(
    point: np.ndarray,
    e1: np.ndarray,
    e2: np.ndarray,
    taxels_mm: np.ndarray,
    gain: np.ndarray,
    noise: np.ndarray,
    sigma_mm: float,
    peak_counts: float,
) -> float:
    """The Cramer-Rao 1-sigma radius (mm) of a contact point at `point` (3,) moving in
    the plane (e1, e2), its amplitude free, read by taxels at `taxels_mm` (T, 3) with
    gains and noise std (T,) through a Gaussian of `sigma_mm`, the strongest reading
    `peak_counts`; inf where the frame does not fix the point."""
    d = point - taxels_mm
    f = gain * np.exp(-0.5 * np.sum(d * d, axis=1) / sigma_mm**2)
    amp = peak_counts / f.max()
    m = amp * f
    jac = np.stack([-m * (d @ e1), -m * (d @ e2)], axis=1) / sigma_mm**2
    jac = np.column_stack([jac, f]) / noise[:, None]
    info = jac.T @ jac
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return float("inf")
    var = cov[0, 0] + cov[1, 1]
    return float(np.sqrt(var)) if var > 0 and np.isfinite(var) else float("inf")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--study", type=Path, required=True, help="the study's output at rest")
    args = ap.parse_args()
    import trimesh
    from run_all import commit, processor

    from fruitcli.evaluation.outline import inside_outline
    from fruitcli.scene import load_scene
    from fruitcli.sensing.skin import forward
    from fruitcli.studies.locate_methods import bench_skin_values
    from fruitcli.tables import read_taxels

    study = args.study
    taxels_csv = next((study / "scene").glob("*/taxels.csv"))
    surface = trimesh.load(next((study / "scene").glob("*/reduced.stl")), force="mesh")
    taxels = read_taxels(taxels_csv)
    outline = taxels.xyz_mm
    scene = load_scene(ROOT / "pipelines" / "fruit-rest.toml")
    threshold = float(scene.detection.threshold_counts)
    print(
        f"Cramer-Rao bound of the bench samples' points, the Fruit at rest, one frame; "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, commit {commit()}, {processor()}, "
        f"{os.cpu_count()} cores"
    )
    for name in GAUSSIAN_BENCHES:
        bench_scene = scene.with_values(bench_skin_values(name, scene.bench.indenters))
        params = forward.SkinParams.from_table(bench_scene.skin)
        skin = forward.make_skin(len(taxels), bench_scene.bench.seed, params, taxels.ids)
        gain = np.ones(len(taxels)) if skin.gain is None else skin.gain
        noise = skin.noise_std_counts
        for ind in scene.bench.indenters:
            truth_csv = study / "work" / name / "bench" / ind / "truth.csv"
            truth = np.loadtxt(truth_csv, delimiter=",", comments="#", skiprows=2)
            ids, points = truth[:, 0].astype(int), truth[:, 1:4]
            e1, e2 = tangent_frames(surface, points)
            sigma = forward.footprint_sigma_mm(ind, params)
            radii = np.array(
                [
                    bound_radius(p, a, b, taxels.xyz_mm, gain, noise, sigma, threshold)
                    for p, a, b in zip(points, e1, e2, strict=True)
                ]
            )
            inside = inside_outline(points, outline)
            outside = ", ".join(
                f"{k}: {r:.1f}" if r < UNPLACED_MM else f"{k}: over {UNPLACED_MM:.0f}"
                for k, r in zip(ids[~inside], radii[~inside], strict=True)
            )
            print(
                f"{name}, {ind}: inside the outline ({int(inside.sum())}) median "
                f"{np.median(radii[inside]):.2f} mm, largest {radii[inside].max():.2f} mm; "
                f"outside, sample: mm ({outside})"
            )


if __name__ == "__main__":
    main()
