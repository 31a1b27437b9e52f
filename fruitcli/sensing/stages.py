"""The sensing stages as file-to-file functions, one module each: `locate_stage`
(`run_locate`), `bench_stage` (`run_bench`) and `sensitivity_stage` (`run_sensitivity`);
what a locator is built from is `locator_setup`, and what the stages read of the scene
`inputs_stage` (`locate_inputs` and the files `LocateFiles` make `run_locate`'s
arguments). The workflow's stage table names this module.

Units: mm, counts, kPa, s. Each stage reads its inputs, calls the pure functions of
`fruitcli.sensing`, and writes its outputs atomically into `out_dir`.
"""

from __future__ import annotations

from fruitcli.sensing.bench_stage import run_bench
from fruitcli.sensing.inputs_stage import LocateFiles, LocateInputs, locate_inputs
from fruitcli.sensing.locate_stage import run_locate
from fruitcli.sensing.sensitivity_stage import run_sensitivity

__all__ = [
    "LocateFiles",
    "LocateInputs",
    "locate_inputs",
    "run_bench",
    "run_locate",
    "run_sensitivity",
]
