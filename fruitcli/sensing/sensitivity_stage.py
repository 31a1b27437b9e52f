"""The sensitivity stage: noise std per taxel at rest and baseline shift per taxel over
the states' animation (sensitivity.json and its pictures). Units: counts, mm.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.detection.locate import load_states
from fruitcli.sensing.inputs_stage import crossing_skin_inputs
from fruitcli.sensing.locator_setup import electrostatic_skin
from fruitcli.tables import read_taxels

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.sensing.detection.locate import States
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin
    from fruitcli.sensing.skin.forward import Skin
    from fruitcli.tables import Taxels


def run_sensitivity(
    scene: Scene,
    taxels_csv: str | os.PathLike,
    states_npz: str | os.PathLike | None,
    out_dir: str | os.PathLike,
    progress: Callable[[str], None] | None = None,
    crossing_dir: str | Path | None = None,
) -> dict:
    """Noise std per taxel at rest and max baseline shift per taxel over the states' animation
    (Figs. 10, 11; Fig. 9 for a bent pad): sensitivity.json, noise_std.png, max_shift.png.
    With ``[skin].model = "electrostatic"`` the shifts come from the crossing's table in
    `crossing_dir` (`electrostatic_skin`)."""
    from fruitcli.fsutil import write_json
    from fruitcli.sensing.skin import forward, sensitivity

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = read_taxels(taxels_csv, FrameError)
    states = None if states_npz is None else load_states(states_npz, len(taxels))
    sens = scene.sensitivity
    from fruitcli.memory import require

    # frames at rest, then the animation's: noise, mean and counts per taxel (float, int)
    for key, frames in (
        ("noise_frames", sens.noise_frames),
        ("animation_frames", sens.animation_frames),
    ):
        require(
            frames * len(taxels) * 8.0 * 4,
            f"{scene.path.name}: [sensitivity].{key} = {frames} over {len(taxels)} taxels",
            FrameError,
        )
    skin = forward.make_skin(
        len(taxels),
        scene.bench.seed,
        forward.SkinParams.from_table(scene.skin),
        taxels.ids,
    )
    rng = np.random.default_rng([scene.bench.seed, 99])
    rest = forward.frame_counts(
        np.broadcast_to(skin.baseline_counts, (sens.noise_frames, len(taxels))),
        skin.noise_std_counts,
        rng,
    )
    std = sensitivity.noise_std_counts(rest)
    response = electrostatic_skin(crossing_skin_inputs(scene, crossing_dir), progress)
    strain, gain, shift_model = _model_shift(states, skin, response, len(taxels))
    anim = sensitivity.animation_shift(shift_model, sens.animation_frames)
    played = forward.frame_counts(skin.baseline_counts + anim, skin.noise_std_counts, rng)
    shift = sensitivity.max_shift_counts(played, rest.mean(axis=0))
    model_max = shift_model.max(axis=0)
    threshold = scene.detection.threshold_counts
    taxel_rows = [
        {
            "id": int(taxels.ids[k]),
            "i": int(taxels.i[k]),
            "j": int(taxels.j[k]),
            "std": float(std[k]),
            "max_shift": float(shift[k]),
            "max_shift_model": float(model_max[k]),
            "strain_max": float(strain[:, k].max()),
            "fab": float(skin.fab[k]),
        }
        for k in range(len(taxels))
    ]
    out = {
        "units": "counts (strain: Green-Lagrange norm, -)",
        "threshold_counts": threshold,
        "noise_frames": sens.noise_frames,
        "animation_frames": sens.animation_frames,
        "states": len(strain),
        "strain_gain_counts": gain,
        **(
            {}
            if response is None
            else {"skin_model": "electrostatic", "counts_per_ff": response.counts_per_ff}
        ),
        "summary": {
            "std": sensitivity.summary(std),
            "max_shift": sensitivity.summary(shift),
            "max_shift_model": sensitivity.summary(model_max),
        },
        "taxels": taxel_rows,
    }
    write_json(out_dir / "sensitivity.json", out)
    _save_maps(out_dir, taxels, states, std, shift, sens.noise_frames, threshold)
    say(
        f"noise std max {std.max():.2f}, max shift max {shift.max():.1f} "
        f"mean {shift.mean():.1f} counts"
    )
    return out


def _model_shift(
    states: States | None, skin: Skin, response: CrossingSkin | None, n_taxels: int
) -> tuple:
    """(strain (S, T) Green-Lagrange norm, the strain gain in counts or None, the model's
    baseline shift (S, T) counts) over the S states (one at rest without states): from
    the strain, or from the crossing's table `response` (an electrostatic skin)."""
    from fruitcli.sensing.skin import forward

    # no deformation (no FEM): one state, the taxels at rest, no strain
    strain = np.zeros((1, n_taxels)) if states is None else forward.taxel_strain(states)
    if response is None:
        gain = forward.calibrate_strain_gain()
        shift_model = forward.strain_shift_counts(strain, skin, gain)
    else:
        from fruitcli.sensing.skin.crossing_skin import shift_counts

        gain = None
        shift_model = (
            np.zeros_like(strain) if states is None else shift_counts(states, response, skin.fab)
        )
    return strain, gain, shift_model


def _save_maps(
    out_dir: Path,
    taxels: Taxels,
    states: States | None,
    std: np.ndarray,
    shift: np.ndarray,
    noise_frames: int,
    threshold: float,
) -> None:
    """The noise std and max shift (T,) counts as heat maps over the grid and top views
    over the body's outline (the states' surface, or the taxels' box without states)."""
    from fruitcli.sensing.skin.heat_maps import save_heatmap, save_topview

    save_heatmap(
        out_dir / "noise_std.png",
        taxels.i,
        taxels.j,
        std,
        f"noise std over {noise_frames} frames at rest",
        threshold / 2,
    )
    save_heatmap(
        out_dir / "max_shift.png",
        taxels.i,
        taxels.j,
        shift,
        "max baseline shift over the animation",
        threshold,
    )
    outline = (
        _box_outline(taxels.xyz_mm[:, :2])
        if states is None
        else states.rest_nodes[states.surface_tris][:, :, :2]
    )
    xy = taxels.xyz_mm[:, :2]
    save_topview(
        out_dir / "noise_std_top.png",
        xy,
        std,
        outline,
        f"noise std over {noise_frames} frames at rest (top view, counts)",
        threshold / 2,
    )
    save_topview(
        out_dir / "max_shift_top.png",
        xy,
        shift,
        outline,
        "max baseline shift over the animation (top view, counts)",
        threshold,
    )


def _box_outline(xy_mm: np.ndarray, pad_mm: float = 8.0) -> np.ndarray:
    """Two triangles (2, 3, 2) covering the taxels' bounding box grown by `pad_mm` (mm)."""
    (x0, y0), (x1, y1) = xy_mm.min(axis=0) - pad_mm, xy_mm.max(axis=0) + pad_mm
    return np.array([[[x0, y0], [x1, y0], [x1, y1]], [[x0, y0], [x1, y1], [x0, y1]]])
