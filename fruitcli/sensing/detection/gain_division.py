"""Which gains detection divides the activations by (``[detection].divide_by_gain``).

Units: none (a gain is the taxel's activation relative to a taxel of gain 1).

Off by default (the paper's pipeline). On with the scene's ``[detection].divide_by_gain
= true``, which takes the gains of ``[skin].taxel_gain`` (`fruit calibrate`'s
gains.csv), or with ``--divide-by-gain GAINS.csv`` on `fruit locate` and `fruit live`.
The file must give one finite gain > 0 for every taxel of the taxel file and for no
other taxel (`forward.load_taxel_gains`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fruitcli.tables import Taxels


@dataclass(frozen=True)
class GainInputs:
    """What gain division reads of a scene: ``[detection].divide_by_gain`` and, when it
    is on, ``[skin].taxel_gain`` (the scene's check made sure it is set). The default:
    no scene, division off."""

    divide_by_gain: bool = False
    taxel_gain: Path | None = None


def detection_gain(
    gain: GainInputs, taxels: Taxels, gains_csv: str | Path | None = None
) -> np.ndarray | None:
    """(T,) gains in the taxel file's order, or None when division is off. `gains_csv`
    (the command-line option) wins over the scene's ``[skin].taxel_gain``."""
    from fruitcli.sensing.skin.forward import load_taxel_gains

    if gains_csv is None:
        if not gain.divide_by_gain:
            return None
        assert gain.taxel_gain is not None  # the scene's check made sure it is set
        gains_csv = gain.taxel_gain
    return load_taxel_gains(gains_csv, taxels.ids, only_these=True)
