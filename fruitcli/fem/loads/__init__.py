"""Loads on the body: chamber pressure on linear cavity walls (`pressure`, the paper's
model) and on curved 3- or 6-node walls (`cavity`), and jig springs (`springs`).
Gravity and prescribed clamps are assembled by the models (`fruitcli.fem.corotational_model`).

May import: `fruitcli.fem.elements`.
"""
