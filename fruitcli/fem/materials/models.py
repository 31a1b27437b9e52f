"""The material models, one table (``[material].model``).

The scene schema's choices and cross-checks, the reference docs, the material builder
(`build.material`, which calls the model's `constants` function) and the FEM stage's
choice of model (`fruitcli.fem.stage.build_model`) read `MATERIAL_MODELS`. Adding a model
is one module with its `constants` function and one entry here
(docs/howto/add-a-material-model.md). This module imports nothing of the library (a
model's function is named by its module path and loaded when first used), so the scene
schema can read it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from importlib import import_module

_HERE = "fruitcli.fem.materials"


@dataclass(frozen=True)
class MaterialModel:
    """A material model: `constants` the ``"module:function"`` of a function
    ``f(keys: build.MaterialKeys, where: str) -> build.Material`` that turns the
    [material] keys into the kernels' constants (C10, C20, C30, kappa in kPa; a bad key
    raises `fruitcli.errors.SceneError` naming ``where.key``), `corotational` when it is
    the paper's corotational Hooke model (solved by `fruitcli.fem.corotational_model`;
    else the hyperelastic `fruitcli.fem.continuum`, whose strain energy is Yeoh's form
    in those constants), `elements` the [fem].element values it runs on (empty: all)."""

    name: str
    doc: str
    constants: str = f"{_HERE}.neo_hookean:constants"
    corotational: bool = False
    elements: tuple[str, ...] = ()

    def builder(self) -> Callable:
        """The function `constants` names (imported on first use)."""
        return _load(self.constants)

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
            constants=f"{_HERE}.yeoh:constants",
        ),
        MaterialModel(
            "corotational",
            "the paper's corotational Hooke (SOFA's), linear tets only",
            corotational=True,
            elements=("p1",),
        ),
    )
}


@cache
def _load(ref: str) -> Callable:
    """The function ``"module:function"`` names (imported once)."""
    module, _, function = ref.partition(":")
    return getattr(import_module(module), function)
