"""Finite elements: Lagrange shape functions and quadrature (`lagrange`), the linear
tet's geometry and Hooke stiffness (`tet4`), the quadratic mesh built from a linear one
(`quadratic`), the compiled element loops for any element and material (`integrate`),
and points (taxels) located in the mesh (`barycentric`). An element is a `lagrange.Family`:
nodes per tet, the surface triangle it induces and their quadrature rules; the families'
names and sizes are the table `families`, which the scene schema reads (so this package
imports none of its modules when loaded).

May import: `fruitcli.fem.materials` (the material kernels the element loops call),
`fruitcli.fem` top modules, `fruitcli.errors`.
"""
