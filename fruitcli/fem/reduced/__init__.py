"""The reduced model for live use: chamber pressures (kPa) -> taxel and node positions (mm)
by polynomial response surfaces (`response_surface`) fitted to full solves (`build`), and
the model itself (`model`).

May import: `fruitcli.fem.solver`, `fruitcli.fem.elements` (the taxels located in the
mesh), `fruitcli.fem` top modules, `fruitcli.errors`,
`fruitcli.fsutil`, `fruitcli.scene`.
"""
