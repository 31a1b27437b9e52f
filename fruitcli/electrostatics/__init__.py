"""Electrostatics on tetrahedra: the field of the skin's yarn crossings (mm, fF).

- `assemble`: the stiffness of div(eps grad phi) = 0 on linear and quadratic tets;
- `capacitance`: potentials with Dirichlet conductors, charges, energies, capacitances;
- `closed_forms`: the capacitances the solver is checked against;
- `occ_mesh`: tetrahedral meshes of gmsh OpenCASCADE models with named regions.
"""
