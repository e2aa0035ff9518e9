"""One step of the Runge–Kutta method proposed and tried: the fixed step, or the adaptive step with its rejections (numba kernels).

A trial step writes the step-end state into ``ynew`` and the stages into
``stages`` (``stages[0]``, the rate at the start, is given).  Whether the step
then ends at an event, and what is recorded, the driver decides
(:func:`.kernel_driver.advance`, which documents the groups ``rk``, ``sol``,
``work`` and ``ctl``).
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_layouts import (F_V4_PEAK, I_REJECTS, I_RHS, MIN_FACTOR, SAFETY, SLIVER_FLOORS, ST_DONE,
                             ST_STEP_TOO_SMALL, TIME_RESOLUTION)
from .kernel_runge_kutta import error_norm, rk_step
from .kernel_step_control import err_root, limit_step


@njit(inline="always")
def fixed_step(t, h, n_act, field, tableau, sol, work):
    """One step of the fixed-step method; False when its end state is not finite."""
    y, istate, _, _ = sol
    stages, _, _, ynew, ytmp, _, _, act = work
    rk_step(t, y, h, tableau, stages, ynew, ytmp, act, n_act, field)
    istate[I_RHS] += tableau[3]
    for i in range(y.shape[0]):
        if not math.isfinite(ynew[i]):
            return False
    return True


@njit(inline="always")
def adaptive_step(t, h, remaining, n_act, field, rk, sol, work, ctl):
    """The first step from ``t`` that the error control accepts, from the proposal ``h``.

    Returns ``(status, h, err, rejected)``: ST_STEP_TOO_SMALL when h falls below
    the time resolution, else ST_DONE with the accepted step, its error norm and
    whether a trial was rejected on the way.
    """
    tableau, method = rk
    y, istate, fstate, _ = sol
    stages, _, _, ynew, ytmp, _, _, act = work
    rtol, atol, hmax, _, err_exp = ctl
    p, ms, mc, _ = field
    n = y.shape[0]
    hmin = TIME_RESOLUTION * max(abs(t), 1.0)
    rejected = False
    err = 0.0
    h = limit_step(h, y, stages, p, ms, mc)
    while True:
        if h > hmax:
            h = hmax
        if h >= remaining or (not rejected and remaining - h < SLIVER_FLOORS * hmin):
            # never leave a sliver behind; after a rejection the step only
            # shrinks (snapping back to the whole remainder would retry the
            # rejected step forever when hmin is coarse, e.g. at a late start)
            h = remaining
        if h < hmin:
            return ST_STEP_TOO_SMALL, h, err, rejected
        rk_step(t, y, h, tableau, stages, ynew, ytmp, act, n_act, field)
        istate[I_RHS] += tableau[3]
        err = error_norm(y, ynew, h, stages, method, act, n_act, (rtol, atol, fstate[F_V4_PEAK]))
        finite = math.isfinite(err)
        if finite:
            for i in range(n):
                if not math.isfinite(ynew[i]):
                    finite = False
                    break
        if finite and err <= 1.0:
            return ST_DONE, h, err, rejected
        istate[I_REJECTS] += 1
        if not finite:
            h *= MIN_FACTOR
        else:
            h *= max(MIN_FACTOR, SAFETY / err_root(err, err_exp))
        rejected = True
