"""Touches from frames (paper Sec. III-B, eq. 7): baseline, threshold, N9 centroid,
multitouch, two footprints fitted to fingers close together (`two_footprints`, the fit2
method), 3D location, baseline drift, touch sessions, taxel health. The methods are one
table (`methods`; the grid methods' functions in `finders`).

May import: `fruitcli.sensing.frames`, `fruitcli.sensing.shape` (each touch's strength,
size and hover height), `fruitcli.sensing.skin.forward` (taxel gains),
`fruitcli.sensing.skin.heights` (the height law), and `fruitcli.errors`,
`fruitcli.fsutil`, `fruitcli.tables`.
"""
