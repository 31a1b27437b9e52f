"""Meshing: the closed shells that bound the body (`shells`), gmsh in a killable child
process (`tetra`, `gmsh_job`, split into patches by `patches`), structured box meshes
(`grid`), boundary topology (`topology`) and tet quality (`quality`).

May import: `fruitcli.fem` top modules, `fruitcli.geometry.mesh` (reading a solid's and a
chamber's surface, as `fruitcli.fem` may), `fruitcli.errors`, `fruitcli.fsutil`,
`fruitcli.interrupts`.
"""
