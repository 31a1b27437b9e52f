"""An estimate of the time a long loop has left, from its rate since a first mark (taken
after its first chunk, so that a first compile or a warm-up does not count)."""

from __future__ import annotations

import time


def time_left(
    first: tuple[float, int] | None, done: int, total: int, now: float | None = None
) -> str:
    """The text "; about N s left" at the rate since `first` = (perf_counter time, items
    done then), or "" while no rate is known or nothing is left."""
    if first is None or done <= first[1] or done >= total:
        return ""
    now = time.perf_counter() if now is None else now
    rate = (done - first[1]) / max(now - first[0], 1e-9)  # items per second
    return f"; about {(total - done) / rate:.0f} s left"
