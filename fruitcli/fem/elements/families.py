"""The element families, one table (``[fem].element``).

The scene schema's choices read `ELEMENT_FAMILIES`; `lagrange.ELEMENTS` adds the
quadrature rules to each entry. This module imports nothing, so the scene schema can
read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ElementFamily:
    """An element family: `order` 1 (linear) or 2 (quadratic) Lagrange tets with
    `nodes_per_tet` nodes, surface triangles of `nodes_per_tri`, the exact quadrature
    degrees for stiffness (`volume_degree`) and cavity volumes (`surface_degree`), and
    whether the volume change is constant per element (`mean_dilatation`, P2/P0)."""

    name: str
    order: int
    nodes_per_tet: int
    nodes_per_tri: int
    volume_degree: int
    surface_degree: int
    mean_dilatation: bool
    doc: str


ELEMENT_FAMILIES: dict[str, ElementFamily] = {
    f.name: f
    for f in (
        ElementFamily(
            "p2",
            2,
            10,
            6,
            2,
            4,
            True,
            "quadratic tets (10 nodes), curved on analytic chambers, with the volume "
            "change constant per element (P2/P0 mean dilatation: no volumetric locking)",
        ),
        ElementFamily(
            "p2-pure",
            2,
            10,
            6,
            2,
            4,
            False,
            "quadratic tets, displacement only (locks as nu -> 0.5; for comparison)",
        ),
        ElementFamily(
            "p1", 1, 4, 3, 1, 2, False, "linear tets (4 nodes): the paper's SOFA element"
        ),
    )
}
