"""Baseline drift tracking: the one tracker behind `fruit live`'s time constant and
``[detection].drift_rate``.

Units: counts, s. Temperature and humidity move every taxel's rest count slowly; the
tracker follows with a first-order filter of time constant tau (s),

    C0 += a (C - C0),  a = 1 - exp(-dt / tau)  (dt: time since the previous frame),

or, built with `DriftTracker.per_frame(r)` (``[detection].drift_rate``), a = r on every
quiet frame, quietness then being decided by the caller (the detection stream: no touch
and no activation above threshold - hysteresis).

but only on quiet frames: no taxel's activation C - C0 above the guard (half the touch
threshold by default), and at least `hold_s` since the last frame that had one (the
silicone relaxes after a press). So a hand hovering just below the threshold freezes the
baseline instead of being absorbed into it, as Infineon CAPSENSE and Microchip QTouch do
(update only below a noise threshold; QTouch's 4 s drift hold time). Counts falling
below the baseline (C - C0 < 0) are never a touch and are always followed. Taxels
flagged broken (`fruitcli.sensing.detection.health`) do not freeze it: a taxel stuck high would
otherwise stop the tracking of all the others for the rest of the run.
"""

from __future__ import annotations

import math

import numpy as np

from fruitcli.errors import FrameError

DEFAULT_TAU_S = 60.0  # thermal drift takes minutes to hours; a visitor's hover seconds
GUARD_FRACTION = 0.5  # of the threshold: CAPSENSE's noise threshold is 40 % of a touch
HOLD_S = 4.0  # QTouch DEF_DRIFT_HOLD_TIME


class DriftTracker:
    """Adapt a baseline (T,) counts in place on quiet frames (see the module docstring)."""

    def __init__(
        self,
        tau_s: float,
        threshold_counts: float,
        guard_counts: float | None = None,
        hold_s: float = HOLD_S,
    ):
        if not (tau_s > 0 and math.isfinite(tau_s)):
            raise FrameError(
                f"drift time constant: expected a finite number of seconds > 0, got {tau_s:g}"
            )
        self.tau_s = float(tau_s)
        self.rate: float | None = None  # fraction per quiet frame (`per_frame`), else tau
        self.follow_below = True  # counts below the baseline are followed while frozen
        self.guard = (
            GUARD_FRACTION * threshold_counts if guard_counts is None else float(guard_counts)
        )
        self.hold_s = float(hold_s)
        self.last_t: float | None = None
        self.last_active = -math.inf  # host time of the last frame above the guard
        self.adapted = 0  # frames that moved the baseline
        self.frozen = 0  # frames that did not (above the guard or in the hold time)

    @classmethod
    def per_frame(cls, rate: float) -> DriftTracker:
        """A tracker moving the baseline by the fraction `rate` (0-1) of C - C0 on every
        frame its caller calls quiet (``update(..., active=False)``); no hold time, and
        nothing moves on an active frame."""
        tracker = cls(1.0, 0.0, hold_s=0.0)
        tracker.tau_s, tracker.rate, tracker.follow_below = math.nan, float(rate), False
        return tracker

    def reset(self) -> None:
        """After a new baseline (reconnect): no history."""
        self.last_t, self.last_active = None, -math.inf

    def update(
        self,
        baseline: np.ndarray,
        values: np.ndarray,
        t_s: float,
        ignore: np.ndarray | None = None,
        active: bool | None = None,
    ) -> bool:
        """One frame's taxel counts (T,) at host time t_s; -> True if it adapted.
        `ignore` (T,) bool: taxels that cannot freeze the tracker (flagged stuck,
        saturated, dead or noisy: not a hand; they are still tracked). `active`: the
        caller's own verdict on the frame, instead of the guard test."""
        if self.rate is not None:  # per frame: the caller says whether the frame is quiet
            if active:
                self.frozen += 1
                return False
            baseline += self.rate * (values - baseline)
            self.adapted += 1
            return True
        dt = 0.0 if self.last_t is None else max(t_s - self.last_t, 0.0)
        self.last_t = t_s
        d = values - baseline
        if active is None:
            near = d > self.guard
            if ignore is not None:
                near &= ~ignore
            active = bool(near.any())
        if active:
            self.last_active = t_s
        if active or t_s - self.last_active < self.hold_s:
            low = d < 0  # below the baseline: follow it even while frozen
            if self.follow_below and low.any() and dt > 0:
                baseline[low] += -math.expm1(-dt / self.tau_s) * d[low]
            self.frozen += 1
            return False
        if dt > 0:
            baseline += -math.expm1(-dt / self.tau_s) * d
        self.adapted += 1
        return True

    def state(self) -> str:
        if self.rate is not None:
            return (
                f"drift tracking {self.rate:g} per quiet frame: {self.adapted} frames "
                f"adapted, {self.frozen} frozen"
            )
        return (
            f"drift tracking tau {self.tau_s:g} s, guard {self.guard:g} counts: "
            f"{self.adapted} frames adapted, {self.frozen} frozen"
        )
