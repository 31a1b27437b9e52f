"""Touches from frames (paper Sec. III-B, eq. 7): baseline, threshold, N9 centroid,
multitouch, two footprints fitted to fingers close together (`two_footprints`, the fit2
method), the skin's footprint fitted around each peak (`model_fit`, the model method, on
the body's own surface where it is known: `surface_chart`), 3D location
(`frames_to_touches`: the batch path; `stream`: frame by frame; both write a
`touch_table`), baseline drift, touch sessions, taxel health. The methods are one table
(`methods`; the grid methods' functions in `finders`), read through the
[detection] settings (`settings`).

May import: `fruitcli.sensing.frames`, `fruitcli.sensing.shape` (each touch's strength,
size and hover height), `fruitcli.sensing.skin.forward` (taxel gains),
`fruitcli.sensing.skin.heights` (the height law), `fruitcli.scene` (the [detection]
defaults), and `fruitcli.errors`,
`fruitcli.fsutil`, `fruitcli.tables`.
"""
