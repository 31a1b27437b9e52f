"""The mechanics (paper Sec. IV): tetrahedral meshes (`meshing`), elements, materials,
loads and the Newton solver; the corotational model of the paper (`corotational_model`)
and the hyperelastic one (`continuum`); the reduced model for live use (`reduced`), the
online solver (`online`), file formats (`io`), the yarns' stretch along the tracks through
the states (`yarn`) and the tetra and simulate stages (`stage`).
Units: mm, kPa, N (`units`).

May import: `fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`, `fruitcli.scene`,
`fruitcli.geometry.mesh` (reading a solid);
never `fruitcli.sensing` or `fruitcli.geometry.tracks`.
"""
