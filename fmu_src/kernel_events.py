"""The signed event indicators of a hybrid mode and their time derivatives (numba kernels).

Each watched indicator ``w`` is signed so that its event happens when ``w``
crosses from ``w <= 0`` to ``w > 0`` (``watch_value``, ``watch_slope``).
"""

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import (contact_damping_factor, contact_damping_factor_rate, contact_force_rate, force_on_bit,
                            overlap)
from .kernel_layouts import (CONTACT, EPS, EV_BOUNCE, EV_BOUNCE_END, EV_CLAMP, EV_IMPACT, EV_SEPARATION,
                             EV_SLIP_START, EV_STICK, EV_UNCLAMP, FREE, I_BOUNCE, I_CONTACT, I_STICK, P_CONTACT,
                             P_LAM, P_R, P_XI, STICK, V_BIT, V_HAMMER, X_BIT, X_HAMMER)

@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watched(istate, p, out):
    """Event kinds watched in the current mode; returns how many (<= 3) in ``out``."""
    n = 0
    if istate[I_STICK] == STICK:
        if istate[I_BOUNCE] == 0:
            out[n] = EV_SLIP_START
            n += 1
            out[n] = EV_BOUNCE
            n += 1
        else:
            out[n] = EV_BOUNCE_END
            n += 1
    else:
        out[n] = EV_STICK
        n += 1
    if p[P_CONTACT] > 0.0:
        mc = istate[I_CONTACT]
        if mc == FREE:
            out[n] = EV_IMPACT
            n += 1
        else:
            out[n] = EV_SEPARATION
            n += 1
            if p[P_LAM] > 0.0:
                out[n] = EV_CLAMP if mc == CONTACT else EV_UNCLAMP
                n += 1
    return n


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_value(kind, y, p, mode_c):
    """Signed indicator of ``kind``: the event happens when it becomes > 0."""
    if kind == EV_SLIP_START:
        return force_on_bit(y, p, mode_c) - 1.0
    if kind == EV_BOUNCE:
        return -(force_on_bit(y, p, mode_c) + 1.0)
    if kind == EV_BOUNCE_END:
        return force_on_bit(y, p, mode_c) + 1.0
    if kind == EV_STICK:
        return -y[V_BIT]
    if kind == EV_IMPACT:
        return overlap(y, p)
    if kind == EV_SEPARATION:
        return -overlap(y, p)
    if kind == EV_CLAMP:
        return -contact_damping_factor(y[V_HAMMER] - y[V_BIT], p)
    if kind == EV_UNCLAMP:
        return contact_damping_factor(y[V_HAMMER] - y[V_BIT], p)
    return -1.0


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_value_drive(kind, y, p, mode_c, d):
    """``watch_value`` given the drive on the bit at ``y``, ``d = force_on_bit(y, p, mode_c)``
    (the solver has it at every step end: the three drive indicators cost no force law)."""
    if kind == EV_SLIP_START:
        return d - 1.0
    if kind == EV_BOUNCE:
        return -(d + 1.0)
    if kind == EV_BOUNCE_END:
        return d + 1.0
    return watch_value(kind, y, p, mode_c)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_tol(kind, y, p):
    """Round-off level of ``watch_value``: an indicator counts as crossed only above it.

    The indicators subtract positions of order of the penetration (x1 - x3),
    so near a switch their computed value is noise of a few ulp of |x1| + |x3|.
    Without this threshold a separation followed by a re-impact inside the
    next step could chatter on that noise.
    """
    if kind == EV_STICK:
        return 0.0
    if kind == EV_CLAMP or kind == EV_UNCLAMP:
        return 8.0 * EPS * (1.0 + p[P_LAM] * (abs(y[V_HAMMER]) + abs(y[V_BIT])))
    r = p[P_R] if (kind == EV_IMPACT or kind == EV_SEPARATION) else 1.0
    return 8.0 * EPS * (abs(y[X_HAMMER]) + abs(y[X_BIT]) + abs(r))


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def drive_rate(y, f, p, mode_c):
    """Time derivative of the drive on the bit (``force_on_bit``) from ``y`` and its derivative ``f``."""
    dd = y[V_HAMMER] - y[V_BIT]
    ddd = f[V_HAMMER] - f[V_BIT]
    s = (f[X_HAMMER] - f[X_BIT]) + 2.0 * p[P_XI] * ddd
    if mode_c == CONTACT:
        s += contact_force_rate(overlap(y, p), dd, ddd, p)
    return s


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_slope_drive(kind, y, f, p, mode_c, r):
    """``watch_slope`` given the drive's rate at ``y``, ``r = drive_rate(y, f, p, mode_c)``."""
    if kind == EV_SLIP_START or kind == EV_BOUNCE_END:
        return r
    if kind == EV_BOUNCE:
        return -r
    return watch_slope(kind, y, f, p, mode_c)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_slope(kind, y, f, p, mode_c):
    """Time derivative of ``watch_value`` from the state ``y`` and its derivative ``f``."""
    if kind == EV_SLIP_START or kind == EV_BOUNCE or kind == EV_BOUNCE_END:
        s = drive_rate(y, f, p, mode_c)
        return -s if kind == EV_BOUNCE else s
    ddd = f[V_HAMMER] - f[V_BIT]
    if kind == EV_STICK:
        return -f[V_BIT]
    if kind == EV_IMPACT:
        return y[V_HAMMER] - y[V_BIT]
    if kind == EV_SEPARATION:
        return -(y[V_HAMMER] - y[V_BIT])
    if kind == EV_CLAMP:
        return -contact_damping_factor_rate(ddd, p)
    if kind == EV_UNCLAMP:
        return contact_damping_factor_rate(ddd, p)
    return 0.0

