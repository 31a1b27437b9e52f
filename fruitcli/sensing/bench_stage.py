"""The bench stage: the virtual 3D-printer bench's frames and true contact points, per
indenter (out_dir/<indenter>/frames.npz, truth.csv). Units: mm, counts, s.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.geometry.body_surface import body_surface, contact_heights
from fruitcli.sensing.detection.locate import load_states
from fruitcli.sensing.frames.recording import Recording
from fruitcli.sensing.inputs_stage import crossing_skin_inputs
from fruitcli.sensing.locator_setup import electrostatic_skin
from fruitcli.tables import read_taxels

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin
    from fruitcli.sensing.skin.forward import Skin
    from fruitcli.sensing.skin.virtual_bench import BenchRun
    from fruitcli.tables import Taxels

POINT_HEADER = ["sample", "x_mm", "y_mm", "z_mm"]
"""The columns of the bench's point tables (truth.csv, measured.csv)."""


@dataclass(frozen=True)
class SampleSpec:
    """Where the bench samples (``[bench].samples``): a quarter pitch off each taxel
    (`quarter`: the grid's spacings x, y in mm) or the points of a CSV (`csv`, its path
    resolved; columns sample,x_mm,y_mm)."""

    quarter: tuple[float, float] | None = None
    csv: Path | None = None


def sample_spec(scene: Scene) -> SampleSpec:
    """The scene's `SampleSpec` (the grid's spacings are read for "quarter" only)."""
    spec = scene.bench.samples
    if spec == "quarter":
        g = scene.grid
        return SampleSpec(quarter=(g.spacing_x_mm, g.spacing_y_mm))
    from fruitcli.scene import resolve_path

    return SampleSpec(csv=resolve_path(scene.path, spec))


def spec_points(spec: SampleSpec, taxels_mm: np.ndarray) -> np.ndarray:
    """(x, y) mm of the bench samples of `spec` over the taxels (T, 3) mm."""
    from fruitcli.sensing.skin.virtual_bench import quarter_samples
    from fruitcli.tables import read_table

    if spec.quarter is not None:
        return quarter_samples(taxels_mm[:, :2], *spec.quarter)
    assert spec.csv is not None, "the samples' CSV, or a quarter pitch off the taxels"
    cols = read_table(spec.csv, ["x_mm", "y_mm"], error=FrameError)
    return np.stack([cols["x_mm"], cols["y_mm"]], axis=1)


def sample_points(scene: Scene, taxels_mm: np.ndarray) -> np.ndarray:
    """(x, y) mm of the scene's bench samples: "quarter" or a CSV (sample,x_mm,y_mm)."""
    return spec_points(sample_spec(scene), taxels_mm)


def run_bench(
    scene: Scene,
    taxels_csv: str | os.PathLike,
    states_npz_or_none: str | os.PathLike | None,
    out_dir: str | os.PathLike,
    progress: Callable[[str], None] | None = None,
    surface_path: str | Path | None = None,
    surface_unit: str = "mm",
    crossing_dir: str | Path | None = None,
) -> dict:
    """Virtual 3D-printer bench: per indenter, out_dir/<indenter>/frames.npz + truth.csv.
    `surface_path`: the body's closed surface at rest (the ground truth's surface; see
    `fruitcli.sensing.skin.virtual_bench`), in `surface_unit`. With ``[skin].model =
    "electrostatic"`` the taxels' activation and baseline shift come from the crossing's
    table in `crossing_dir` (`electrostatic_skin`)."""
    from fruitcli.memory import require
    from fruitcli.sensing.frames.board import taxel_cells
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.virtual_bench import bench_bytes

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = read_taxels(taxels_csv, FrameError)
    board, bench = scene.board, scene.bench
    cells = taxel_cells(taxels, board, str(taxels_csv))
    # idle frames: counts and their noise per taxel (float), then board frames (float, uint16)
    require(
        bench.baseline_frames * (3 * 8 * len(taxels) + 10 * board.rows * board.cols),
        f"{scene.path.name}: [bench].baseline_frames = {bench.baseline_frames}",
        FrameError,
    )
    skin = forward.make_skin(
        len(taxels), bench.seed, forward.SkinParams.from_table(scene.skin), taxels.ids
    )
    surface = None if surface_path is None else body_surface(surface_path, surface_unit)
    response = electrostatic_skin(crossing_skin_inputs(scene, crossing_dir), progress)
    states, taxels_mm, shift = _bench_state(scene, taxels, states_npz_or_none, skin, response)
    xy = sample_points(scene, taxels_mm)
    z, truth_surface = contact_heights(xy, taxels_mm, states, bench.state, surface)
    contact = np.column_stack([xy, z])[np.flatnonzero(np.isfinite(z))]
    say(
        f"{len(xy)} sample points, {len(contact)} of them over {truth_surface} "
        f"({len(xy) - len(contact)} outside it are left out)"
    )
    if len(contact) == 0:
        raise FrameError(
            f"{scene.path.name}: [bench].samples: none of the {len(xy)} sample "
            f"points lies over {truth_surface}; expected points (x, y) over the "
            "body"
        )
    require(
        bench_bytes(bench.step_mm, len(contact), len(taxels), board.rows * board.cols),
        f"{scene.path.name}: [bench].step_mm = {bench.step_mm:g} over {len(contact)} samples",
        FrameError,
    )
    indenters: dict[str, dict[str, int]] = {}  # name -> frames, samples, dropped
    result = {
        "samples": int(len(xy)),
        "off_surface": int(len(xy) - len(contact)),
        "truth_surface": truth_surface,
        "indenters": indenters,
    }
    at = (contact, taxels_mm, skin.baseline_counts + shift)  # points, taxels, baseline
    for n, name in enumerate(bench.indenters):
        run, frames = _run_indenter(scene, n, name, at, skin, response, cells)
        _write_run(scene, name, run, frames, truth_surface, out_dir / name)
        indenters[name] = {
            "frames": run.counts.shape[0],
            "samples": int(len(run.truth_ids)),
            "dropped": run.dropped,
        }
        say(f"{name}: {len(run.truth_ids)} samples, {run.counts.shape[0]} frames")
    return result


def _bench_state(
    scene: Scene,
    taxels: Taxels,
    states_npz: str | os.PathLike | None,
    skin: Skin,
    response: CrossingSkin | None,
) -> tuple:
    """(states or None, taxel positions (T, 3) mm, baseline shift (T,) counts) at
    [bench].state: the FEM state's taxels and their strain's (or the crossing table's)
    shift, or the taxels at rest and no shift without states."""
    from fruitcli.sensing.skin import forward

    state = scene.bench.state
    if states_npz is None:
        if state != 0:
            raise FrameError(f"{scene.path.name}: [bench].state = {state} needs FEM states")
        return None, taxels.xyz_mm, np.zeros(len(taxels))
    states = load_states(states_npz, len(taxels))
    if not 0 <= state < states.n_states:
        raise FrameError(
            f"{scene.path.name}: [bench].state: {state} not in the states "
            f"(0..{states.n_states - 1})"
        )
    if response is None:
        shift = forward.strain_shift_counts(forward.taxel_strain(states, state), skin)
    else:
        from fruitcli.sensing.skin.crossing_skin import shift_counts

        shift = shift_counts(states, response, skin.fab, state)
    return states, states.taxels_mm[state], shift


def _run_indenter(
    scene: Scene,
    n: int,
    name: str,
    at: tuple[np.ndarray, np.ndarray, np.ndarray],
    skin: Skin,
    response: CrossingSkin | None,
    cells: tuple[np.ndarray, np.ndarray],
):
    """The bench run of indenter `name` (the n-th) down onto each contact point; `at`:
    (contact points (m, 3) mm, taxel positions (T, 3) mm, baseline (T,) counts); `cells`:
    the taxels' (rows, cols) on the board. -> (the run (`virtual_bench.descend`), its
    board frames (n, rows, cols) counts)."""
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.virtual_bench import cell_counts, descend

    board, bench = scene.board, scene.bench
    threshold = scene.detection.threshold_counts
    if response is None:
        forward.footprint_sigma_mm(name, skin.params)  # validates the name
    else:
        response.object_index(name)
    rng = np.random.default_rng([bench.seed, n])
    contact, taxels_mm, baseline = at
    run = descend(
        contact,
        taxels_mm,
        baseline,
        skin,
        name,
        bench.step_mm,
        bench.baseline_frames,
        threshold,
        rng,
        response,
    )
    if len(run.truth_ids) == 0:
        raise FrameError(
            f"{scene.path.name}: [bench]: no sample of the {name} indenter "
            f"reached [detection].threshold_counts = {threshold:g} counts; "
            "the bench has no touch to record"
        )
    fill = forward.frame_counts(
        np.full((run.counts.shape[0], board.rows, board.cols), forward.BASELINE_COUNTS),
        np.median(skin.noise_std_counts),
        rng,
    )
    rows, cols = cells
    return run, cell_counts(run.counts, rows, cols, (board.rows, board.cols), fill)


def _write_run(
    scene: Scene, name: str, run: BenchRun, frames: np.ndarray, truth_surface: str, out_dir: Path
) -> None:
    """out_dir/frames.npz (the board frames of `run`, with the bench's settings as meta)
    and out_dir/truth.csv (its true contact points, mm)."""
    from fruitcli.sensing.frames.recording import write_npz
    from fruitcli.sensing.skin.virtual_bench import BENCH_FPS

    bench = scene.bench
    n_frames = frames.shape[0]
    meta = {
        "source": "bench",
        "scene": scene.name,
        "indenter": name,
        "state": bench.state,
        "seed": bench.seed,
        "step_mm": bench.step_mm,
        "threshold_counts": scene.detection.threshold_counts,
        "baseline_frames": bench.baseline_frames,
        "fps": BENCH_FPS,
        "start_gap_mm": {
            str(int(k)): float(g) for k, g in zip(run.truth_ids, run.start_gap_mm, strict=True)
        },
    }
    rec = Recording(frames, np.arange(n_frames) / BENCH_FPS, sample=run.sample, meta=meta)
    write_npz(out_dir / "frames.npz", rec)
    write_csv(
        out_dir / "truth.csv",
        POINT_HEADER,
        ([int(k), *map(float, p)] for k, p in zip(run.truth_ids, run.truth_mm, strict=True)),
        comments=[
            f"bench contact points ({name} indenter, state {bench.state}), mm, on {truth_surface}"
        ],
    )
