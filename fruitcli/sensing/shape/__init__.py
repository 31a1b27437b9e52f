"""A touch's shape beyond its position: strength, size and hover height from the
activation around its peak (`touch_shape`, compiled in `shape_kernel`), and two
footprints of the calibrated skin fitted around a peak to separate fingers close
together (`two_footprints`, ``[detection] method = "fit2"``).

May import: `fruitcli.sensing.detection.detect` (the grid and N9 layout),
`fruitcli.sensing.skin` (the height law), `fruitcli.errors`.
"""
