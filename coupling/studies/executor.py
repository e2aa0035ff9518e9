"""The one study engine: chunks of scenes run in process or on a Dask cluster.

Every study (``bifurcation``, ``sweep``, ``map``, ``optimize``) hands the
executor a *chunk function* and a list of items (scenes).  The executor cuts
the items into chunks of at least :attr:`ExecutorOptions.chunk_seconds` of
estimated work, runs the chunks and returns the results in the items' order.

* ``workers=1``: the chunks run here, one after the other, without Dask
  (debugging, small studies, tests; ``dask=True`` runs them on a 1-worker
  local cluster instead).
* otherwise a ``dask.distributed`` client: on the cluster at
  ``scheduler`` (or ``$DASK_SCHEDULER_ADDRESS``), else on a ``LocalCluster``
  of ``workers`` single-threaded worker *processes* (default: one per CPU).
  Each worker loads the compiled kernels from the on-disk cache once, when
  the client connects (:func:`warm_worker`); tasks never recompile.

Each item is computed independently of every other (a scene starts from
rest), so the results are identical, bit for bit, whatever the chunking and
the number or kind of workers.  On a cluster the chunks are planned for load
balance (:func:`chunk_plan`): each chunk is a spread-out sample of the items
(the cost of a scene varies over a grid: a cell in stick-slip costs much
more than one that stays stuck), and the chunks shrink from a few per worker
to the minimum size, submitted largest first, so the workers finish together.
A progress bar (tqdm) is drawn on stderr only when stderr is a terminal.  An
interrupted run (Ctrl-C) cancels its tasks and closes the local cluster, so no
worker process outlives it; the workers ignore the terminal's Ctrl-C (they are
forked from a fork server that ignores it), so only this process reports it.
"""
from __future__ import annotations

import contextlib
import logging
import math
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from typing import Callable, Optional, Sequence

import numpy as np

from hammerbit.model.validation import ParameterError

__all__ = ["ExecutorOptions", "Executor", "chunk_bounds", "chunk_plan", "warm_worker", "SCHEDULER_ENV"]

#: Environment variable naming an existing Dask scheduler (same as Dask's own).
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"


@dataclass(frozen=True, kw_only=True)
class ExecutorOptions:
    """Where and how a study runs (keyword-only).

    Attributes
    ----------
    workers : int, optional
        Local worker processes (default: the CPUs of this machine); ``1``
        runs in this process without Dask.  Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default
        ``$DASK_SCHEDULER_ADDRESS`` if set.
    progress : bool, optional
        Progress bar on stderr; default only when stderr is a terminal.
    chunk_seconds : float
        Least estimated work per task [s] (a chunk holds at least one item).
    dask : bool
        Run on Dask even with ``workers=1`` (a 1-worker local cluster), e.g.
        to measure Dask's own overhead against the in-process run.
    """

    workers: Optional[int] = None
    scheduler: Optional[str] = None
    progress: Optional[bool] = None
    chunk_seconds: float = 0.2
    dask: bool = False

    def __post_init__(self):
        if self.workers is not None and not (isinstance(self.workers, (int, np.integer))
                                             and 1 <= self.workers <= 4096):
            raise ParameterError("workers", self.workers, "an integer in [1, 4096]")
        if not (isinstance(self.chunk_seconds, (int, float)) and 0 < self.chunk_seconds < 3600):
            raise ParameterError("chunk_seconds", self.chunk_seconds, "(0, 3600) s")

    @property
    def address(self) -> Optional[str]:
        """The scheduler address in use (option, else the environment), or None."""
        return self.scheduler or os.environ.get(SCHEDULER_ENV) or None

    @property
    def in_process(self) -> bool:
        """True when the study runs here, without Dask."""
        return self.address is None and self.workers == 1 and not self.dask

    @property
    def local_workers(self) -> int:
        return int(self.workers or os.cpu_count() or 1)


def chunk_bounds(n_items: int, cost_s: float, target_s: float) -> list:
    """``[(start, stop), ...]`` of contiguous chunks of about ``target_s`` work each.

    ``cost_s`` is the estimated work per item; every chunk holds at least one.
    """
    if n_items <= 0:
        return []
    size = max(1, int(math.ceil(target_s / max(cost_s, 1e-12))))
    return [(i, min(i + size, n_items)) for i in range(0, n_items, size)]


def chunk_plan(n_items: int, cost_s: float, target_s: float, workers: int) -> list:
    """Index arrays of the chunks of a cluster run, in submission order.

    The items are visited in a fixed pseudo-random order, so that every chunk
    is a spread-out sample of them and chunks of equal size cost about the
    same even where the cost per item varies along a grid.  Sizes follow
    guided self-scheduling: ``ceil(remaining / (2 workers))`` items, but at
    least ``target_s / cost_s`` (and one); the chunks come largest first, so
    the last ones, which set how evenly the workers finish, are the smallest.
    Items that each carry the target work on their own (``cost_s >=
    target_s``: nothing to amortise) are one chunk each, in their order.
    Every item is in exactly one chunk.
    """
    if n_items <= 0:
        return []
    least = max(1, int(math.ceil(target_s / max(cost_s, 1e-12))))
    if least == 1:
        return [np.array([i]) for i in range(n_items)]
    order = np.random.default_rng(20040101).permutation(n_items)
    plan, start = [], 0
    while start < n_items:
        size = max(least, int(math.ceil((n_items - start) / (2.0 * max(1, workers)))))
        plan.append(np.sort(order[start:start + size]))
        start += size
    return plan


#: Dask settings of a local cluster (scheduler, nannies, workers).  Its
#: processes share the machine's cores with the scenes, so the periodic
#: housekeeping is slowed down: no statistical profiler (a stack sample of
#: every thread every 10 ms), the event-loop tick, system monitor and the
#: nannies' memory check at 0.2 s, 1 s and 1 s instead of 20, 500 and 100 ms.
LOCAL_CLUSTER_CONFIG = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "200ms",
    "distributed.admin.system-monitor.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def warm_worker() -> str:
    """Load the solver's compiled kernels in this process (from the on-disk cache).

    Runs once on every worker when a client connects, so that no task pays for
    loading (or compiling) the kernels.  The executor knows no study: a chunk
    function's module (and its own small kernels) load with the first task
    that needs them.
    """
    from hammerbit.model.numba_target import runs_portable
    from hammerbit.model.presets import preset
    from hammerbit.model.stepping import Stepper
    g = preset("paper-fig9")
    if runs_portable() and not Stepper(g).load():
        # a worker of a master that drives FMUs (their portable CPU target) with nothing compiled
        # for that target: its tasks may never run the in-process solver, so it compiles nothing here
        return "ok"
    Stepper(g).advance(4 * g.period)        # the stepper's kernel
    return "ok"


@contextlib.contextmanager
def _sigint_deferred(*, inherit_ignored: bool = False):
    """A Ctrl-C while the block runs is raised when it ends (in the main thread; elsewhere a no-op).

    Interrupted half-way, ``LocalCluster()`` leaves a cluster that nobody can
    close but distributed's exit handler, which then fails with a traceback;
    deferred, the cluster is assigned first and closed by :meth:`Executor.close`.
    Around the cluster's shutdown, a Ctrl-C cannot cut it short and leave
    workers behind.

    With ``inherit_ignored``, processes started in the block inherit SIGINT
    ignored (``SIG_IGN`` survives ``exec``, and Python then leaves it alone):
    the fork server of :func:`_start_forkserver`.  The signal is blocked in this
    thread meanwhile, and Linux keeps a blocked signal pending even while it is
    ignored, so a Ctrl-C then is raised after the block; only one that the
    kernel hands to another thread of this process (a BLAS thread) during the
    server's fork and exec, a few milliseconds, is dropped.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    hits = []

    def record(signum, frame):
        hits.append(signum)

    old = signal.signal(signal.SIGINT, record)
    masked = inherit_ignored and hasattr(signal, "pthread_sigmask")
    try:
        if masked:
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        if inherit_ignored:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        yield
    finally:
        signal.signal(signal.SIGINT, record)
        if masked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})   # a pending one is recorded
        signal.signal(signal.SIGINT, old)
    if hits:
        raise KeyboardInterrupt


def _start_forkserver() -> bool:
    """Start multiprocessing's fork server with SIGINT ignored (once per process).

    The local cluster's workers are forked from it and get the server's
    signal handlers, so a Ctrl-C in the terminal, sent to the whole process
    group, interrupts only this process (which cancels the tasks and closes
    the cluster) instead of every worker printing its own
    ``KeyboardInterrupt`` traceback.  Only the server's own start (its fork
    and exec) runs with SIGINT ignored here, and a Ctrl-C meanwhile is raised
    after it (:func:`_sigint_deferred`).  False where the platform has no fork
    server (Windows): the workers are then spawned as usual.
    """
    import multiprocessing
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return False
    from multiprocessing import forkserver
    # nothing preloaded: the server would import the caller's __main__, which the workers never need
    forkserver.set_forkserver_preload([])
    with _sigint_deferred(inherit_ignored=True):
        forkserver.ensure_running()
    return True


def _run_chunk(fn, items, fixed):
    """Run one chunk; its results and the CPU time [s] it took in this worker."""
    c0 = time.process_time()
    res = fn(items, *fixed)
    return res, time.process_time() - c0


class Executor:
    """Runs chunk functions over items; a context manager around its Dask client.

    Parameters
    ----------
    options : ExecutorOptions

    Examples
    --------
    >>> with Executor(ExecutorOptions(workers=1)) as ex:
    ...     ex.run(chunk_fn, items, fixed=(groups,), cost_s=1e-3)   # doctest: +SKIP
    """

    def __init__(self, options: ExecutorOptions = ExecutorOptions()):
        self.options = options
        self.client = None
        self.cluster = None
        self.workers = 1
        self.setup_s = 0.0
        self.cpu_s = 0.0
        """CPU time [s] the chunks took, summed over the workers (all runs so far)."""

    # -- life cycle ---------------------------------------------------------
    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def connect(self) -> None:
        """Start or join the Dask cluster (no-op in process or when connected)."""
        if self.client is not None or self.options.in_process:
            return
        t0 = time.perf_counter()
        from dask.distributed import Client, LocalCluster
        addr = self.options.address
        if addr:
            try:
                self.client = Client(addr, timeout="10s")
            except (OSError, TimeoutError) as e:
                raise ParameterError("scheduler", addr, f"a reachable Dask scheduler ({e})") from None
        else:
            # ":0": the scheduler's HTTP server on a free port (8787 may be taken by another study)
            import dask
            method = "forkserver" if _start_forkserver() else "spawn"
            with dask.config.set({**LOCAL_CLUSTER_CONFIG, "distributed.worker.multiprocessing-method":
                                  method}), _sigint_deferred():
                # the nannies hand the config to their workers
                self.cluster = LocalCluster(n_workers=self.options.local_workers, threads_per_worker=1,
                                            processes=True, dashboard_address=":0",
                                            silence_logs=logging.CRITICAL)
            self.client = Client(self.cluster)
        self.client.run(warm_worker)
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        self.setup_s = time.perf_counter() - t0

    def close(self) -> None:
        """Close the client and the local cluster (its worker processes end)."""
        client, cluster = self.client, self.cluster
        self.client = self.cluster = None
        with _sigint_deferred() if cluster is not None else contextlib.nullcontext():
            try:
                if client is not None:
                    client.close(timeout=10)
            finally:
                if cluster is not None:
                    cluster.close(timeout=10)

    # -- running ----------------------------------------------------------
    def _progress(self, total: int, label: str):
        from tqdm import tqdm
        show = self.options.progress
        if show is None:
            show = sys.stderr.isatty()
        return tqdm(total=total, desc=label or None, unit="scene", file=sys.stderr, disable=not show,
                    dynamic_ncols=True, leave=False)

    def run(self, fn: Callable, items: Sequence, *, fixed: tuple = (), cost_s: float = 1e-3,
            label: str = "") -> list:
        """Run ``fn(chunk, *fixed)`` over chunks of ``items``; results in the items' order.

        Parameters
        ----------
        fn : callable
            A module-level function (picklable by reference) taking a list of
            items and the ``fixed`` arguments, returning a list with one
            result per item.
        items : sequence
            The scenes (small picklable objects).
        fixed : tuple
            Arguments shared by every chunk.
        cost_s : float
            Estimated work per item [s], for the chunk size.
        label : str
            Progress-bar label.

        Returns
        -------
        list
            One result per item.
        """
        items = list(items)
        bounds = chunk_bounds(len(items), cost_s, self.options.chunk_seconds)
        out: list = [None] * len(items)
        bar = self._progress(len(items), label)
        try:
            if self.options.in_process or len(bounds) <= 1 and self.options.address is None \
                    and self.client is None:
                for a, b in bounds:
                    res, cpu = _run_chunk(fn, items[a:b], fixed)
                    out[a:b] = res
                    self.cpu_s += cpu
                    bar.update(b - a)
                return out
            self.connect()
            from dask.distributed import as_completed
            plan = chunk_plan(len(items), cost_s, self.options.chunk_seconds, self.workers)
            futures = [self.client.submit(_run_chunk, fn, [items[i] for i in idx], fixed, pure=False,
                                          priority=len(plan) - k)          # largest first
                       for k, idx in enumerate(plan)]
            where = {f.key: idx for f, idx in zip(futures, plan)}
            try:
                for fut in as_completed(futures):
                    idx = where[fut.key]
                    res, cpu = fut.result()
                    for i, r in zip(idx, res):
                        out[i] = r
                    self.cpu_s += cpu
                    bar.update(len(idx))
            except BaseException:
                self.client.cancel(futures)
                raise
            return out
        finally:
            bar.close()
