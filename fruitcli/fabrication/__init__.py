"""Fabrication: the molds that cast the pieces of the touch skin (`mold`), the yarn
lengths and stretch along the tracks (`yarn`), and the make-mold stage (`stage`).

May import: `fruitcli.geometry`, `fruitcli.fem.elements` (barycentric maps),
`fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
