"""A touch's shape beyond its position: strength, size and hover height from the
activation around its peak (`touch_shape`, compiled in `shape_kernel`).

May import: `fruitcli.sensing.skin` (the height law), `fruitcli.errors`.
"""
