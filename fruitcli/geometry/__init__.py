"""Geometry: the shapes of the skin, in mm.

- `mesh`: triangle-mesh tools: reading an artist's mesh as it is, writing meshes that
  survive an STL round trip, inside and outside (winding numbers, solid angles), exact
  point-to-surface distances and vertical rays.
- `tracks`: make-tracks (paper Sec. III-D, Fig. 6): the reduced body, its plane
  sections, the yarn tubes carved along them, the taxels at their crossings, previews.
- `artist` (the default 'Fruit'), `padgrid` (a flat pad's taxels and grid lines), `body_surface`
  (where points meet the body's surface, at rest or carried by a FEM state), `state_mesh`
  (what the body's surface and the skin read of a FEM state).

May import: `fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`, and
`fruitcli.fem.elements` (barycentric maps); never `fruitcli.sensing`.
"""
