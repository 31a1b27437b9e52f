"""fruit: model-based capacitive touch sensing on soft robots.

Packages, each with its own docstring: `geometry` (meshes, make-tracks), `fabrication`
(molds, yarn), `fem` (tetrahedral meshes and the quasi-static mechanics), `sensing`
(frames to touches in 3D, the skin model), `printer` (the printer bench), `evaluation`
(error tables against ground truth), `studies` (runtime, stability and bench studies,
sweeps), `workflow` (the planner and its stages), `cli` (one module per command).
Shared by all: `errors`, `fsutil` (atomic writes), `tables` (CSV, npz, taxels), `scene`.

Imports run one way: `cli` uses `workflow`, which uses the packages of each stage;
`tests/test_imports.py` checks the rules each package's docstring states.
"""
