"""fruit: model-based capacitive touch sensing on soft robots.

Packages, each with its own docstring: `geometry` (meshes, make-tracks), `fabrication`
(molds, yarn), `fem` (tetrahedral meshes and the quasi-static mechanics), `sensing`
(frames to touches in 3D, the skin model), `printer` (the printer bench), `evaluation`
(error tables against ground truth), `studies` (runtime, stability and bench studies,
sweeps), `workflow` (the planner and its stages), `cli` (one module per command).

Shared by all: `fruitcli.errors`, `fruitcli.fsutil` (atomic writes), `fruitcli.tables`
(CSV, npz, taxels), `fruitcli.interrupts` (Ctrl-C), `fruitcli.memory` (memory estimates),
`fruitcli.time_left` (a long loop's time left), `fruitcli.compile_notice` (numba's first
compile announced); they import only one another, and every module may import them.

Tables of choices, one per variation point, each importing nothing of `fruitcli`, so that
the scene schema (`scene`) and every module may read them:
`fruitcli.sensing.detection.methods`, `fruitcli.sensing.skin.models`,
`fruitcli.sensing.frames.formats`, `fruitcli.fem.materials.models`,
`fruitcli.fem.elements.families`, `fruitcli.fem.solver.solvers`,
`fruitcli.evaluation.registrations`, `fruitcli.geometry.mesh.units`.

The scene files' package `fruitcli.scene` sits at the bottom with them: it imports only
the shared modules, the tables and the two modules its docstring names.

The top modules (the shared ones, `bundled`, `bundled_files`, `output_folder`)
May import: one another, the tables of choices and `fruitcli.scene`.

The distribution's name on the package index is `DISTRIBUTION`; the import package and
its command keep theirs (`fruitcli`, `fruit`).

Imports run one way: `cli` uses `workflow`, which uses the packages of each stage;
`tests/test_imports.py` reads the "May import" rule of each package's docstring and fails
on any import outside it.
"""

DISTRIBUTION = "fruit-touch"  # pip install fruit-touch
