"""Frame registration of measured points onto the truth before the errors are taken.

The paper's published measurements are registered by a translation (their mean error
vector is zero to 1e-7 mm); a printer's frame is never exactly the model's. Methods:

- ``none``: the measurement as it is;
- ``translation``: remove the mean error vector (the paper's protocol), n >= 1;
- ``rigid``: least-squares rotation and translation (Kabsch), n >= 3 not on one line, 3D;
- ``similarity``: rotation, translation and one scale (Umeyama), as for a cast piece
  that shrank; n >= 3 not on one line, 3D.

The transform maps a measured point m to ``scale * rotation @ m + translation_mm`` (mm).
Top-view (x, y) data support ``none`` and ``translation`` only: a projection cannot carry
the 3D rotation between two frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fruitcli.errors import EvaluationError
from fruitcli.evaluation.registrations import REGISTRATIONS

METHODS = tuple(REGISTRATIONS)
METHODS_2D = tuple(r.name for r in REGISTRATIONS.values() if r.top_view)
MIN_SAMPLES = {r.name: r.min_samples for r in REGISTRATIONS.values()}
COLLINEAR_RATIO = 1e-9
"""A point set whose second singular value (centred) is below this fraction of the first
lies on one line: its rotation about that line is undetermined."""


@dataclass(frozen=True)
class Transform:
    """measured -> truth frame: x' = scale * rotation @ x + translation_mm (mm)."""

    method: str
    rotation: np.ndarray  # (d, d)
    translation_mm: np.ndarray  # (d,)
    scale: float = 1.0

    def apply(self, xyz: np.ndarray) -> np.ndarray:
        """Transformed points (n, d) mm."""
        return self.scale * xyz @ self.rotation.T + self.translation_mm

    @property
    def rotation_deg(self) -> float:
        """Angle of the rotation (degrees, 0..180)."""
        d = self.rotation.shape[0]
        c = (np.trace(self.rotation) - (d - 2)) / 2.0  # 3D: (tr - 1) / 2; 2D: tr / 2
        return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))

    def as_dict(self) -> dict:
        return {
            "method": self.method,
            "rotation": self.rotation.tolist(),
            "rotation_deg": self.rotation_deg,
            "translation_mm": self.translation_mm.tolist(),
            "scale": self.scale,
        }

    def describe(self) -> str:
        """One line for a table caption."""
        if self.method == "none":
            return "not registered"
        t = ", ".join(f"{round(v, 2) + 0.0:+.2f}" for v in self.translation_mm)
        text = f"{self.method}: translation ({t}) mm"
        if self.method in ("rigid", "similarity"):
            text += f", rotation {self.rotation_deg:.2f} deg"
        if self.method == "similarity":
            text += f", scale {self.scale:.4f}"
        return text


def identity(d: int) -> Transform:
    return Transform("none", np.eye(d), np.zeros(d))


def check_method(method: str, dims: int, n: int, where: str) -> None:
    """Refuse a method the data cannot support, naming `where` (the measured file)."""
    if method not in METHODS:
        raise EvaluationError(
            f"{where}: register: expected one of {', '.join(METHODS)}, got {method!r}"
        )
    if dims == 2 and method not in METHODS_2D:
        raise EvaluationError(
            f"{where}: register = {method} needs 3D data (x, y, z); "
            f"top-view (x, y) data support {' and '.join(METHODS_2D)} only"
        )
    need = MIN_SAMPLES[method]
    if n < need:
        extra = " not on one line" if need == 3 else ""
        raise EvaluationError(
            f"{where}: register = {method} needs at least {need} matched sample(s){extra}, got {n}"
        )


def _collinear(x: np.ndarray) -> bool:
    s = np.linalg.svd(x - x.mean(axis=0), compute_uv=False)
    return s[0] == 0 or s[1] <= COLLINEAR_RATIO * s[0]


def register(
    truth: np.ndarray, measured: np.ndarray, method: str, where: str = "measured"
) -> Transform:
    """The `method` transform that best maps `measured` (n, d) onto `truth` (n, d) mm in
    the least-squares sense. `where` names the data in errors."""
    n, d = truth.shape
    check_method(method, d, n, where)
    if method == "none":
        return identity(d)
    mu_t, mu_m = truth.mean(axis=0), measured.mean(axis=0)
    if method == "translation":
        return Transform(method, np.eye(d), mu_t - mu_m)
    if _collinear(measured) or _collinear(truth):
        raise EvaluationError(
            f"{where}: register = {method}: the {n} matched samples lie on "
            "one line, so the rotation about it is undetermined "
            "(need 3 samples not on one line)"
        )
    a, b = measured - mu_m, truth - mu_t
    u, s, vt = np.linalg.svd(b.T @ a)  # cross-covariance truth x measured (d, d)
    fix = np.eye(d)
    fix[-1, -1] = np.sign(np.linalg.det(u @ vt)) or 1.0  # a rotation, not a reflection
    rot = u @ fix @ vt
    scale = float((s * np.diag(fix)).sum() / (a * a).sum()) if method == "similarity" else 1.0
    return Transform(method, rot, mu_t - scale * rot @ mu_m, scale)
