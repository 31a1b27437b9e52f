"""Touches from frames (paper Sec. III-B, eq. 7): baseline, threshold, N9 centroid,
multitouch, 3D location, baseline drift, touch sessions, taxel health.

May import: `fruitcli.sensing.frames`, `fruitcli.sensing.skin.forward` (taxel gains), and
`fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
