"""The Yeoh model's constants: C10, C20, C30 as given (kPa) and the bulk modulus the keys
fix; E and nu are the small-strain ones they imply (mu = 2 C10)."""

from __future__ import annotations

from fruitcli.errors import SceneError
from fruitcli.fem.materials.build import Material, MaterialKeys


def constants(keys: MaterialKeys, where: str) -> Material:
    """The Material of [material] `keys`; SceneError naming `where`'s key when c10 is
    missing or <= 0 or c30 < 0."""
    if keys.c10_kpa is None:
        raise SceneError(
            f"{where}.c10_kpa: the yeoh model needs its constants "
            "(c10_kpa > 0, c20_kpa, c30_kpa in kPa)"
        )
    c10, c20, c30, kappa = keys.c10_kpa, keys.c20_kpa, keys.c30_kpa, keys.kappa_kpa
    if not c10 > 0:
        raise SceneError(
            f"{where}.c10_kpa: expected > 0 (the small-strain shear modulus is 2 c10), got {c10}"
        )
    if c30 < 0:
        raise SceneError(
            f"{where}.c30_kpa: expected >= 0 (a negative c30 makes the "
            f"material unstable at large stretch), got {c30}"
        )
    e = 9.0 * kappa * 2 * c10 / (3.0 * kappa + 2 * c10)
    nu = (3.0 * kappa - 4 * c10) / (2.0 * (3.0 * kappa + 2 * c10))
    return Material(keys.model, e, nu, c10, c20, c30, kappa)
