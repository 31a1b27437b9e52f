"""The skins the locate study hands its locators, each fitted to another run of the
bench's board than the run it scores (`fruitcli.studies.locate_methods`, the demo's
model rows): `calibrated_skin`, `fruit calibrate`'s law and gains from a run with ground
truth, and `touch_width_skin`, the footprint's width from another run's touches alone.

Units: mm.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from fruitcli.scene import Scene

CALIBRATION_INDENTER = "small"


@dataclass(frozen=True)
class BenchBody:
    """What a bench run stands on: the taxels (CSV), the FEM states (npz; None: at rest)
    and the body's closed surface (None: not known) in `unit`."""

    taxels: Path
    states: Path | None
    surface: Path | None
    unit: str = "mm"

    def taxels_mm(self, state: int) -> np.ndarray:
        """The taxels' positions (T, 3) mm at FEM state `state` (at rest without states)."""
        from fruitcli.sensing.detection.locate import load_states
        from fruitcli.tables import read_taxels

        if self.states is None:
            return read_taxels(self.taxels).xyz_mm
        return load_states(self.states).taxels_mm[state]


def calibration_run(
    bench_scene: Scene,
    body: BenchBody,
    work: Path,
    board_table: Path | None = None,
    indenters: Iterable[str] = (),
) -> list[str]:
    """The board of `bench_scene` (its crossing table `board_table` when electrostatic)
    run on the bench on `body` at other sample points than the scene's (half a pitch off each
    taxel, and right over each taxel) into WORK/bench, with ``CALIBRATION_INDENTER``
    and each of `indenters`. -> the indenters run, in that order."""
    from fruitcli.fsutil import write_csv
    from fruitcli.sensing.stages import run_bench
    from fruitcli.tables import read_taxels

    work.mkdir(parents=True, exist_ok=True)
    g = bench_scene.grid
    over = read_taxels(body.taxels).xyz_mm[:, :2]
    xy = np.vstack([over + np.array([g.spacing_x_mm, g.spacing_y_mm]) / 2, over])
    points = work / "samples.csv"
    write_csv(points, ["sample", "x_mm", "y_mm"], ([k, *p] for k, p in enumerate(xy)))
    # the two [bench] keys replaced as they are, without `with_values`' checks across
    # keys: those read every section, and the demo's stage declares only what it reads
    names = [
        CALIBRATION_INDENTER,
        *(i for i in dict.fromkeys(indenters) if i != CALIBRATION_INDENTER),
    ]
    bench = replace(bench_scene.bench, samples=str(points.resolve()), indenters=names)
    run = replace(bench_scene, sections={**bench_scene.sections, "bench": bench})
    run_bench(
        run,
        body.taxels,
        body.states,
        work / "bench",
        surface_path=body.surface,
        surface_unit=body.unit,
        crossing_dir=board_table,
    )
    return names


def calibrated_skin(
    bench_scene: Scene,
    body: BenchBody,
    work: Path,
    board_table: Path | None = None,
    fitted_table: Path | None = None,
    indenters: Iterable[str] = (),
) -> Any:
    """`fruit calibrate`'s [skin] table fitted to a run of the board of `bench_scene`
    (its crossing table `board_table` when electrostatic) at other sample points (half a
    pitch off each taxel, for the law, and right over each taxel, for its gain:
    `taxel_gains`; ``CALIBRATION_INDENTER``): the Gaussian law, or with `fitted_table` the
    crossing table's counts per fF, and the gains. Each of `indenters` is calibrated on
    the same run too (WORK/skin-NAME), and its footprint width joins the table's, as a
    user calibrates each object the skin will see; the rest is ``CALIBRATION_INDENTER``'s."""
    from fruitcli.scene import load_skin_table
    from fruitcli.sensing.inputs_stage import calibrate_inputs, crossing_skin_inputs
    from fruitcli.sensing.locator_setup import electrostatic_skin
    from fruitcli.sensing.skin.calibrate import run_calibrate

    names = calibration_run(bench_scene, body, work, board_table, indenters)
    fitter = bench_scene
    response = None
    if fitted_table is not None:
        fitter = bench_scene.with_values({"skin.model": "electrostatic"})
        response = electrostatic_skin(crossing_skin_inputs(fitter, fitted_table))
    feet = {}
    for name in names:
        ind = work / "bench" / name
        folder = work / ("skin" if name == CALIBRATION_INDENTER else f"skin-{name}")
        run_calibrate(
            calibrate_inputs(fitter),
            ind / "frames.npz",
            ind / "truth.csv",
            body.taxels,
            folder,
            name,
            response=response,
        )
        feet.update(load_skin_table(folder / "skin.toml").footprint_sigma_mm or {})
    skin = load_skin_table(work / "skin" / "skin.toml")
    return replace(skin, footprint_sigma_mm=feet) if len(names) > 1 else skin


def touch_width_skin(
    bench_scene: Scene,
    scene: Scene,
    body: BenchBody,
    work: Path,
    indenters: Iterable[str],
) -> Any:
    """`scene`'s [skin] table with each of `indenters`' footprint width taken from the
    touches of another run of `bench_scene`'s board (`calibration_run`) alone, without
    its ground truth (`fruit calibrate` without --truth: `fruitcli.sensing.touch_width`), as a user
    without a printer bench would."""
    from fruitcli.sensing.touch_width import run_touch_width

    names = calibration_run(bench_scene, body, work, None, indenters)
    feet = dict(scene.skin.footprint_sigma_mm or {})
    for name in names:
        frames = work / "bench" / name / "frames.npz"
        found = run_touch_width(
            scene, frames, body.taxels, work / f"width-{name}", name, body.states
        )
        feet[name] = found["footprint_sigma_mm"]
    return replace(scene.skin, footprint_sigma_mm=feet)
