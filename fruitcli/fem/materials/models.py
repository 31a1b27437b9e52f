"""The material models, one table (``[material].model``).

The scene schema's choices and cross-checks, the material builder (`build`) and the FEM
stage's choice of model (`fruitcli.fem.stage.build_model`) read `MATERIAL_MODELS`. This
module imports nothing, so the scene schema can read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class MaterialModel:
    """A material model: `corotational` when it is the paper's corotational Hooke model
    (solved by `fruitcli.fem.corotational_model`; else the hyperelastic
    `fruitcli.fem.continuum`), `elements` the [fem].element values it runs on (empty: all)."""

    name: str
    doc: str
    corotational: bool = False
    elements: tuple[str, ...] = ()

    def runs_on(self, element: str) -> bool:
        """Whether this model runs on [fem].element `element`."""
        return not self.elements or element in self.elements


MATERIAL_MODELS: dict[str, MaterialModel] = {
    m.name: m
    for m in (
        MaterialModel("neo-hookean", "neo-Hookean from E and nu (default)"),
        MaterialModel(
            "yeoh",
            "Yeoh with its constants (c10_kpa, c20_kpa, c30_kpa; bulk modulus from "
            "bulk_modulus_kpa or E and nu)",
        ),
        MaterialModel(
            "corotational",
            "the paper's corotational Hooke (SOFA's), linear tets only",
            corotational=True,
            elements=("p1",),
        ),
    )
}
