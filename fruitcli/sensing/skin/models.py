"""The skin models, one table (``[skin].model``).

The scene schema's choices read `SKIN_MODELS`; the sensing stages dispatch on
`SkinModel.computed`. This module imports nothing, so the scene schema can read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SkinModel:
    """A skin model: `computed` when the taxels' response comes from the crossing's
    computed field (`fruitcli.electrostatics`) rather than the assumed footprint."""

    name: str
    doc: str
    computed: bool = False


SKIN_MODELS: dict[str, SkinModel] = {
    m.name: m
    for m in (
        SkinModel(
            "gaussian",
            "the assumed footprint, gap decay and strain gain (`fruitcli.sensing.skin.forward`)",
        ),
        SkinModel(
            "electrostatic",
            "the computed crossing's table (`fruitcli.electrostatics`)",
            computed=True,
        ),
    )
}
