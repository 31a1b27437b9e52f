"""Benchmark: the reduced model of the default Fruit (pipelines/fruit-breathing.toml's
mesh, taxels and 3 chambers): build time, held-out error at 50 random pressure vectors
(taxels mm, chamber volumes %), error against degree and samples, and the time per
pressure vector (taxels alone, one vector at a time as the live loop asks; a batch;
every node).

By default the model is built on the paper's element (p1, corotational; one state in
tens of ms) so that `make bench` stays short; `--element p2` builds it on the scene's
own p2 neo-Hookean element (175 full solves of 2-7 s each: about 10-20 min on a
loaded 2-core machine). With `--reuse OUT`, a reduced model already built (OUT/reduce,
e.g. `fruit run SCENE --until reduce`, or `--keep OUT` of an earlier run) is timed
instead of building one.

Run: .venv/bin/python tests/performance/bench_reduced.py [--element p1|p2]
     [--keep OUT | --reuse OUT]
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def variant(scene, element: str):
    """The scene on `element`: p1 with the paper's corotational Hooke (nu 0.45), or the
    scene's own element and material."""
    if element == "p2":
        return scene
    return scene.with_values(
        {"fem.element": "p1", "material.model": "corotational", "material.poisson_ratio": 0.45}
    )


def _rounds(fn, rows, rounds: int = 15) -> tuple[float, float, float]:
    """(best wall, median wall, median CPU) us per call of fn(row) over `rounds` passes
    through `rows`. On a shared machine the wall time includes waiting for a core; the
    thread's CPU time (time.thread_time) is the cost itself."""
    wall, cpu = [], []
    for _ in range(rounds):
        t0, c0 = time.perf_counter(), time.thread_time()
        for row in rows:
            fn(row)
        wall.append((time.perf_counter() - t0) / len(rows) * 1e6)
        cpu.append((time.thread_time() - c0) / len(rows) * 1e6)
    return min(wall), float(np.median(wall)), float(np.median(cpu))


def time_per_vector(model, n: int = 200) -> dict:
    """(best, median) us per pressure vector: taxels one at a time, taxels in one batch
    of 2000 (per vector), every node one at a time, the live loop's ReducedOnline.update."""
    from fruitcli.fem.online import ReducedOnline

    rng = np.random.default_rng(3)
    p = model.lo + rng.random((n, len(model.lo))) * (model.hi - model.lo)
    big = model.lo + rng.random((2000, len(model.lo))) * (model.hi - model.lo)
    model.taxels(p[0])  # warm
    live = ReducedOnline(model)
    return {
        "taxels_one_us": _rounds(model.taxels, p),
        "taxels_batch_us": tuple(v / 2000 for v in _rounds(model.taxels, [big], 15)),
        "nodes_one_us": _rounds(model.nodes, p[:20], 5),
        "live_update_us": _rounds(live.update, p),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--element", choices=["p1", "p2"], default="p1")
    ap.add_argument("--reuse", type=Path, default=None)
    ap.add_argument(
        "--keep",
        type=Path,
        default=None,
        help="build into this folder (kept, for --reuse) instead of a temporary one",
    )
    args = ap.parse_args()
    from fruitcli.fem.reduced import model as reduced
    from fruitcli.scene import load_scene
    from fruitcli.workflow import planner
    from fruitcli.workflow.reduced_model import ensure_reduced

    print(f"load average {os.getloadavg()[0]:.1f} (2 cores)")
    if args.reuse is not None:
        model = reduced.load(args.reuse / "reduce" / "reduced.npz")
        print(f"reduced model of {args.reuse} (as built):")
    else:
        scene = variant(
            load_scene(ROOT / "pipelines" / "fruit-breathing.toml", must_exist=False), args.element
        )
        with tempfile.TemporaryDirectory() as tmp:
            out = args.keep or Path(tmp) / "out"
            t0 = time.perf_counter()
            planner.run(scene, out, until="tetra")
            print(f"default Fruit meshed in {time.perf_counter() - t0:.1f} s")
            model = ensure_reduced(scene, out)
        print(f"reduced model of the default Fruit on {args.element}:")
    a, v = model.arrays, model.validation()
    solve_ms = a["solve_ms"]
    print(
        f"  build {v['build_s']:.1f} s: {v['full_solves']} full solves "
        f"({np.median(solve_ms[1:]):.0f} ms median, first from rest {solve_ms[0]:.0f} ms), "
        f"fit {float(a['fit_s']):.2f} s; {a['coef_taxels'].shape[1] // 3} taxels, "
        f"{len(model.rest_nodes)} nodes, {len(model.modes)} POD modes"
    )
    box = ", ".join(
        f"{n} {lo:g}..{hi:g}"
        for n, lo, hi in zip(model.chamber_names, model.lo, model.hi, strict=True)
    )
    print(
        f"  range {box} kPa; degree {v['degree']} (leave-one-out taxel max by degree: "
        + ", ".join(
            f"{int(d)}: {e:.3g} mm"
            for d, e in zip(a["loo_degrees"], a["loo_taxel_max_mm"], strict=True)
        )
        + ")"
    )
    print(
        f"  held-out at {v['vectors']} random pressure vectors: taxels max "
        f"{v['taxel_max_mm']:.2g} mm, median {v['taxel_median_mm']:.2g} mm (bound "
        f"{reduced.TAXEL_BOUND_MM} mm); volumes max {v['volume_max_pct']:.2g} %, median "
        f"{v['volume_median_pct']:.2g} % (bound {reduced.VOLUME_BOUND_PCT} %); surface "
        f"nodes max {v['surface_max_mm']:.2g} mm; "
        + ("within the bound" if v["within_bound"] else "OUTSIDE THE BOUND")
    )
    print("  held-out error against samples and degree:")
    print(
        f"  {'per axis':>8} {'samples':>7} {'degree':>6} {'taxel max mm':>12} {'volume max %':>12}"
    )
    for m, d, s, e, ve in a["study"]:
        print(f"  {m:8.0f} {s:7.0f} {d:6.0f} {e:12.2g} {ve:12.2g}")
    t = time_per_vector(model)
    print(
        f"  load average {os.getloadavg()[0]:.1f}; per pressure vector, wall best / wall "
        "median / CPU median of 15 passes (us):"
    )
    for key, label in (
        ("taxels_one_us", "taxels, one vector at a time (bound 100 us)"),
        ("taxels_batch_us", "taxels, in a batch of 2000"),
        ("live_update_us", "fruit live's ReducedOnline.update"),
        ("nodes_one_us", "every node, one vector"),
    ):
        print(f"    {label}: " + " / ".join(f"{v:.1f}" for v in t[key]))


if __name__ == "__main__":
    main()
