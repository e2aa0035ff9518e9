"""A transition of the hybrid model at an event: the reset map with its bookkeeping, the event log and the event cap (numba kernels).

After the state has reached an event, :func:`transition` closes the old mode
(its contact-force peak, its last step size), applies the reset map
(:mod:`.kernel_reset`), logs the event and counts it in its forcing period:
more than ``O_EVCAP`` events in one period is an event storm.  The new mode
starts with its own step-size history.
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import contact_force_at, force_on_bit
from .kernel_layouts import (CONTACT, EV_SEPARATION, EV_STICK, F_ERRACC, F_H_MODE, F_PEAK, F_T_STICK, FREE,
                             I_CONTACT, I_NLOG, I_STICK, I_WIN, I_WIN_EVENTS, L_KIND, L_PEAK, L_T, L_VREL,
                             L_X1, L_X2, L_X3, L_X4, SLIP, ST_DONE, ST_EVENT_STORM, STICK, V_BIT, V_HAMMER,
                             X_BIT, X_HAMMER)
from .kernel_reset import apply_event


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def step_slot(ms, mc):
    """Regime whose last step size is remembered: 0 stick, 1 slip, 2 contact."""
    if mc != FREE:
        return 2
    return ms


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def set_active(istate, n, act):
    """Indices of the integrated components: m2 is not integrated while it sticks."""
    k = 0
    for i in range(n):
        if istate[I_STICK] == STICK and (i == 2 or i == 3):
            continue
        act[k] = i
        k += 1
    return k


@njit(inline="always")
def log_event(log, t, taken, y, vrel, fstate, istate):
    """Write the event ``taken`` at ``t`` (the state after the reset) into the next row of ``log``."""
    r = istate[I_NLOG]
    log[r, L_T] = t
    log[r, L_KIND] = taken
    log[r, L_X1] = y[X_HAMMER]
    log[r, L_X2] = y[V_HAMMER]
    log[r, L_X3] = y[X_BIT]
    log[r, L_X4] = y[V_BIT]
    log[r, L_VREL] = vrel
    log[r, L_PEAK] = fstate[F_PEAK] if taken == EV_SEPARATION else 0.0
    istate[I_NLOG] = r + 1


@njit(inline="always")
def transition(kind, t, h, d_min, field, sol, kit, log, evcap):
    """The transition at the event ``kind`` at ``t`` (``y`` is there; ``h``: the step size
    of the mode left, ``d_min``: the lowest drive so far).

    Returns ``(status, h, d_min, d_y)``: ST_EVENT_STORM when the event exceeds the
    cap of its forcing period, else ST_DONE with the first step size of the new
    mode; ``d_y`` is the drive on the bit after the reset.
    """
    p, ms, mc, _ = field
    y, istate, fstate, _ = sol
    fixed, period = kit[0], kit[8]
    if mc == CONTACT:
        f_contact1 = contact_force_at(y, p, mc)
        if f_contact1 > fstate[F_PEAK]:
            fstate[F_PEAK] = f_contact1
    vrel = y[V_HAMMER] - y[V_BIT]
    if step_slot(ms, mc) != SLIP:
        fstate[F_H_MODE + step_slot(ms, mc)] = h
    taken = apply_event(kind, y, istate, fstate, p)
    fstate[F_ERRACC] = 0.0  # the new regime starts its own step-size history
    if taken == EV_STICK:
        fstate[F_T_STICK] = t
    d_y = force_on_bit(y, p, istate[I_CONTACT])
    if d_y < d_min:
        d_min = d_y
    if log.shape[0] > 0:
        log_event(log, t, taken, y, vrel, fstate, istate)
    win = int(math.floor(t / period))
    if win != istate[I_WIN]:
        istate[I_WIN] = win
        istate[I_WIN_EVENTS] = 0
    istate[I_WIN_EVENTS] += 1
    if istate[I_WIN_EVENTS] > evcap:
        return ST_EVENT_STORM, h, d_min, d_y
    slot = step_slot(istate[I_STICK], istate[I_CONTACT])
    if not fixed and fstate[F_H_MODE + slot] > 0.0:
        h = fstate[F_H_MODE + slot]
    return ST_DONE, h, d_min, d_y
