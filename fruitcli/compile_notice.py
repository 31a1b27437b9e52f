"""Announce numba's compiles: fruit's numerical kernels are compiled on their first use
after an install or an update, then loaded from numba's disk cache (`cache=True`): the
first run of make-tracks' reduction, compiling, took 20.8 s on 2 busy cores.

numba fires its "numba:compile" event only when it compiles (a kernel loaded from the
cache fires none), so the first such event is the one to announce, once per process; at
exit the time spent compiling is told too. numba itself is not imported here (it costs
about 0.3 s, which commands that never compile should not pay): the listener is
installed when some module first imports it.
"""

from __future__ import annotations

import atexit
import importlib.abc
import importlib.util
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from importlib.machinery import ModuleSpec
    from types import ModuleType

    from numba.core.event import Event as NumbaEvent

ANNOUNCE = (
    "compiling fruit's numerical kernels (numba), once after an install or update; "
    "later runs load them from numba's cache (the time it took is told at the end)"
)


class Notice:
    """Counts top-level compiles and their time; `say(line)` hears the first and the
    total at exit."""

    def __init__(self, say: Callable[[str], None]):
        self.say = say
        self.silent = False
        self.lock = threading.Lock()
        self.depth = threading.local()
        self.started: float | None = None
        self.seconds = 0.0
        self.kernels = 0

    def on_event(self, event: NumbaEvent) -> None:
        """numba's event listener: a compile's start and end (nested compiles, of the
        functions a kernel calls, count as part of it)."""
        depth = getattr(self.depth, "n", 0)
        if event.is_start:
            self.depth.n = depth + 1
            if depth == 0:
                self.depth.t0 = time.perf_counter()
                with self.lock:
                    first = self.started is None
                    if first:
                        self.started = time.perf_counter()
                if first and not self.silent:
                    self.say(ANNOUNCE)
        else:
            self.depth.n = max(depth - 1, 0)
            if depth == 1:
                with self.lock:
                    self.kernels += 1
                    self.seconds += time.perf_counter() - self.depth.t0

    def summary(self) -> None:
        if self.kernels and not self.silent:
            self.say(
                f"compiled {self.kernels} kernel(s) in {self.seconds:.1f} s; "
                "later runs load them from numba's cache"
            )


def _listen(notice: Notice) -> None:
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev: NumbaEvent) -> None:
            notice.on_event(ev)

        def on_end(self, ev: NumbaEvent) -> None:
            notice.on_event(ev)

    event.register("numba:compile", Listener())
    atexit.register(notice.summary)


class _AfterImport(importlib.abc.MetaPathFinder):
    """Finds nothing itself: on the first import of numba, lets the other finders load
    it, then installs the listener."""

    def __init__(self, notice: Notice):
        self.notice = notice

    def find_spec(
        self, name: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ):
        if name != "numba":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        loader, notice = spec.loader, self.notice

        class Then(importlib.abc.Loader):
            def create_module(self, spec: ModuleSpec):
                return loader.create_module(spec)

            def exec_module(self, module: ModuleType) -> None:
                if module.__spec__ is not None:
                    module.__spec__.loader = loader
                module.__loader__ = loader
                loader.exec_module(module)
                _listen(notice)

        spec.loader = Then()
        return spec


NOTICE: Notice | None = None
"""The process's notice, once `install` ran (the console entry point runs it)."""


def install(say: Callable[[str], None]) -> Notice:
    """Announce numba's compiles in this process through `say(line)` (once per process:
    a second call returns the first notice)."""
    global NOTICE
    if NOTICE is None:
        NOTICE = Notice(say)
        if "numba" in sys.modules:
            _listen(NOTICE)
        else:
            sys.meta_path.insert(0, _AfterImport(NOTICE))
    return NOTICE


def silence(quiet: bool) -> None:
    """--quiet: nothing said."""
    if NOTICE is not None:
        NOTICE.silent = quiet
