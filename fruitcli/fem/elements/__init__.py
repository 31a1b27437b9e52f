"""Finite elements: Lagrange shape functions and quadrature (`lagrange`), and the
quadratic mesh built from a linear one (`quadratic`). An element is a `Family`: nodes
per tet, the surface triangle it induces and their quadrature rules."""

from fruitcli.fem.elements.lagrange import ELEMENTS, Family, family

__all__ = ["ELEMENTS", "Family", "family"]
