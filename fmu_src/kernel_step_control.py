"""Step-size control of the Runge–Kutta steps: the limits on a step, the next step's proposal and the step cap (numba kernels).

The controller is the classical one (``SAFETY / err^(1/(q+1))`` within
``[MIN_FACTOR, MAX_FACTOR]``) with Gustafsson's predictive term used only to
shrink.  The nonsmooth places get their own limits: the stiff Hunt–Crossley
contact caps h to the explicit method's stability region, and a bit slowing to
a stop keeps the step short of the stop and, after it, out of the friction
layer, where the friction law is extrapolated.  Called from
:func:`.kernel_driver.advance` (the inlined pieces are documented there).
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import contact_stiffness, overlap
from .kernel_layouts import (CONTACT, CONTACT_STABILITY_LIMIT, ERRACC_FLOOR, F_ERRACC, F_H_MODE, F_HACC, F_V4_PEAK,
                             FREE, I_SWIN, I_SWIN_STEPS, LAYER_TARGET, MAX_FACTOR, MIN_FACTOR, P_MU, P_RHO, SAFETY,
                             SLIP, STOP_OVERSHOOT, STOP_SHRINK_FLOOR, TINY, V_BIT, V_HAMMER)
from .kernel_runge_kutta import friction_layer_err


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def err_root(x, e):
    """x ** e for the controller; DOP853's e = 1/8 as three square roots (cheaper than pow)."""
    if e == 0.125:
        return math.sqrt(math.sqrt(math.sqrt(x)))
    return x ** e


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def count_step(t1, period, istate, cap):
    """Count an accepted step in its forcing period; True when the cap is exceeded."""
    w = int(math.floor(t1 / period))
    if w != istate[I_SWIN]:
        istate[I_SWIN] = w
        istate[I_SWIN_STEPS] = 0
    istate[I_SWIN_STEPS] += 1
    return cap > 0.0 and istate[I_SWIN_STEPS] > cap


@njit(inline="always")
def limit_step(h, y, stages, p, ms, mc):
    """The proposed step ``h`` capped where an explicit step must stay short: stiff contact
    and a bit decelerating to a stop (``stages[0]``: the rate at the step start)."""
    if mc != FREE:
        # stiff contact: keep h within the explicit method's
        # stability region, h omega_c <= 1.5, omega_c^2 = dF_c/dd / m_eff
        dpen = overlap(y, p)
        if dpen > 0.0:
            # the damping only stiffens the contact while it closes (d' > 0); CLAMPED pulls nothing
            kcl = contact_stiffness(dpen, max(y[V_HAMMER] - y[V_BIT], 0.0) if mc == CONTACT else 0.0, p)
            minv = 1.0 + (1.0 / p[P_RHO] if ms == SLIP else 0.0)
            hcap = CONTACT_STABILITY_LIMIT / math.sqrt(kcl * minv + TINY)
            if h > hcap:
                h = hcap
    if ms == SLIP and stages[0, V_BIT] < 0.0 and y[V_BIT] > 0.0:
        # the bit decelerates to a stop: do not step far past the
        # predicted stop, where the friction law is extrapolated
        t_stop = -y[V_BIT] / stages[0, V_BIT]
        if h > STOP_OVERSHOOT * t_stop:
            h = max(STOP_OVERSHOOT * t_stop, STOP_SHRINK_FLOOR * h)
    return h


@njit(inline="always")
def next_step_size(h, err, rejected, modes, ends, p, fstate, method, ctl, n_act):
    """The step proposed after an accepted step ``h`` with error ``err`` (its history in
    ``fstate``, updated here); ``modes = (ms, mc)``, ``ends = (v4, f4)``: the bit's velocity
    and its rate at the step end; ``ctl = (rtol, atol, hmax, e_abs, err_exp)``."""
    ms, mc = modes
    v4, f4 = ends
    rtol, atol, _, e_abs, err_exp = ctl
    if err == 0.0:
        fac = MAX_FACTOR
    else:
        fac = min(MAX_FACTOR, SAFETY / err_root(err, err_exp))
        if fstate[F_ERRACC] > 0.0:
            # Gustafsson's predictive controller (as in Radau5), used
            # only to shrink: an error that grows from step to step
            # (the bit nearing its stop) is met before it rejects
            fg = fac * (h / fstate[F_HACC]) * err_root(fstate[F_ERRACC] / err, err_exp)
            fac = min(fac, max(fg, MIN_FACTOR))
    if rejected:
        fac = min(1.0, fac)
    if ms == SLIP and mc == FREE and fstate[F_ERRACC] == 0.0:
        # first step of a slip: the next slip starts with this step's successor
        # (the step that ended the slip came from the stop layer: far too small)
        fstate[F_H_MODE + SLIP] = h * fac
    fstate[F_HACC] = h
    fstate[F_ERRACC] = max(err, ERRACC_FLOOR)
    h_next = h * fac
    if ms == SLIP and f4 < 0.0 and v4 > 0.0 and p[P_MU] < 1.0:
        # the bit decelerates: keep the next step out of the friction layer
        sc4 = atol + rtol * max(v4, fstate[F_V4_PEAK])
        # a step whose friction error stays below the target: Newton steps on
        # ln h aimed a little below it (ln ef is convex in ln h, so they approach
        # from above and stop as soon as the target is met)
        for _ in range(8):
            ef, dlog = friction_layer_err(h_next, v4, f4, p, method, e_abs, n_act, sc4)
            if ef <= LAYER_TARGET:
                break
            h_next *= max(MIN_FACTOR, math.exp(math.log(0.5 * LAYER_TARGET / ef) / max(dlog, 1.0)))
    return h_next
