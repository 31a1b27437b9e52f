"""Where the model sits on the printer: model <-> printer coordinates (mm).

p_printer = Rz(rotate_z_deg) p_model + model_origin_mm; z stays vertical.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.scene import PrinterSection


class Placement:
    """The ``[printer]`` placement of the model on the bed."""

    def __init__(self, model_origin_mm: Sequence[float] | np.ndarray, rotate_z_deg: float = 0.0):
        self.origin = np.asarray(model_origin_mm, float)
        a = np.radians(rotate_z_deg)
        self.rot = np.array(
            [[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]]
        )

    @classmethod
    def from_printer(cls, printer: PrinterSection) -> Placement:
        """From a scene's [printer] (a `fruitcli.scene.PrinterSection`)."""
        assert printer.model_origin_mm is not None  # the scene's check
        return cls(printer.model_origin_mm, printer.rotate_z_deg)

    def to_printer(self, p_model: np.ndarray) -> np.ndarray:
        """(..., 3) model mm -> printer mm."""
        return np.asarray(p_model, float) @ self.rot.T + self.origin

    def to_model(self, p_printer: np.ndarray) -> np.ndarray:
        """(..., 3) printer mm -> model mm."""
        return (np.asarray(p_printer, float) - self.origin) @ self.rot
