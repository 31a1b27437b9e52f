"""The Fruit's breathing with the crossing glued (the paper's design, the default) and
not glued (every node of the one-crossing cell moves with the silicone, the yarns too).

Units: counts, fF. For each: the crossing's shift stretched 10 % and bent as the paper's
pad along x and y, the counts per fF fitted so the larger bend gives 10 counts (as
`fruit skin` does), and each taxel's largest |shift| over the breathing states of
``pipelines/fruit-breathing.toml`` (max, mean). Reads the electrostatic breathing run of
`compare_skins.py` in OUT (run that first).

    python tests/performance/skin_glue_check.py --out OUT
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # tests.performance


def main(argv=None) -> None:
    from fruitcli.electrostatics import crossing
    from fruitcli.electrostatics.cell_mesh import mesh_cell
    from fruitcli.electrostatics.design import cell_spec, crossing_inputs
    from fruitcli.scene import load_scene
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin
    from fruitcli.studies.machine import machine_line
    from tests.performance.compare_skins import breathing_shifts

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    root = args.out.resolve() / "fruit-breathing-electrostatic"
    inputs = crossing_inputs(load_scene(root.parent / f"{root.name}.toml"))
    spec = cell_spec(inputs)
    small = crossing.deformation_spec(spec)
    solver = crossing.CellSolver(mesh_cell(small, 1, inputs.time_limit_s), inputs.permittivity)
    c0_def = solver.capacitance()
    with np.load(root / "skin" / "crossing.npz") as data:
        arrays = {k: data[k] for k in data.files}
    summary = json.loads((root / "skin" / "summary.json").read_text())
    print(machine_line())
    print(
        "| crossing | 10 % stretch x / y (fF) | pad's bend x / y (fF) | counts per fF | "
        "breathing max / mean (counts) |"
    )
    print("|---|---|---|---|---|")
    for label, glued in (("glued (default)", True), ("not glued", False)):
        strains, c_s, curvs, c_b = crossing.deformation_table(solver, small, c0_def, glued)
        at = list(strains).index(0.1)
        d_s, d_b = c_s - c0_def, c_b - c0_def
        cpf = 10.0 / np.abs(d_b[:, -1]).max()
        table = {**arrays, "c_stretch_ff": c_s - c0_def + arrays["c0_ff"]}
        table["c_bend_ff"] = c_b - c0_def + arrays["c0_ff"]
        response = CrossingSkin.from_table(table, summary, cpf)
        b = breathing_shifts(root, "electrostatic", response)
        print(
            f"| {label} | {d_s[0, at]:+.2f} / {d_s[1, at]:+.2f} | {d_b[0, -1]:+.2f} / "
            f"{d_b[1, -1]:+.2f} | {cpf:.3f} | {b['max']:.1f} / {b['mean']:.2f} |"
        )


if __name__ == "__main__":
    main()
