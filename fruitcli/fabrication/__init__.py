"""Fabrication: the molds that cast the pieces of the touch skin (`mold`) and the
make-mold stage (`stage`). The yarn stretch along the tracks is a simulate output
(`fruitcli.fem.yarn`).

May import: `fruitcli.geometry`, `fruitcli.fem.elements` (barycentric maps),
`fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
