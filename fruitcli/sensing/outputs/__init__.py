"""Where touches go: `touches.csv` written in bulk, TUIO 1.1 cursors and plain OSC over
UDP, and the live view page.

May import: `fruitcli.sensing.detection`, `fruitcli.errors`, `fruitcli.fsutil`.
"""
