"""The solver: the equilibrium of one state through load steps (`state`), Newton
iterations on one load step (`newton`), the start of a state from the ones before
(`predictor`), moved [[fixed]] regions (`prescribed`), the options and result of a state
(`options`), linear solves with the tangents (`linsolve` for the corotational model,
`continuum_linsolve` for the hyperelastic one), the kept factor through MKL PARDISO
(`pardiso`) and sparse assembly with a fixed pattern (`assemble`).

May import: `fruitcli.fem` top modules, `fruitcli.fem.materials` (the corotational
tangent's compiled products, which `linsolve` applies matrix-free), `fruitcli.errors`.
"""
