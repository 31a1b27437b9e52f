"""Python's cyclic garbage collector moved out of the frame path of the live loop.

Units: objects, collections. Left automatic, the collector runs whenever enough objects
were allocated, possibly in the middle of a frame, adding its time to that frame's
latency (in the latency bench's process on this loaded machine, gc callbacks timed young
collections at 0.4 ms on average and up to 10 ms, and full ones at 110-180 ms, most of
them while the bench made its frames). `FrameGC` freezes what start-up made (imports,
compiled kernels: never garbage), turns the automatic collector off, and collects after
a frame's outputs are sent, by CPython's default rule (generation 0 after 700
allocations, 1 after 10 of those, 2 after 10 of those), while the loop would wait for
the next line anyway.
"""

from __future__ import annotations

import gc

THRESHOLDS = (700, 10, 10)  # CPython's defaults


class FrameGC:
    """``with FrameGC() as g: ... g.after_frame()``: see the module docstring."""

    def __init__(self, thresholds: tuple[int, int, int] = THRESHOLDS):
        self.thresholds = thresholds
        self.collections = [0, 0, 0]
        self._was_enabled = gc.isenabled()

    def __enter__(self) -> FrameGC:
        gc.collect()
        gc.freeze()
        gc.disable()
        return self

    def after_frame(self) -> None:
        """Collect now if the automatic collector would have by now."""
        c0, c1, c2 = gc.get_count()
        t0, t1, t2 = self.thresholds
        if c0 < t0:
            return
        gen = 0
        if c1 + 1 >= t1:
            gen = 2 if c2 + 1 >= t2 else 1
        gc.collect(gen)
        self.collections[gen] += 1

    def __exit__(self, *exc: object) -> None:
        gc.unfreeze()
        if self._was_enabled:
            gc.enable()
