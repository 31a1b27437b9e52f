"""The printer bench: a Marlin 3D printer carrying an indenter over the skin while a MuCa
board records (the paper's protocol, Sec. V-B, on real hardware), and an emulated printer.

May import: `fruitcli.sensing`, `fruitcli.geometry.body_surface` (where the indenter
meets the body), `fruitcli.scene` (the [printer] and [board] records its inputs hold),
`fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
