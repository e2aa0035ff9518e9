"""The paper's analyses: period-n detection, bifurcation diagrams, penetration
sweeps (Fig. 14) and the largest Lyapunov exponent (chaos, Fig. 15).

A bifurcation sweep asks the kernels only for Poincaré points and never
allocates a trajectory.  Sweeps run in parallel threads: the numba driver
releases the GIL (``nogil=True``), so two cores do two parameter values at once.
"""
from __future__ import annotations

import math
import os
import sys
import time as _time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from hammerbit.model import kernels as K
from hammerbit.model.params import GROUP_NAMES, Groups, ParameterError
from hammerbit.model.stepping import SolverOptions, Stepper

from .simulate import simulate

__all__ = ["relative_coordinates", "detect_period", "bifurcation", "BifurcationResult",
           "penetration_sweep", "largest_lyapunov", "progress_bar"]


def relative_coordinates(poincare: np.ndarray) -> np.ndarray:
    """Bounded coordinates (x1 - x3, x2 - x4, x4) of Poincaré samples, shape (n, 3)."""
    p = poincare
    return np.column_stack([p["hammer_position"] - p["bit_position"],
                            p["hammer_velocity"] - p["bit_velocity"], p["bit_velocity"]])


def detect_period(poincare: np.ndarray, *, max_period: int = 32, tol: float = 1e-5) -> Optional[int]:
    """Period-n of the bounded motion from Poincaré samples.

    Uses the last half of the samples: the smallest n <= ``max_period`` with
    ``|s[k + n] - s[k]| <= tol * (1 + |s|)`` for every k there, where s are the
    relative coordinates (x1 - x3, x2 - x4, x4).

    Returns
    -------
    int or None
        n, or None when no period up to ``max_period`` fits (quasi-periodic,
        chaotic or not yet settled).
    """
    s = relative_coordinates(poincare)
    half = s[len(s) // 2:]
    m = len(half)
    for n in range(1, max_period + 1):
        if m < 2 * n + 1:
            break
        diff = np.abs(half[n:] - half[:-n])
        if np.all(diff <= tol * (1.0 + np.abs(half[n:]))):
            return n
    return None


def progress_bar(done: int, total: int, *, start: float, stream=None, width: int = 30) -> None:
    """Print a one-line progress bar with elapsed and remaining time (stderr)."""
    stream = stream or sys.stderr
    frac = done / total if total else 1.0
    el = _time.perf_counter() - start
    eta = el / frac - el if frac > 0 else float("nan")
    bar = "#" * int(width * frac) + "-" * (width - int(width * frac))
    stream.write(f"\r[{bar}] {done}/{total}  {el:6.1f}s elapsed, {eta:6.1f}s left")
    if done >= total:
        stream.write("\n")
    stream.flush()


@dataclass
class BifurcationResult:
    """Poincaré points of a sweep.

    Attributes
    ----------
    param : str
        Swept group name.
    values : ndarray, shape (m,)
        Parameter values.
    points : ndarray, shape (m, k, 5)
        The last k Poincaré samples [tau, x1, x2, x3, x4] for each value.
    periods : list of int or None
        Detected period-n for each value.
    drift : ndarray, shape (m,)
        Penetration per forcing period over the kept samples [x0].
    wall_time_s : float
        Wall time of the sweep.
    total_periods : int
        Forcing periods integrated in all.
    """

    param: str
    values: np.ndarray
    points: np.ndarray
    periods: list
    drift: np.ndarray
    wall_time_s: float
    total_periods: int

    @property
    def periods_per_second(self) -> float:
        return self.total_periods / self.wall_time_s if self.wall_time_s > 0 else float("nan")

    def to_csv(self, path) -> None:
        """One row per Poincaré point: value, tau, x1-x3, x2-x4, x4, x3."""
        rows = []
        for i, v in enumerate(self.values):
            P = self.points[i]
            for r in P:
                rows.append((v, r[0], r[1] - r[3], r[2] - r[4], r[4], r[3]))
        np.savetxt(path, np.array(rows), delimiter=",",
                   header=f"{self.param},tau,x1_minus_x3,x2_minus_x4,x4,x3", comments="")


def _poincare_run(groups, periods, keep, solver, phase):
    """Only the last ``keep`` Poincaré samples of a run from rest (no trajectory)."""
    T = groups.period
    st = Stepper(groups, solver=solver)
    start = max(periods - keep + 1, 0)
    st.opts[K.O_POIN_T0] = (start + phase) * T
    poin = np.zeros((keep, 5))
    st.advance(periods * T + (phase * T if phase > 0 else 0.0), poincare=poin)
    return poin[: int(st.istate[K.I_POIN_NEXT])]


def bifurcation(groups: Groups, param: str, values: Sequence[float], *, periods: int = 300,
                keep: int = 64, solver: SolverOptions = SolverOptions(), phase: float = 0.0,
                workers: Optional[int] = None, progress: bool = False) -> BifurcationResult:
    """Bifurcation diagram: Poincaré points against one group.

    Parameters
    ----------
    groups : Groups
        Base parameters.
    param : str
        Group to sweep (``a``, ``b``, ``eta``, ``r`` ...).
    values : sequence of float
        Values of ``param``.
    periods : int
        Forcing periods per value (from rest); the last ``keep`` are kept.
    keep : int
        Poincaré samples kept per value.
    solver : SolverOptions
        Integrator options.
    phase : float
        Poincaré phase, fraction of the period.
    workers : int, optional
        Threads (default: the number of CPUs).
    progress : bool
        Print a progress bar to stderr.

    Returns
    -------
    BifurcationResult
    """
    if param not in GROUP_NAMES:
        raise ParameterError("param", param, "one of " + ", ".join(GROUP_NAMES))
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size == 0:
        raise ParameterError("values", values, "a non-empty 1-D sequence")
    if not (isinstance(periods, (int, np.integer)) and periods >= 2):
        raise ParameterError("periods", periods, "an integer >= 2")
    keep = int(min(keep, periods))
    scenes = [groups.replace(**{param: float(v)}) for v in values]  # validates every value
    workers = workers or os.cpu_count() or 1
    _poincare_run(scenes[0], 1, 1, solver, phase)  # load the compiled kernels before timing
    out = np.full((values.size, keep, 5), np.nan)
    t0 = _time.perf_counter()
    done = 0
    with ThreadPoolExecutor(max_workers=workers) as ex:
        futs = {ex.submit(_poincare_run, g, periods, keep, solver, phase): i for i, g in enumerate(scenes)}
        from concurrent.futures import as_completed
        for f in as_completed(futs):
            i = futs[f]
            pts = f.result()
            out[i, : pts.shape[0]] = pts
            done += 1
            if progress:
                progress_bar(done, len(scenes), start=t0)
    wall = _time.perf_counter() - t0
    per = []
    drift = np.zeros(values.size)
    from .simulate import POINCARE_DTYPE
    for i in range(values.size):
        rec = np.rec.fromarrays(out[i].T, dtype=POINCARE_DTYPE).view(np.ndarray)
        per.append(detect_period(rec))
        drift[i] = (out[i, -1, 3] - out[i, 0, 3]) / max(keep - 1, 1)
    return BifurcationResult(param=param, values=values, points=out, periods=per, drift=drift,
                             wall_time_s=wall, total_periods=int(periods * values.size))


def penetration_sweep(groups: Groups, values: Sequence[float], *, param: str = "a", periods: int = 100,
                      solver: SolverOptions = SolverOptions(), workers: Optional[int] = None) -> np.ndarray:
    """Penetration x3 after ``periods`` forcing periods against one group (Fig. 14).

    Returns
    -------
    ndarray, shape (m,)
        Penetration [x0] for each value.
    """
    values = np.asarray(values, dtype=float)
    scenes = [groups.replace(**{param: float(v)}) for v in values]

    def one(g):
        return simulate(g, periods, solver=solver).penetration

    with ThreadPoolExecutor(max_workers=workers or os.cpu_count() or 1) as ex:
        return np.array(list(ex.map(one, scenes)))


def largest_lyapunov(groups: Groups, *, windows: int = 200, window_periods: int = 10, transient: int = 300,
                     delta0: float = 1e-9,
                     solver: SolverOptions = SolverOptions(rtol=1e-11, atol=1e-13)) -> dict:
    """Largest Lyapunov exponent of the stroboscopic map from twin trajectories.

    After a transient, a copy of the reference trajectory is displaced by
    ``delta0`` in the hammer position (always a free coordinate, so the copy's
    hybrid modes stay consistent) and both are advanced ``window_periods``
    forcing periods; the growth of their separation in the bounded coordinates
    (x1 - x3, x2 - x4, x4) is logged.  Repeated over ``windows`` consecutive
    windows along the attractor, the mean log-growth per period estimates the
    exponent.  Per-period renormalisation (Benettin) is avoided on purpose:
    resetting a perturbed state next to a stick/slip or contact switch makes the
    map look discontinuous and biases the estimate.

    Returns
    -------
    dict
        ``lambda_per_period``, ``lambda_per_tau``, ``history`` (running
        estimate after each window, shape (windows,)), ``growth`` (log-growth
        of each window).
    """
    T = groups.period
    ref = Stepper(groups, solver=solver)
    ref.advance(transient * T)
    per = Stepper(groups, solver=solver)

    def rel(y):
        return np.array([y[0] - y[2], y[1] - y[3], y[3]])

    growth = np.zeros(windows)
    hist = np.zeros(windows)
    for k in range(windows):
        per.set_state(ref.get_state())
        per.y[0] += delta0
        d0 = float(np.linalg.norm(rel(per.y) - rel(ref.y)))
        t_next = (transient + (k + 1) * window_periods) * T
        ref.advance(t_next)
        per.advance(t_next)
        d = max(float(np.linalg.norm(rel(per.y) - rel(ref.y))), 1e-300)
        growth[k] = math.log(d / d0)
        hist[k] = growth[: k + 1].mean() / window_periods
    lam = float(growth.mean() / window_periods)
    return {"lambda_per_period": lam, "lambda_per_tau": lam / T, "history": hist, "growth": growth}
