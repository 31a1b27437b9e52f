"""make-tracks (paper Sec. III-D, Fig. 6): the reduced body (`reduce`, once `densify` has
split the artist surface's long edges), plane sections (`sections`) and the track curves
on the grid (`curves`), yarn tubes (`tubes`) carved from the casting piece (`carve`),
taxels at the crossings (`taxels`), the preview picture (`preview`), the run's files and
warnings (`outputs`) and the whole stage (`make_tracks`).

May import: `fruitcli.geometry.mesh`, `fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
