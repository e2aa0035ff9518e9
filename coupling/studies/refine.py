"""Local refinement of a constrained optimum: a compass search that closes in on the feasible boundary.

The ROP landscape of the hammer is piecewise smooth: steps where the period-n
changes, and constraints (the contact-force limit, ``a + b <= 1``, the
frequency windows, the scene's own flags) that often bind at the optimum.
A penalty method does not follow such a ridge.  :func:`pattern_search` moves
from a feasible start along the ``3**k - 1`` grid directions (the diagonals
too, so it can slide along a boundary that no axis follows) and accepts a
move only to a feasible, faster point; when no move improves it halves its
step.  A faster point cut off by a constraint is thus approached from the
feasible side by ever smaller steps, so the search ends on the active
constraint.  The result is the best feasible point seen, never worse than
the start.
"""
from __future__ import annotations

import itertools
import math
from typing import Callable

import numpy as np

__all__ = ["pattern_search", "MIN_STEP"]

#: The search stops when its step is below this fraction of every bound's span.
MIN_STEP = 1e-4


def pattern_search(evaluate: Callable, x0: np.ndarray, start, lo: np.ndarray, hi: np.ndarray,
                   step: np.ndarray, budget: int):
    """Best feasible point from ``start`` (a feasible candidate at ``x0``).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(x) -> candidate`` with ``.feasible`` (bool) and ``.rop_m_per_h``
        (float, NaN when the scene did not run).
    x0 : ndarray
        The start's variables.
    lo, hi : ndarray
        Bounds.
    step : ndarray
        First step per variable (one grid cell).
    budget : int
        Evaluations allowed.

    Returns
    -------
    candidate
        The best feasible candidate seen (``start`` if nothing beats it).
    """
    k = x0.size
    dirs = [np.array(d, dtype=float) for d in itertools.product((-1, 0, 1), repeat=k) if any(d)]
    best, x, h = start, np.array(x0, dtype=float), np.array(step, dtype=float)
    span = hi - lo
    used = 0

    def better(c):
        return c.feasible and math.isfinite(c.rop_m_per_h) and c.rop_m_per_h > best.rop_m_per_h

    while used < budget and np.any(h > MIN_STEP * span):
        improved = False
        for d in dirs:
            if used >= budget:
                break
            y = np.clip(x + d * h, lo, hi)
            if np.array_equal(y, x):
                continue
            c = evaluate(y)
            used += 1
            if better(c):
                best, improved = c, True
        if improved:
            x = np.array([best.values[n] for n in best.values], dtype=float)
        else:
            h = 0.5 * h
    return best
