"""The crossing cell stretched along a yarn or bent, by moving its mesh nodes.

Units: mm. The crossing is glued (Sec. III-C of the paper: the insulating layer there
does not change), so the deformation is blended in with the lateral distance rho from
the crossing: none within `glue_mm`, all of it beyond `glue_mm + ramp_mm` (a smoothstep
between). Moving the nodes of one mesh, instead of meshing the deformed cell anew, keeps
the discretization of the crossing, so C_delta - C0 is not buried in remeshing noise.

- Stretch by strain s along x or y: the deformation gradient of an incompressible
  uniaxial stretch, lambda = 1 + s along the axis, lambda^-1/2 across it and in depth
  (the silicone and the cover thin).
- Bend to curvature kappa along x or y: the cell wraps a cylinder whose axis lies across
  the bend, the neutral plane `neutral_mm` under the surface keeping its length, so the
  surface stretches by neutral_mm * kappa (outer side up).
"""

from __future__ import annotations

import numpy as np

AXES = {"x": 0, "y": 1}


def blend(nodes: np.ndarray, glue_mm: float, ramp_mm: float) -> np.ndarray:
    """(N,) weight 0 within `glue_mm` of the crossing's vertical axis, 1 beyond
    glue_mm + ramp_mm, a smoothstep between."""
    t = np.clip((np.hypot(nodes[:, 0], nodes[:, 1]) - glue_mm) / ramp_mm, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def stretched(nodes: np.ndarray, axis: str, strain: float) -> np.ndarray:
    """Nodes (N, 3) under the incompressible uniaxial stretch 1 + strain along `axis`."""
    lam = 1.0 + strain
    scale = np.full(3, lam**-0.5)
    scale[AXES[axis]] = lam
    return nodes * scale


def bent(nodes: np.ndarray, axis: str, curvature_per_mm: float, neutral_mm: float) -> np.ndarray:
    """Nodes (N, 3) bent along `axis` to `curvature_per_mm` about a neutral plane
    `neutral_mm` under the surface z = 0 (the surface on the outside)."""
    out = nodes.copy()
    if curvature_per_mm == 0:
        return out
    radius = 1.0 / curvature_per_mm
    a = AXES[axis]
    r = radius + nodes[:, 2] + neutral_mm
    theta = nodes[:, a] / radius
    out[:, a] = r * np.sin(theta)
    out[:, 2] = r * np.cos(theta) - radius - neutral_mm
    return out


def deformed(nodes: np.ndarray, target: np.ndarray, glue_mm: float, ramp_mm: float) -> np.ndarray:
    """Nodes moved towards `target` (N, 3) by the glue blend."""
    return nodes + blend(nodes, glue_mm, ramp_mm)[:, None] * (target - nodes)
