"""The electrostatic skin's speed: the default crossing's table, and assembly against
scikit-fem.

Target: the default cell's table (both indenters, a finger, the strains and
bends) in at most 2 minutes on a 2-core machine: the default Fruit's design (pitch 16 x
12 mm, cover 2 mm, yarn radius 0.6 mm, insulation 0.1 mm, eps_r 2.8, 10 gaps to 8 mm). Prints
the mesh and solve times, C0, counts per fF and the derived equivalents.

Then the virtual bench's cost per frame with each skin model (target: the electrostatic
no more than twice the Gaussian): `virtual_bench.descend` over a flat 8 x 6 grid of
taxels 16 x 12 mm apart (the default Fruit has 40), the small indenter coming down on a
sample a quarter taxel off each, every frame of each descent made (threshold out of
reach), the table just computed; the least CPU time (this process's: other work on a shared
machine counts less) of FRAME_RUNS interleaved runs of each.
`python tests/performance/bench_skin.py --frames DIR` times only that, on the table of
`fruit skin`'s DIR.

`python tests/performance/bench_skin.py --assembly` instead times the stiffness assembly of
fruit's kernel (linear and quadratic tets) against scikit-fem's on the same gmsh meshes
(scikit-fem must be importable; it is not a dependency).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from fruitcli.electrostatics import assemble
from fruitcli.electrostatics.design import CrossingInputs, run_crossing

DEFAULT = CrossingInputs(
    pitch_x_mm=16.0,
    pitch_y_mm=12.0,
    cover_mm=2.0,
    yarn_radius_mm=0.6,
    insulation_mm=0.1,
    permittivity=2.8,
    gaps_mm=(0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0),
    time_limit_s=120.0,
)
TARGET_S = 120.0
FRAME_RUNS = 9
FRAME_RATIO_TARGET = 2.0


def table() -> None:
    from fruitcli.electrostatics.crossing import STEPS_PER_HALF_PITCH
    from fruitcli.electrostatics.design import table_arrays
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

    t0 = time.perf_counter()
    tab, summary = run_crossing(DEFAULT)
    wall = time.perf_counter() - t0
    mesh = summary["mesh"]
    quadrant = (STEPS_PER_HALF_PITCH + 1) ** 2  # positions; each solve gives 3 x 3 crossings
    solves = (
        1
        + len(tab.objects) * len(tab.gap_mm) * quadrant
        + 2 * (len(tab.strain) - 1 + len(tab.curvature_per_mm) - 1)
    )
    print(
        f"default cell: {mesh['tets']} tets, {mesh['nodes']} nodes (P{mesh['order']}), "
        f"{solves} solves"
    )
    print(
        f"  mesh {summary['mesh_s']:.1f} s, solves {summary['solve_s']:.1f} s, "
        f"table {wall:.1f} s wall (target <= {TARGET_S:.0f} s: "
        f"{'met' if wall <= TARGET_S else 'MISSED'})"
    )
    print(
        f"  C0 {summary['c0_ff']:.1f} fF, counts per fF {summary['counts_per_ff']:.3f} "
        f"(bent pad: {summary['counts_fit']['shift_ff']:+.2f} fF -> 10 counts)"
    )
    assumed = summary["assumed"]
    for name, obj in summary["objects"].items():
        sigma = assumed["footprint_sigma_mm"].get(name)
        print(
            f"  {name:7s} dC at contact {obj['contact_dc_ff']:8.2f} fF = "
            f"{obj['contact_counts']:6.1f} counts (assumed {assumed['contact_counts']:.0f}); "
            f"footprint sigma {obj['footprint_sigma_mm']:.2f} mm (assumed "
            f"{'-' if sigma is None else f'{sigma:.2f}'}); gap decay "
            f"{obj['gap_decay_mm']:.2f} mm (assumed {assumed['gap_decay_mm']:.1f}); "
            f"threshold crossed at {obj['threshold_gap_mm']:.2f} mm"
        )
    shifts = summary["deformation_shift_counts"]
    for key in ("stretch_x", "stretch_y"):
        print(f"  {key} at strains {shifts['strain']}: {np.round(shifts[key], 1).tolist()} counts")
    for key in ("bend_x", "bend_y"):
        print(
            f"  {key} at curvatures {np.round(shifts['curvature_per_mm'], 4).tolist()} /mm: "
            f"{np.round(shifts[key], 1).tolist()} counts"
        )
    frame_cost(CrossingSkin.from_table(table_arrays(tab), summary))


def frame_cost(response) -> None:
    """Print the virtual bench's microseconds per frame with each skin model."""
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.virtual_bench import START_GAP_MM, descend, quarter_samples

    gx, gy = np.meshgrid(np.arange(8) * 16.0, np.arange(6) * 12.0, indexing="ij")
    taxels = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    xy = quarter_samples(taxels[:, :2], 16.0, 12.0)
    contact = np.column_stack([xy, np.zeros(len(xy))])
    skin = forward.make_skin(len(taxels), 0)
    step = 0.1
    frames = len(contact) * len(np.arange(START_GAP_MM, -2.0 - step / 2, -step))
    best = {"gaussian": np.inf, "electrostatic": np.inf}
    for _ in range(FRAME_RUNS):
        for name, model in (("gaussian", None), ("electrostatic", response)):
            rng = np.random.default_rng(0)
            t0 = time.process_time()
            descend(
                contact, taxels, skin.baseline_counts, skin, "small", step, 10, np.inf, rng, model
            )
            best[name] = min(best[name], time.process_time() - t0)
    per = {name: 1e6 * t / frames for name, t in best.items()}
    ratio = per["electrostatic"] / per["gaussian"]
    print(
        f"bench per frame ({len(taxels)} taxels, {frames} frames): gaussian "
        f"{per['gaussian']:.2f} us, electrostatic {per['electrostatic']:.2f} us, ratio "
        f"{ratio:.2f} (target <= {FRAME_RATIO_TARGET:g}: "
        f"{'met' if ratio <= FRAME_RATIO_TARGET else 'MISSED'})"
    )


def assembly() -> None:
    sys.path.insert(0, "tests/electrostatics")
    import es_shapes

    try:
        from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, MeshTet, asm
        from skfem.helpers import dot, grad
    except ImportError:
        print("scikit-fem is not installed: only fruit's assembly is timed")
        asm = None

    for order, h in ((1, 0.12), (2, 0.2)):
        mesh = es_shapes.concentric_spheres(1.0, 2.0, h, order)
        eps = np.random.default_rng(0).uniform(1.0, 3.0, len(mesh.tets))
        best = min(_timed(assemble.stiffness, mesh.nodes, mesh.tets, eps, order) for _ in range(3))
        line = f"P{order}: {len(mesh.tets)} tets: fruit {best:.3f} s"
        if asm is not None:
            corners = np.unique(mesh.tets[:, :4])
            renumber = np.full(len(mesh.nodes), -1)
            renumber[corners] = np.arange(len(corners))
            sk_mesh = MeshTet(mesh.nodes[corners].T.copy(), renumber[mesh.tets[:, :4]].T.copy())
            element = ElementTetP1() if order == 1 else ElementTetP2()

            @BilinearForm
            def form(u, v, w):
                return w.eps * dot(grad(u), grad(v))

            def skfem_once(sk_mesh, element, eps):
                basis = Basis(sk_mesh, element)
                return asm(form, basis, eps=np.repeat(eps[:, None], basis.X.shape[1], axis=1))

            sk = min(_timed(skfem_once, sk_mesh, element, eps) for _ in range(3))
            line += f", scikit-fem {sk:.3f} s"
        print(line)


def _timed(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


if __name__ == "__main__":
    if "--assembly" in sys.argv[1:]:
        assembly()
    elif "--frames" in sys.argv[1:]:
        from fruitcli.sensing.skin.crossing_skin import CrossingSkin

        frame_cost(CrossingSkin.load(Path(sys.argv[sys.argv.index("--frames") + 1])))
    else:
        table()
