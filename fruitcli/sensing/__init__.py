"""Sensing: from raw CDC frames to touches in 3D, and the skin model behind the virtual bench.

Sub-packages, by concept (each states what it may import in its own docstring):

- `frames`: the board (21 x 12 cells, taxel <-> cell), its stock firmware's formats and
  recordings of frames (`.npz`, MuCa ASCII logs), read whole or chunk by chunk.
- `detection`: baseline, threshold, N9 centroid, multitouch (paper Sec. III-B), two
  footprints fitted to separate fingers close together, 3D location (eq. 7), baseline
  drift, touch sessions, taxel health, gain division.
- `shape`: a touch's strength, size and hover height.
- `skin`: the skin's forward model, the virtual 3D-printer bench, its calibration,
  sensitivity analysis and heat maps.
- `outputs`: where touches go: touches CSV, TUIO 1.1 and plain OSC, the live view.
- `live`: the live loop on a board over serial: ports, reconnecting, recording, the run
  log, an emulated board on a pseudo-terminal.

The sensing stages as file-to-file functions, one module each: `locate_stage`,
`bench_stage`, `sensitivity_stage` (`stages` offers all three); `inputs_stage` turns the
scene into their typed inputs; `locator_setup` builds what locating a recording needs
(the locator, the surface projector, the skin's heights) from those inputs;
`touch_width` finds the skin's footprint width from a recording's touches alone.
May import: the sub-packages above, `fruitcli.geometry`, `fruitcli.fem`,
`fruitcli.electrostatics`, `fruitcli.scene`; never `fruitcli.workflow` or `fruitcli.cli`.
"""
