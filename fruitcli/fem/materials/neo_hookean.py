"""The compressible neo-Hookean model's constants: C10 = mu / 2 from E and nu (kPa), no
C20 or C30, and the bulk modulus the keys fix (the corotational model reads the same
constants)."""

from __future__ import annotations

from fruitcli.errors import SceneError
from fruitcli.fem.materials.build import Material, MaterialKeys, lame_from


def constants(keys: MaterialKeys, where: str) -> Material:
    """The Material of [material] `keys`; SceneError naming `where` when mu <= 0."""
    mu, _ = lame_from(keys.young_modulus_kpa, keys.poisson_ratio)
    if not mu > 0:
        raise SceneError(f"{where}: the shear modulus E / (2 (1 + nu)) must be > 0")
    return Material(
        keys.model, keys.young_modulus_kpa, keys.poisson_ratio, 0.5 * mu, 0.0, 0.0, keys.kappa_kpa
    )
