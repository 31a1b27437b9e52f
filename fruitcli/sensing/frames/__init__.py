"""Raw CDC frames: the board's geometry, its stock firmware's formats and recordings.

May import: `fruitcli.scene` (the [board] record), `fruitcli.errors`, `fruitcli.fsutil`,
`fruitcli.tables`.
"""
