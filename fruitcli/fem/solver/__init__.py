"""The solver: Newton iterations on one state (`newton`), linear solves with the
tangents (`linsolve` for the corotational model, `continuum_linsolve` for the
hyperelastic one), the kept factor through MKL PARDISO (`pardiso`) and sparse assembly
with a fixed pattern (`assemble`).

May import: `fruitcli.fem` top modules, `fruitcli.fem.materials` (the corotational
tangent's compiled products, which `linsolve` applies matrix-free), `fruitcli.errors`.
"""
