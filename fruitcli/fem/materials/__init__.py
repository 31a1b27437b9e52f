"""Materials: the paper's corotational Hooke model on linear tets (`corotation`, its
compiled loops in `corotation_kernels`), hyperelastic strain energies with stress and
tangent per quadrature point (`hyperelastic`), and the scene's [material] (`build`).

May import: `fruitcli.fem` top modules, `fruitcli.errors`.
"""
