"""The scene's [material] as the constants the FEM uses: which model, and its
isochoric (C10, C20, C30) and bulk (kappa) constants in kPa."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from fruitcli.errors import SceneError
from fruitcli.fem.materials.models import MATERIAL_MODELS


@dataclass(frozen=True)
class Material:
    model: str
    young_modulus_kpa: float
    poisson_ratio: float
    c10_kpa: float
    c20_kpa: float
    c30_kpa: float
    bulk_modulus_kpa: float

    @property
    def shear_modulus_kpa(self) -> float:
        """Small-strain shear modulus mu = 2 C10 (kPa)."""
        return 2.0 * self.c10_kpa

    def constants(self) -> np.ndarray:
        """(c10, c20, c30, kappa) for the compiled kernels."""
        return np.array([self.c10_kpa, self.c20_kpa, self.c30_kpa, self.bulk_modulus_kpa])


@dataclass(frozen=True)
class MaterialKeys:
    """The scene's [material] keys as a model's `constants` function reads them: the
    model's name, Young's modulus E (kPa), Poisson's ratio nu, the Yeoh constants (kPa;
    c10 None when not given) and the bulk modulus kappa (kPa) already fixed:
    ``bulk_modulus_kpa`` when given, else from E and nu, and > 0."""

    model: str
    young_modulus_kpa: float
    poisson_ratio: float
    c10_kpa: float | None
    c20_kpa: float
    c30_kpa: float
    kappa_kpa: float


def lame_from(e_kpa: float, nu: float) -> tuple[float, float]:
    """(mu, kappa) in kPa from Young's modulus and Poisson's ratio."""
    return e_kpa / (2.0 * (1.0 + nu)), e_kpa / (3.0 * (1.0 - 2.0 * nu))


def material(
    model: str = "neo-hookean",
    young_modulus_kpa: float = 100.0,
    poisson_ratio: float = 0.45,
    c10_kpa: float | None = None,
    c20_kpa: float = 0.0,
    c30_kpa: float = 0.0,
    bulk_modulus_kpa: float | None = None,
    where: str = "[material]",
) -> Material:
    """A checked Material, from the `constants` function of `model`'s entry in
    `MATERIAL_MODELS`; errors name the scene field."""
    if model not in MATERIAL_MODELS:
        from difflib import get_close_matches

        near = get_close_matches(model, MATERIAL_MODELS, 1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise SceneError(
            f"{where}.model: expected one of {', '.join(MATERIAL_MODELS)}, got {model!r}{hint}"
        )
    _, kappa = lame_from(young_modulus_kpa, poisson_ratio)
    if bulk_modulus_kpa is not None:
        kappa = float(bulk_modulus_kpa)
    if not kappa > 0:
        raise SceneError(
            f"{where}.bulk_modulus_kpa: expected > 0 (a material with a "
            f"negative bulk modulus is unstable), got {kappa}"
        )
    keys = MaterialKeys(
        model,
        float(young_modulus_kpa),
        float(poisson_ratio),
        None if c10_kpa is None else float(c10_kpa),
        float(c20_kpa),
        float(c30_kpa),
        kappa,
    )
    return MATERIAL_MODELS[model].builder()(keys, where)


class MaterialFields(Protocol):
    """The fields of a scene's [material] `from_scene` reads (a `fruitcli.scene`
    `MaterialSection`); moduli in kPa."""

    @property
    def model(self) -> str: ...

    @property
    def young_modulus_kpa(self) -> float: ...

    @property
    def poisson_ratio(self) -> float: ...

    @property
    def c10_kpa(self) -> float | None: ...

    @property
    def c20_kpa(self) -> float | None: ...

    @property
    def c30_kpa(self) -> float | None: ...

    @property
    def bulk_modulus_kpa(self) -> float | None: ...


def from_scene(mat: MaterialFields) -> Material:
    """The Material of a scene's [material] table (a `fruitcli.scene.MaterialSection`)."""
    return material(
        mat.model,
        mat.young_modulus_kpa,
        mat.poisson_ratio,
        mat.c10_kpa,
        mat.c20_kpa or 0.0,
        mat.c30_kpa or 0.0,
        mat.bulk_modulus_kpa,
    )
