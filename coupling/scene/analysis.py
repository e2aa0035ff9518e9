"""The paper's analyses of one scene: period-n detection at the Poincaré
section and the largest Lyapunov exponent (chaos, Fig. 15).

Studies over many scenes (bifurcation diagrams, penetration sweeps, regime
maps, the ROP optimum) live in :mod:`hammerbit.studies`.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
from numba import njit

from hammerbit.model.params import Groups
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper

__all__ = ["relative_coordinates", "relative_rows", "detect_period", "period_n", "PERIOD_MAX", "PERIOD_TOL", "largest_lyapunov"]

#: Period detection: the largest period-n tried, and the relative tolerance of a repeat.
PERIOD_MAX = 32
PERIOD_TOL = 1e-5


@njit(cache=True, nogil=True)
def relative_rows(poin, n_rows, out):
    """Bounded coordinates (x1 - x3, x2 - x4, x4) of plain Poincaré rows ``poin[:n_rows]`` into ``out``."""
    for k in range(n_rows):
        out[k, 0] = poin[k, 1] - poin[k, 3]
        out[k, 1] = poin[k, 2] - poin[k, 4]
        out[k, 2] = poin[k, 4]


def relative_coordinates(poincare: np.ndarray) -> np.ndarray:
    """Bounded coordinates (x1 - x3, x2 - x4, x4) of Poincaré samples, shape (n, 3).

    ``poincare`` is a structured array (``simulate``'s ``POINCARE_DTYPE``) or
    plain rows ``[tau, x1, x2, x3, x4]`` of shape (n, 5).
    """
    p = poincare
    if p.dtype.names is not None:
        p = np.column_stack([np.zeros(len(p)), p["hammer_position"], p["hammer_velocity"],
                             p["bit_position"], p["bit_velocity"]])
    p = np.ascontiguousarray(p, dtype=np.float64)
    out = np.empty((len(p), 3))
    relative_rows(p, len(p), out)
    return out


@njit(cache=True, nogil=True)
def period_n(s, max_period, tol):
    """Period-n of the relative coordinates ``s`` (shape (n, 3)), 0 when none up to ``max_period``.

    The rule of :func:`detect_period`, compiled, so that a study can run it
    per scene without Python in between: the last half of the rows, the
    smallest n with ``|s[k + n] - s[k]| <= tol * (1 + |s[k + n]|)`` for every
    k and coordinate (a NaN never repeats).
    """
    start = s.shape[0] // 2
    m = s.shape[0] - start
    for n in range(1, max_period + 1):
        if m < 2 * n + 1:
            break
        ok = True
        for k in range(start, s.shape[0] - n):
            for c in range(s.shape[1]):
                a = s[k + n, c]
                if not (abs(a - s[k, c]) <= tol * (1.0 + abs(a))):
                    ok = False
                    break
            if not ok:
                break
        if ok:
            return n
    return 0


def detect_period(poincare: np.ndarray, *, max_period: int = PERIOD_MAX, tol: float = PERIOD_TOL) -> Optional[int]:
    """Period-n of the bounded motion from Poincaré samples.

    Uses the last half of the samples: the smallest n <= ``max_period`` with
    ``|s[k + n] - s[k]| <= tol * (1 + |s|)`` for every k there, where s are the
    relative coordinates (x1 - x3, x2 - x4, x4) (:func:`period_n`).

    Returns
    -------
    int or None
        n, or None when no period up to ``max_period`` fits (quasi-periodic,
        chaotic or not yet settled).
    """
    n = int(period_n(relative_coordinates(poincare), int(max_period), float(tol)))
    return n if n > 0 else None


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
