"""The reduced model as the commands use it: built on demand through the planner (into
OUT/reduce, reused while the mesh, material, taxels and range are unchanged), then
evaluated at pressure vectors (kPa) instead of solving the FEM."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from click._termui_impl import ProgressBar

    from fruitcli.fem.reduced.model import ReducedModel
    from fruitcli.scene import Scene


def ensure_reduced(
    scene: Scene,
    out_root: Path,
    taxels_csv: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
    label: str | None = None,
    bar: Callable[[int], ProgressBar[Any]] | None = None,
) -> ReducedModel:
    """The scene's ReducedModel, from OUT/reduce (built there first when missing or
    stale). `taxels_csv` replaces the scene's [grid].taxels. A scene without one (not
    meshed, no chambers) is one FruitError line starting with `label`. `bar(total)`, when
    given, makes a progress bar (a context manager with `update(n)`) for the build's
    full solves; without it they are progress lines too."""
    from fruitcli.errors import FruitError
    from fruitcli.fem.reduced import model as reduced
    from fruitcli.workflow import planner
    from fruitcli.workflow.fem_stages import wanting_reduced
    from fruitcli.workflow.scene_outputs import shared_outputs
    from fruitcli.workflow.stage_paths import reduced_path

    sc = wanting_reduced(scene)
    if taxels_csv is not None:
        sc = sc.with_values({"grid.taxels": Path(taxels_csv)})
    log = progress or (lambda msg: None)
    shown = None  # the open bar of the build's full solves

    def route(msg: str) -> None:  # the build's full solves on a bar, the rest as lines
        nonlocal shown
        if bar is not None and msg.startswith("state ") and "/" in msg.split(":")[0]:
            if shown is None:
                shown = bar(int(msg.split(":")[0].split("/")[1]))
                shown.__enter__()
            shown.update(1)
            return
        if shown is not None:
            shown.__exit__(None, None, None)
            shown = None
        log(msg)

    try:
        steps = planner.run(
            sc, out_root, until="reduce", progress=route, shared=shared_outputs(out_root)
        )
    finally:
        if shown is not None:
            shown.__exit__(None, None, None)
    skipped = {st.stage: st.reason for st in steps if st.action == "not needed"}
    if "reduce" in skipped:
        label = label or scene.path.name
        what = "not meshed" if "tetra" in skipped else "without a reduced model"
        raise FruitError(f"{label}: the scene is {what} ({skipped['reduce']})")
    return reduced.load(reduced_path(sc, planner.Context(Path(out_root))))


def actuation_table(scene: Scene, names: list[str]) -> np.ndarray:
    """(S, K) kPa of the scene's [actuation] states in `names` order."""
    from fruitcli.errors import SceneError
    from fruitcli.scene import n_states

    act = scene.actuation
    if act.volume_growth_mm3:
        raise SceneError(
            "[actuation].volume_growth_mm3: the reduced model maps pressures; "
            "use --model full or --pressures"
        )
    table = act.pressure_kpa or {}
    return np.stack(
        [np.asarray(table.get(n, [0.0] * n_states(scene)), float) for n in names], axis=1
    )


def simulate_reduced(
    scene: Scene,
    out_dir: Path,
    taxels_csv: str | Path | None,
    table: np.ndarray | None,
    rows: np.ndarray | None,
    pressures_csv: str | Path | None,
    progress: Callable[[str], None],
    vtu: bool = False,
    bar: Callable[[int], ProgressBar[Any]] | None = None,
) -> dict:
    """`fruit simulate --model reduced`: states.npz at the rows of `table` (S, K) kPa
    (in the scene's chamber order; default its [actuation] states). Rows outside the
    model's range are one error naming the first (file line `rows`)."""
    from fruitcli.fem import io
    from fruitcli.fem.reduced.model import states_arrays
    from fruitcli.fsutil import staged_dir

    model = ensure_reduced(scene, out_dir, taxels_csv, progress, bar=bar)
    names = [c.name for c in scene.chambers]
    where = str(pressures_csv) if pressures_csv is not None else f"{scene.path.name}: [actuation]"
    if table is None:
        table, rows = actuation_table(scene, names), None
    order = [names.index(n) for n in model.chamber_names]
    kpa = table[:, order]
    model.check_range(kpa, where, rows)
    from fruitcli.memory import require

    # displacements (S, N, 3) float64, built and then written (twice)
    require(
        2 * 8 * 3 * len(kpa) * len(model.rest_nodes),
        f"{where}: {len(kpa)} states of {len(model.rest_nodes)} nodes",
    )
    arrays = states_arrays(model, kpa)
    with staged_dir(out_dir) as tmp:
        io.save_npz(tmp / "states.npz", arrays)
        if vtu:
            for i, u in enumerate(arrays["displacement_mm"]):
                io.write_vtu(
                    tmp / f"state_{i:03d}.vtu",
                    model.rest_nodes + u,
                    arrays["elements"],
                    {"displacement_mm": u},
                )
    return {
        "states": len(kpa),
        "us_per_state": 1e3 * float(np.median(arrays["solve_ms"])),
        "describe": model.describe(),
    }
