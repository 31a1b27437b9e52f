"""Where independent tasks run: in this process, in local worker processes (`--jobs N`),
or on an existing Dask distributed cluster (`--scheduler ADDRESS`).

`run_graph` runs a small graph of tasks (a task starts once the tasks it depends on
have finished) on any of them and reports each result as its future finishes. A task
whose worker process dies is run again: by Dask's scheduler itself (up to its
`distributed.scheduler.allowed-failures`, 3 by default), and for local processes by
starting a fresh pool (up to `MAX_ATTEMPTS` times).

Ctrl-C is the parent's alone: local workers are started with SIGINT blocked (and ignore
it once running), so a Ctrl-C in the terminal, sent to every process of the group, prints
no worker's traceback; the parent stops its workers (`abort`) and says "Interrupted.".
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
import signal
import threading
from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from fruitcli.errors import FruitError

MAX_ATTEMPTS = 3  # a task whose local worker died this often is given up (as Dask's default)
K = TypeVar("K", bound=Hashable)  # a task graph's key

CONNECT_TIMEOUT_S = 10.0  # waiting for a Dask scheduler to answer, and for its workers


class WorkerLost(FruitError):
    """A task's worker process died every time it was tried."""


@dataclass
class Task:
    """`func(arg, results)` where results maps each of `deps` to its task's result.
    `func` must be a module-level function (it is pickled by reference)."""

    func: Callable
    arg: Any
    deps: tuple = ()
    attempts: int = field(default=0, compare=False)


def default_jobs() -> int:
    return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT held pending in this thread for the block (a process started inside it
    inherits the mask: it never sees Ctrl-C); a Ctrl-C that came is delivered after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _share_cores(jobs: int) -> None:
    """In a new worker: Ctrl-C ignored (the parent handles it), and the worker's share of
    the cores for numba's parallel element loops (jobs workers each running as many
    threads as there are cores would spin against each other; `fruitcli.fem.threads`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # ignored from now on
    import numba

    from fruitcli.fem import threads

    # numba.config sets its settings from the environment at import, out of mypy's sight
    most = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    numba.set_num_threads(max(1, min(most, (os.cpu_count() or 1) // jobs)))
    threads.AUTO = False  # the share holds; the solvers do not pick from the load


class Serial:
    """Run tasks here, one after the other."""

    name = "serial"

    def close(self) -> None:
        pass

    def abort(self) -> None:
        pass


class LocalPool:
    """`jobs` spawned worker processes on this machine."""

    def __init__(self, jobs: int):
        import multiprocessing as mp

        self.jobs = jobs
        self.name = f"{jobs} local processes"
        self._ctx = mp.get_context("spawn")
        self.pool = self._new()

    def _new(self):
        return cf.ProcessPoolExecutor(
            self.jobs, mp_context=self._ctx, initializer=_share_cores, initargs=(self.jobs,)
        )

    def submit(self, func: Callable[..., Any], *args: Any) -> cf.Future:
        with _sigint_blocked():  # a worker started here is deaf to Ctrl-C
            return self.pool.submit(func, *args)

    def lost(self, exc: BaseException) -> bool:
        return isinstance(exc, cf.process.BrokenProcessPool)

    def abort(self) -> None:
        """Ctrl-C: stop the workers now (they ignore SIGINT), so `close` need not wait for
        their tasks."""
        # the executor's own table of its processes (it offers no public one)
        for process in list((getattr(self.pool, "_processes", None) or {}).values()):
            with contextlib.suppress(OSError, ValueError, AttributeError):
                process.terminate()

    def renew(self) -> None:
        """A worker died: the pool is broken for every task in it; start a new one."""
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = self._new()

    def close(self) -> None:
        """Wait for the workers to end (their tasks are done, cancelled, or stopped by
        `abort`), with Ctrl-C held until they have: a pool left half shut down keeps its
        threads into the interpreter's exit, where they crashed it."""
        with _sigint_blocked():
            self.pool.shutdown(wait=True, cancel_futures=True)


class DaskPool:
    """The workers of a running Dask distributed scheduler (the client only connects)."""

    def __init__(self, address: str, timeout_s: float = CONNECT_TIMEOUT_S):
        try:
            from distributed import Client
        except ImportError:
            raise FruitError(
                "--scheduler needs the Dask extra: pip install 'fruit-touch[cluster]'"
            ) from None
        self.address = address
        _check_address(address)
        try:
            self.client = Client(address, timeout=timeout_s, set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise FruitError(
                f"--scheduler {address}: no Dask scheduler answered within "
                f"{timeout_s:g} s ({reason})"
            ) from None
        try:
            self.client.wait_for_workers(1, timeout=timeout_s)
        except (OSError, TimeoutError) as exc:
            self.client.close()
            raise FruitError(
                f"--scheduler {address}: the scheduler has no worker after "
                f"{timeout_s:g} s; start some (dask worker {address})"
            ) from exc
        workers = self.client.scheduler_info()["workers"]
        self.workers = len(workers)
        threads = max((w.get("nthreads", 1) for w in workers.values()), default=1)
        self.name = f"Dask scheduler {address} ({self.workers} workers)"
        if threads > 1:  # see fruitcli.studies.sweep_run.ONE_AT_A_TIME
            self.name += (
                f"; a worker with {threads} threads runs one sweep variant at a "
                "time: give workers one thread each and more processes"
            )
        self.executor = self.client.get_executor(pure=False)

    def submit(self, func: Callable[..., Any], *args: Any) -> cf.Future:
        return self.executor.submit(func, *args)

    def lost(self, exc: BaseException) -> bool:
        from distributed import KilledWorker

        return isinstance(exc, KilledWorker)

    def renew(self) -> None:
        pass  # the scheduler already reran the task on other workers

    def probe(self, out_dir: Path) -> None:
        """Refuse the cluster unless every worker sees `out_dir` (a file written here is
        read there) and runs the same fruit code as this machine."""
        import uuid

        token = uuid.uuid4().hex
        out_dir = Path(out_dir).resolve()
        out_dir.mkdir(parents=True, exist_ok=True)
        probe_file = out_dir / f".fruit-probe-{token}"
        probe_file.write_text(token)
        try:
            answers = self.client.run(see_probe, str(probe_file), token)
        except Exception as exc:
            raise FruitError(
                f"--scheduler {self.address}: the workers cannot run fruit "
                f"({type(exc).__name__}: {str(exc).splitlines()[0]}); install "
                "fruitcli on them"
            ) from None
        finally:
            probe_file.unlink(missing_ok=True)
        blind = sorted(f"{a} on {host}" for a, (seen, host, _) in answers.items() if not seen)
        if blind:
            raise FruitError(
                f"--out {out_dir}: not visible to {len(blind)} of {len(answers)} "
                f"workers ({', '.join(blind[:3])}); give an --out on a file "
                "system the workers share"
            )
        mine = code_hash()
        other = sorted(a for a, (_, _, h) in answers.items() if h != mine)
        if other:
            raise FruitError(
                f"--scheduler {self.address}: workers {', '.join(other[:3])} run "
                "a different fruit version than this machine; install the same "
                "one there"
            )

    def close(self) -> None:
        self.executor.shutdown(wait=False)
        self.client.close()

    def abort(self) -> None:
        pass  # closing does not wait for the cluster's tasks


def _check_address(address: str) -> None:
    """A malformed address is refused before a Client is made (a half-made one would
    print a traceback when collected)."""
    from distributed.comm import get_address_host_port

    try:
        get_address_host_port(address)
    except ValueError as exc:
        if "don't know how to extract" not in str(exc):  # inproc://, ucx:// are fine
            raise FruitError(
                f"--scheduler {address}: not a scheduler address ({exc}); expected tcp://host:port"
            ) from None


def see_probe(path: str, token: str) -> tuple[bool, str, str]:
    """On a worker: (does it read `token` at `path`, its host name, its fruit code hash)."""
    import socket

    try:
        seen = Path(path).read_text() == token
    except OSError:
        seen = False
    return seen, socket.gethostname(), code_hash()


def code_hash() -> str:
    """sha256 of the fruitcli package's sources (same on every machine of one install)."""
    import fruitcli
    from fruitcli.fsutil import file_hash_many

    root = Path(fruitcli.__file__).parent
    return file_hash_many(sorted(root.rglob("*.py")))


def open_executor(
    jobs: int | None = None,
    scheduler: str | None = None,
    out_dir: Path | None = None,
    timeout_s: float = CONNECT_TIMEOUT_S,
) -> Serial | LocalPool | DaskPool:
    """Serial (jobs 1), LocalPool (jobs N, default all cores) or DaskPool (scheduler);
    with a scheduler and `out_dir`, the workers must see `out_dir` (probed)."""
    if scheduler:
        pool = DaskPool(scheduler, timeout_s)
        if out_dir is not None:
            try:
                pool.probe(out_dir)
            except BaseException:
                pool.close()
                raise
        return pool
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    return Serial() if jobs == 1 else LocalPool(jobs)


def run_graph(
    pool: Serial | LocalPool | DaskPool,
    tasks: dict[K, Task],
    on_done: Callable[[K, Any], None] | None = None,
    on_lost: Callable[[K, str], Any] | None = None,
) -> dict[K, Any]:
    """Run `tasks` (in insertion order, each once its deps are done) on `pool`; returns
    key -> result. `on_done(key, result)` is called as each finishes. A task whose worker
    died `MAX_ATTEMPTS` times (or past Dask's own retries) gets `on_lost(key, message)`
    as its result, or raises `WorkerLost` without `on_lost`."""
    on_done = on_done or (lambda key, result: None)
    results: dict[K, Any] = {}
    if isinstance(pool, Serial):
        for key in _topological(tasks):
            task = tasks[key]
            results[key] = task.func(task.arg, {d: results[d] for d in task.deps})
            on_done(key, results[key])
        return results
    try:
        _run_pooled(pool, tasks, on_done, on_lost, results)
    except KeyboardInterrupt:
        pool.abort()
        raise
    return results


def _run_pooled(
    pool: LocalPool | DaskPool,
    tasks: dict[K, Task],
    on_done: Callable[[K, Any], None],
    on_lost: Callable[[K, str], Any] | None,
    results: dict,
) -> None:
    """`run_graph` on a pool of workers (local or Dask), filling `results`."""
    waiting = dict(tasks)
    running: dict[cf.Future, K] = {}

    def launch(key: K):
        task = tasks[key]
        task.attempts += 1
        running[pool.submit(task.func, task.arg, {d: results[d] for d in task.deps})] = key

    def launch_ready():
        for key in [k for k, t in waiting.items() if all(d in results for d in t.deps)]:
            del waiting[key]
            launch(key)

    launch_ready()
    while running:
        done, _ = cf.wait(list(running), return_when=cf.FIRST_COMPLETED)
        lost: list[tuple[K, BaseException | None]] = []
        for fut in done:
            key = running.pop(fut)
            exc = fut.exception()
            if exc is None:
                results[key] = fut.result()
                on_done(key, results[key])
            elif pool.lost(exc):
                lost.append((key, exc))
            else:
                raise exc
        if lost and isinstance(pool, LocalPool):  # every task in the broken pool is lost
            lost += [(running.pop(f), None) for f in list(running)]
            pool.renew()
        for key, exc in lost:
            task = tasks[key]
            if isinstance(pool, LocalPool) and task.attempts < MAX_ATTEMPTS:
                launch(key)
                continue
            message = (
                f"its worker process died {task.attempts} time(s)"
                if exc is None or isinstance(pool, LocalPool)
                else f"its worker died repeatedly ({exc})"
            )
            if on_lost is None:
                raise WorkerLost(f"task {key}: {message}")
            results[key] = on_lost(key, message)
            on_done(key, results[key])
        launch_ready()


def _topological(tasks: dict[K, Task]) -> list[K]:
    order, seen = [], set()

    def visit(key: K):
        if key in seen:
            return
        seen.add(key)
        for d in tasks[key].deps:
            visit(d)
        order.append(key)

    for key in tasks:
        visit(key)
    return order
