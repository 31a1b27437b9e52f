"""A picture of the crossing cell's kinematics: the one-crossing cell of the default
Fruit at rest, bent as the paper's pad (180 deg over 48 mm, about the neutral plane
1.5 mm under the surface) and stretched by 30 %, each along the Rx yarn (x), drawn as
the mesh nodes within 0.4 mm of the plane y = 0 (a slice through the Rx yarn and across
the Tx yarn). The crossing is glued (`deform.blend`): the nodes within two yarn radii
and the insulation of its vertical axis do not move, so the yarns' distance there does
not change; the deformation ramps in over half a pitch beyond.

    python tests/performance/skin_cell_picture.py OUT.png
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fruitcli.electrostatics import crossing, deform
from fruitcli.electrostatics.cell_mesh import mesh_cell

GAPS = (0.0, 1.0)


def main(out: str) -> None:
    spec = crossing.deformation_spec(crossing.cell_spec(16.0, 12.0, 2.0, 0.6, 0.1, GAPS))
    mesh = mesh_cell(spec, 1, 600.0)
    nodes = mesh.nodes
    glue = 2 * spec.yarn_radius_mm + spec.insulation_mm
    ramp = min(spec.pitch_x_mm, spec.pitch_y_mm) / 2
    states = {
        "at rest": nodes,
        "bent along x (the paper's pad)": deform.deformed(
            nodes,
            deform.bent(nodes, "x", crossing.PAD_BEND_CURVATURE_PER_MM, crossing.NEUTRAL_MM),
            glue,
            ramp,
        ),
        "stretched 30 % along x": deform.deformed(
            nodes, deform.stretched(nodes, "x", 0.3), glue, ramp
        ),
    }
    near = (np.abs(nodes[:, 1]) < 0.4) & (nodes[:, 2] < 4.0)
    yarn = np.zeros(len(nodes), bool)
    for name in ("tx", "rx"):
        yarn[mesh.surfaces[name]] = True
    glued = deform.blend(nodes, glue, ramp) == 0
    fig, axes = plt.subplots(len(states), 1, figsize=(9, 9), sharex=True)
    for ax, (title, at) in zip(axes, states.items(), strict=True):
        sel = near & ~yarn
        ax.scatter(at[sel, 0], at[sel, 2], s=1, c="0.6", label="cell nodes")
        sel = near & glued & ~yarn
        ax.scatter(at[sel, 0], at[sel, 2], s=2, c="tab:green", label="glued (not moved)")
        for name, colour in (("rx", "tab:red"), ("tx", "tab:blue")):
            idx = np.intersect1d(mesh.surfaces[name], np.flatnonzero(near))
            ax.scatter(at[idx, 0], at[idx, 2], s=3, c=colour, label=f"{name} yarn")
        if at is nodes:
            ax.axhline(0.0, lw=0.5, c="k")  # the skin's surface
        ax.set_title(title)
        ax.set_ylabel("z (mm)")
        ax.set_aspect("equal")
    axes[0].legend(loc="upper right", fontsize=7, markerscale=4)
    axes[-1].set_xlabel("x (mm), slice at y = 0")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main(sys.argv[1])
