"""The skin model: raw counts of every taxel for an indenter and a FEM state (forward
model), the virtual 3D-printer bench built on it, its calibration from a bench recording,
sensitivity analysis and per-taxel heat maps.

May import: `fruitcli.sensing.frames`, `fruitcli.fem`, `fruitcli.geometry`,
`fruitcli.electrostatics` (the computed crossing of the electrostatic skin),
`fruitcli.scene` (the [skin] defaults and skin tables), and `fruitcli.errors`,
`fruitcli.fsutil`, `fruitcli.tables`.
"""
