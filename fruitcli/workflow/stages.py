"""The pipeline's stages, in dependency order, as the planner sees them.

Each entry says when a scene needs the stage (and why not, when it does not), which
library function does the work, and which scene keys it reads: `reads` (whole sections
or `section.key`, hashed with the content of every file a path key names), `minus`
(keys of a read section it does not read), `decides` (keys only `needed` reads) and
`derived` (keys hashed through a value its `inputs` derives). `inputs` adds only what
is not a scene key; upstream outputs are covered by the hashes of `deps`.
tests/workflow/test_stage_hashes.py records what each stage reads on small scenes and
fails on a read its declaration lacks. The heavy modules are imported only when a stage
runs.

The entries live with their stages, by concept: `geometry_stages` (make-artist,
make-tracks, pad-grid), `fem_stages` (tetra, limits, simulate, reduce) and
`sensing_stages` (skin, bench, locate, evaluate, sensitivity); where a stage finds its
inputs (and the key groups several stages read) is `stage_paths`.
"""

from __future__ import annotations

from fruitcli.workflow.fem_stages import LIMITS_STAGE, REDUCE_STAGE, SIMULATE_STAGE, TETRA_STAGE
from fruitcli.workflow.geometry_stages import MAKE_ARTIST_STAGE, MAKE_TRACKS_STAGE, PAD_GRID_STAGE
from fruitcli.workflow.sensing_stages import (
    BENCH_STAGE,
    EVALUATE_STAGE,
    LOCATE_STAGE,
    SENSITIVITY_STAGE,
    SKIN_STAGE,
)
from fruitcli.workflow.stage_types import Stage

STAGES: list[Stage] = [
    MAKE_ARTIST_STAGE,
    MAKE_TRACKS_STAGE,
    PAD_GRID_STAGE,
    TETRA_STAGE,
    LIMITS_STAGE,
    SIMULATE_STAGE,
    REDUCE_STAGE,
    SKIN_STAGE,
    BENCH_STAGE,
    LOCATE_STAGE,
    EVALUATE_STAGE,
    SENSITIVITY_STAGE,
]
