"""Electrostatics on tetrahedra: the field of the skin's yarn crossings (mm, fF).

- `assemble`: the stiffness of div(eps grad phi) = 0 on linear and quadratic tets;
- `capacitance`: potentials with Dirichlet conductors, charges, energies, capacitances;
- `closed_forms`: the capacitances the solver is checked against;
- `occ_mesh`: tetrahedral meshes of gmsh OpenCASCADE models with named regions;
- `cell_geometry`, `cell_mesh`: the crossing cell's model, meshed in a killable child;
- `touch_objects`: the grounded indenters and finger;
- `deform`: the cell stretched along a yarn or bent;
- `crossing`: C0, the dC table and C_delta of one crossing;
- `equivalents`: footprint sigma, gap decay and counts derived from the table;
- `design`: a scene's crossing inputs (checked) and `fruit skin`'s outputs.

May import: `fruitcli.fem` (the PARDISO factor), `fruitcli.sensing.skin.forward` (the
assumed model, for comparison), `fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.scene`.
"""
