"""The scene schema's sections of the sensing: [board], [frames], [detection], [bench],
[skin], [printer], [sensitivity], [report] and [[evaluate]]. Units in the key names (mm,
counts, s)."""

from __future__ import annotations

from fruitcli.evaluation.registrations import REGISTRATIONS
from fruitcli.geometry.mesh.units import MAX_EXTENT_MM
from fruitcli.scene.key import Key
from fruitcli.scene.limits import (
    ANGLE,
    COORDINATE,
    COUNTS,
    FAR_MM,
    LENGTH,
    MAX_COUNTS,
    MAX_FRAMES,
    MAX_HEIGHT_FORM,
    MAX_INDENTERS,
    MAX_ITEMS,
    MAX_MODEL_FRAMES,
    MAX_SECONDS,
    MAX_STATES,
    MAX_WIDENING_PER_MM,
    POSITIVE,
    POSITIVE_LENGTH,
    SEED,
    gap_table,
    nonempty_box,
)
from fruitcli.sensing.detection.methods import METHODS as DETECTION_METHODS
from fruitcli.sensing.detection.methods import method_help
from fruitcli.sensing.frames.formats import BOARD_COLS, BOARD_FORMATS, BOARD_ROWS
from fruitcli.sensing.skin.models import SKIN_MODELS

SECTIONS: dict[str, dict[str, Key]] = {
    "board": {
        "rows": Key(
            "int",
            BOARD_ROWS,
            "frame rows (Tx lines of the FocalTech FT5316, MuCa)",
            min=1,
            max=1024,
        ),
        "cols": Key("int", BOARD_COLS, "frame columns (Rx lines)", min=1, max=1024),
        "offset_i": Key("int", 0, "frame row of taxel i = 0", min=0, max=1023),
        "offset_j": Key("int", 0, "frame column of taxel j = 0", min=0, max=1023),
        "flip_i": Key("bool", False, "taxel i counts down the frame rows"),
        "flip_j": Key("bool", False, "taxel j counts down the frame columns"),
        "transpose": Key("bool", False, "taxel i runs along frame columns"),
        "format": Key(
            "str",
            "auto",
            "frames on the port and in raw captures: auto, ascii "
            "(stock Muca_Raw) or binary (stock SendRawByte packets)",
            choices=("auto", *BOARD_FORMATS),
        ),
    },
    "frames": {
        "recording": Key("path", None, "recorded frames (.npz or MuCa ASCII log)"),
        "model": Key(
            "str",
            "reduced",
            "a recording with chamber pressures: reduced (taxels "
            "from the reduced model at each frame's pressures) or full (along the "
            "simulated states)",
            choices=("reduced", "full"),
        ),
    },
    "detection": {
        "threshold_counts": Key(
            "num",
            20.0,
            "touch threshold on v = C - C0 (counts)",
            **POSITIVE,
            max=MAX_COUNTS,
        ),
        "baseline_frames": Key(
            "int", 10, "frames averaged into the baseline C0", min=1, max=MAX_FRAMES
        ),
        "method": Key(
            "str",
            "n9",
            "how touches are found and placed: " + method_help(),
            choices=tuple(DETECTION_METHODS),
        ),
        "model_frames": Key(
            "int",
            1,
            "frames whose mean activation the model method fits: a touch's frame and "
            "those just before it (1: the frame alone); a still touch's noise falls by "
            "its square root, a moving one lags by half as many frames",
            min=1,
            max=MAX_MODEL_FRAMES,
            expected="frames >= 1",
        ),
        "noise_floor_counts": Key(
            "num",
            0.0,
            "subtracted from v before weighting (n9_floor)",
            **COUNTS,
            expected="counts >= 0",
        ),
        "hysteresis_counts": Key(
            "num",
            0.0,
            "touch ends below threshold - hysteresis",
            **COUNTS,
            expected="counts >= 0",
        ),
        "debounce_frames": Key(
            "int",
            0,
            "frames above threshold before a touch starts",
            min=0,
            max=MAX_FRAMES,
            expected="frames >= 0",
        ),
        "drift_rate": Key(
            "num",
            0.0,
            "baseline tracking rate per untouched frame (0: off)",
            min=0.0,
            max=1.0,
            expected="a rate per frame 0 <= rate <= 1",
        ),
        "track_gate_mm": Key(
            "num",
            0.0,
            "touch IDs across frames within this distance (0: off)",
            **LENGTH,
            expected="a distance >= 0 mm",
        ),
        "project": Key(
            "str",
            "none",
            "none (the N9 average of the 3D taxels, the paper) or "
            "surface (moved to the nearest point of the body)",
            choices=("none", "surface"),
        ),
        "divide_by_gain": Key(
            "bool",
            False,
            "divide each taxel's activation by its gain in "
            "[skin].taxel_gain before detection (threshold, maxima and N9 "
            "weights on the divided v; off: the paper)",
        ),
        "hovers": Key("bool", False, "report hovers (below the touch threshold) as kind hover"),
        "hover_threshold_counts": Key(
            "num",
            None,
            "hover threshold (counts; default 8 x the [skin] noise std); below threshold_counts",
            **POSITIVE,
            max=MAX_COUNTS,
        ),
        "hover_hysteresis_counts": Key(
            "num",
            None,
            "a hover ends below its threshold minus "
            "this (counts; default 3 x the [skin] noise std)",
            **COUNTS,
        ),
        "footprint": Key(
            "str",
            None,
            "[skin].footprint_sigma_mm entry heights and strengths "
            "assume (default: the only one, else small)",
        ),
    },
    "bench": {
        "indenters": Key(
            "list",
            ["small", "medium"],
            "indenters to replay: small, medium",
            max_items=MAX_INDENTERS,
        ),
        "samples": Key("str", "quarter", "quarter (a quarter taxel off the grid) or a CSV path"),
        "state": Key("int", 0, "FEM state the bench runs on", min=0, max=MAX_STATES - 1),
        "step_mm": Key(
            "num",
            0.1,
            "indenter descent step (mm; its frames are sized by `memory` first)",
            **POSITIVE,
            max=7.0,
        ),
        "seed": Key("int", 0, "seed of the noise", **SEED),
        "baseline_frames": Key(
            "int",
            10,
            "idle frames recorded before the first descent: the baseline `fruit locate` "
            "takes, if more than [detection].baseline_frames",
            min=1,
            max=MAX_FRAMES,
        ),
        "reference_length_mm": Key(
            "num", None, "for % errors (default: largest truth span)", **POSITIVE_LENGTH
        ),
        "register": Key(
            "str",
            "none",
            "registration of the bench rows: none, translation, "
            "rigid or similarity (see [[evaluate]].register)",
            choices=tuple(REGISTRATIONS),
        ),
    },
    "skin": {  # the skin's forward model (fruitcli.sensing.skin.forward); defaults: its assumptions
        "footprint_sigma_mm": Key(
            "table",
            None,
            "per indenter: lateral Gaussian width (mm); default small 6.18, medium 7.21",
            **POSITIVE_LENGTH,
            expected="a width > 0 mm",
            max_items=MAX_INDENTERS,
        ),
        "contact_counts": Key(
            "num",
            60.0,
            "activation of the taxel under the indenter at contact (counts)",
            **POSITIVE,
            max=MAX_COUNTS,
        ),
        "gap_decay_mm": Key(
            "num", 2.0, "activation falls as exp(-gap / gap_decay_mm) (mm)", **POSITIVE_LENGTH
        ),
        "height_as_distance": Key(
            "num",
            1.0,
            "weight of a crossing's height under the contact point (along z, the bench's "
            "approach) in the footprint's squared distance: 1 a Gaussian in 3D distance, 0 "
            "in the lateral offset only (fruit calibrate fits it)",
            min=0.0,
            max=MAX_HEIGHT_FORM,
        ),
        "height_as_gap": Key(
            "num",
            0.0,
            "share of a crossing's height difference from the contact point added to the gap "
            "in exp(-gap / gap_decay_mm) (fruit calibrate fits it)",
            min=0.0,
            max=MAX_HEIGHT_FORM,
        ),
        "widening_per_mm": Key(
            "num",
            0.0,
            "share by which the footprint's width grows per mm of gap: sigma (1 + "
            "widening_per_mm * gap), the gap with the height difference's share "
            "(fruit calibrate fits it)",
            min=0.0,
            max=MAX_WIDENING_PER_MM,
        ),
        "gain_spread": Key(
            "num",
            0.0,
            "taxel gains drawn uniformly in 1 +- spread (seeded)",
            min=0.0,
            max=1.0,
            max_exclusive=True,
            expected="0 <= spread < 1",
        ),
        "noise_std_counts": Key(
            "range",
            [0.5, 1.85],
            "noise std (counts): one value, or [lo, hi] drawn per taxel (seeded)",
            max=MAX_COUNTS,
            expected=f"a std 0 <= value <= {MAX_COUNTS} counts, or [lo, hi] within it",
            unbounded="its lower bound 0 is its kind's (`range`)",
        ),
        "taxel_gain": Key(
            "path",
            None,
            "CSV (id, gain) of measured taxel gains, e.g. fruit "
            "calibrate's gains.csv (with gain_spread = 0)",
        ),
        # the electrostatic crossing (fruitcli.electrostatics.crossing, `fruit skin`)
        "model": Key(
            "str",
            "gaussian",
            "gaussian (the assumed footprint, gap decay and strain "
            "gain above) or electrostatic (the crossing's field)",
            choices=tuple(SKIN_MODELS),
        ),
        "permittivity": Key(
            "num",
            2.8,
            "relative permittivity of the silicone (Ecoflex: about "
            "2.8, as quoted for platinum-cure silicones at low "
            "frequency, 2.5-3)",
            min=1.0,
            max=1e4,
            expected="a relative permittivity >= 1 (Ecoflex: about 2.8)",
        ),
        "yarn_radius_mm": Key(
            "num",
            None,
            "radius of the conductive yarn (mm; default [tracks].track_radius_mm)",
            **POSITIVE_LENGTH,
            expected="> 0 (mm)",
        ),
        "insulation_mm": Key(
            "num",
            0.1,
            "insulating layer between Tx and Rx where they cross (mm)",
            **POSITIVE_LENGTH,
            expected="> 0 (mm; the yarns must not touch)",
        ),
        "counts_per_ff": Key(
            "num",
            None,
            "CDC counts per fF of the electrostatic skin (default: fitted so the crossing "
            "bent as the paper's pad shifts 10 counts; fruit calibrate fits it to a "
            "bench recording)",
            **POSITIVE,
            max=1e6,
            expected="> 0 (counts per fF)",
        ),
        "gaps_mm": Key(
            "list",
            [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0],
            "object gaps of the crossing's table (mm, increasing from 0: contact)",
            valid=gap_table,
            expected=f"at least two gaps in mm, increasing, starting at 0 (contact), "
            f"at most {MAX_EXTENT_MM:g}",
            max_items=MAX_ITEMS,
        ),
    },
    "printer": {  # the real bench: a Marlin printer with an indenter (fruit bench --printer)
        "model_origin_mm": Key(
            "vec3",
            None,
            "where the model's origin is, printer coordinates (mm; required with [printer])",
            **COORDINATE,
        ),
        "rotate_z_deg": Key("num", 0.0, "model rotated about z on the bed (degrees)", **ANGLE),
        "safe_height_mm": Key(
            "num",
            20.0,
            "tip height above the model's highest point between samples (mm)",
            **POSITIVE_LENGTH,
            expected="> 0 (mm above the model's highest point; lower "
            "would drag the tip through the model)",
        ),
        "step_mm": Key(
            "num",
            0.1,
            "descent step (mm, 0 < step <= 1)",
            **POSITIVE,
            max=1.0,
            expected="0 < step <= 1 mm",
        ),
        "feed_mm_min": Key(
            "num",
            600.0,
            "feed rate of every move (mm/min)",
            **POSITIVE,
            max=1e6,
            expected="> 0 mm/min",
        ),
        "max_press_mm": Key(
            "num",
            1.5,
            "deepest press below the expected surface before the sample is an error (mm)",
            **POSITIVE_LENGTH,
            expected="> 0 mm",
        ),
        "bed_mm": Key(
            "box",
            [0.0, 0.0, 0.0, 220.0, 220.0, 250.0],
            "reachable volume [xmin, ymin, zmin, xmax, ymax, zmax], printer coordinates (mm)",
            valid=nonempty_box,
            **COORDINATE,
            expected=f"[xmin, ymin, zmin, xmax, ymax, zmax] with min < max, within +-{FAR_MM:g} mm",
        ),
        "baud": Key("int", 115200, "the printer's serial baud rate", **POSITIVE, max=10**8),
        "home": Key("bool", False, "send G28 (home all axes) first"),
        "timeout_s": Key(
            "num",
            30.0,
            "longest wait for an 'ok' (s; busy lines extend it)",
            **POSITIVE,
            max=MAX_SECONDS,
            expected="> 0 s",
        ),
    },
    "sensitivity": {
        "noise_frames": Key(
            "int",
            300,
            "frames at rest for the per-taxel noise std",
            min=2,
            max=MAX_FRAMES,
            expected="frames >= 2 (a standard deviation needs two)",
        ),
        "animation_frames": Key(
            "int",
            60,
            "frames over one animation cycle",
            min=1,
            max=100_000,
            expected="frames >= 1",
        ),
    },
    "report": {
        "paper_rows": Key(
            "list", [], "paper Table I rows to show next to ours", max_items=MAX_ITEMS
        ),
    },
    "evaluate": {},
}
"""The sections, in the order the schema lists them."""

ITEMS: dict[str, dict[str, Key]] = {
    "evaluate": {
        "label": Key("str", None, "row label, e.g. 'Rest, small'", required=True),
        "truth": Key("path", None, "ground-truth CSV (sample,x_mm,y_mm[,z_mm])", required=True),
        "measured": Key("path", None, "measured CSV (same samples)", required=True),
        "reference_length_mm": Key(
            "num", None, "for % errors (default: largest truth span)", **POSITIVE_LENGTH
        ),
        "register": Key(
            "str",
            "none",
            "none, translation (the paper's protocol), rigid or "
            "similarity: measurement mapped onto the truth first",
            choices=tuple(REGISTRATIONS),
        ),
    },
}
"""The keys of one table of each array of tables."""
