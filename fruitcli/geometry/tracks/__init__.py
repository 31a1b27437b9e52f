"""make-tracks (paper Sec. III-D, Fig. 6): the reduced body (`reduce`), plane sections
(`sections`), yarn tubes (`tubes`), taxels at the crossings (`taxels`), the preview
picture (`preview`) and the whole stage (`make_tracks`).

May import: `fruitcli.geometry.mesh`, `fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
