"""The live loop on a MuCa board: serial ports, reconnecting, recording, the run log, and
a board emulated on a pseudo-terminal.

May import: `fruitcli.sensing.frames`, `fruitcli.sensing.detection`,
`fruitcli.sensing.outputs`, `fruitcli.errors`, `fruitcli.fsutil`.
"""
