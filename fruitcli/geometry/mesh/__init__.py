"""Triangle-mesh tools: loading (`load`), writing (`export`), inside and outside
(`winding`, `solid_angle`), exact distances (`distance`) and vertical rays (`columns`).

May import: `fruitcli.errors`, `fruitcli.fsutil`.
"""
