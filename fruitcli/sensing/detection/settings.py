"""Detection settings (`Settings`): the scene's ``[detection]`` section as the locator and
the frame-by-frame stream read it, each default the scene schema's. Units: counts,
frames, mm."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from fruitcli.errors import FrameError
from fruitcli.scene import SCHEMA
from fruitcli.sensing.detection.detect import MAX_TOUCHES
from fruitcli.sensing.detection.methods import METHODS

if TYPE_CHECKING:
    from fruitcli.scene import DetectionSection

HOVER_NOISE_SIGMAS = 8.0  # default hover threshold, in noise std (max over 252 taxels: ~3)
HOVER_HYSTERESIS_SIGMAS = 3.0  # default hover hysteresis: ends 5 std up, above the noise


def _default(key: str) -> Any:
    """The schema's default of ``[detection].key``."""
    return SCHEMA["detection"][key].default


@dataclass(frozen=True)
class Settings:
    """Detection settings, as the scene's ``[detection]`` section names them; each
    default is the schema's (`fruitcli.scene`)."""

    threshold_counts: float = _default("threshold_counts")
    baseline_frames: int = _default("baseline_frames")
    method: str = _default("method")
    noise_floor_counts: float = _default("noise_floor_counts")
    hysteresis_counts: float = _default("hysteresis_counts")
    debounce_frames: int = _default("debounce_frames")
    drift_rate: float = _default("drift_rate")
    track_gate_mm: float = _default("track_gate_mm")
    max_touches: int = MAX_TOUCHES
    hovers: bool = _default("hovers")
    hover_threshold_counts: float | None = _default("hover_threshold_counts")  # None: noise's
    hover_hysteresis_counts: float | None = _default("hover_hysteresis_counts")  # None: noise's
    footprint: str | None = _default("footprint")  # [skin] footprint heights assume
    model_frames: int = _default("model_frames")  # frames whose mean the model method fits

    @classmethod
    def from_scene(cls, detection: DetectionSection, **overrides: object) -> Settings:
        """From a scene's [detection] (a `fruitcli.scene.DetectionSection`); `overrides`
        that are not None win."""
        keys = {
            k: getattr(detection, k)
            for k in cls.__dataclass_fields__
            if k in type(detection).__dataclass_fields__
        }
        keys.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**keys)

    @property
    def stateful(self) -> bool:
        return bool(
            self.drift_rate > 0
            or self.hysteresis_counts > 0
            or self.hovers
            or self.debounce_frames > 1
            or self.track_gate_mm > 0
        )

    def hover_levels(self, noise_std_counts: float) -> tuple[float, float]:
        """(on, off) hover levels (counts): the threshold and threshold - hysteresis,
        defaults from the skin's noise std; FrameError when not below the touch threshold."""
        on = self.hover_threshold_counts
        on = HOVER_NOISE_SIGMAS * noise_std_counts if on is None else float(on)
        hyst = self.hover_hysteresis_counts
        hyst = HOVER_HYSTERESIS_SIGMAS * noise_std_counts if hyst is None else float(hyst)
        if not 0 < on < self.threshold_counts:
            how = (
                ""
                if self.hover_threshold_counts is not None
                else f" ({HOVER_NOISE_SIGMAS:g} x the skin's noise std {noise_std_counts:g})"
            )
            raise FrameError(
                f"[detection].hover_threshold_counts: expected > 0 and below the "
                f"touch threshold {self.threshold_counts:g} counts, got {on:g}" + how
            )
        if not 0 <= hyst < on:
            raise FrameError(
                f"[detection].hover_hysteresis_counts: expected >= 0 and below "
                f"the hover threshold {on:g} counts, got {hyst:g}"
            )
        return on, on - hyst

    @property
    def floor(self) -> float:
        return self.noise_floor_counts if METHODS[self.method].floor else 0.0


def check_skin_file(path: str | os.PathLike, method: str | None) -> None:
    """A [skin] file given for detection (``--skin``, `fruit calibrate`'s skin.toml) must
    state the footprint the model method fits: without ``footprint_sigma_mm`` its table
    would silently take the default width. FrameError naming the file and key."""
    import tomllib

    if method not in METHODS or METHODS[method].refine != "model":
        return
    try:
        with open(path, "rb") as fh:
            given = tomllib.load(fh).get("skin", {})
    except (OSError, tomllib.TOMLDecodeError):
        return  # the skin file's own reader reports it
    if isinstance(given, dict) and "footprint_sigma_mm" not in given:
        raise FrameError(
            f'{path}: [skin].footprint_sigma_mm: missing; [detection].method = "model" '
            "fits the skin's footprint at its calibrated width (fruit calibrate writes it)"
        )
