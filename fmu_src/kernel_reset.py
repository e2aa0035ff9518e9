"""The reset map of the hybrid model at an event (numba kernel)."""

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import contact_mode_at_impact, force_on_bit
from .kernel_layouts import (CLAMPED, CONTACT, EV_BOUNCE, EV_BOUNCE_END, EV_CLAMP, EV_IMPACT, EV_SEPARATION,
                             EV_SLIP_ON, EV_SLIP_START, EV_STICK, EV_UNCLAMP, FREE, F_IMPACT_V, F_PEAK,
                             F_V4_PEAK, F_X3_SLIP, I_BOUNCE, I_CONTACT, I_COUNT0, I_STICK, SLIP, STICK,
                             V_BIT, V_HAMMER, X_BIT)

@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def apply_event(kind, y, istate, fstate, p):
    """Apply the reset map of ``kind`` at the event state ``y`` (modified in place).

    Returns the kind actually taken (slip -> stick becomes EV_SLIP_ON when the
    drive still exceeds the static threshold).
    """
    mc = istate[I_CONTACT]
    if kind == EV_SLIP_START:
        istate[I_STICK] = SLIP
        y[V_BIT] = 0.0
        fstate[F_V4_PEAK] = 0.0
        fstate[F_X3_SLIP] = y[X_BIT]
    elif kind == EV_STICK:
        y[V_BIT] = 0.0
        # the drift only moves forward: no round-off step backwards
        if y[X_BIT] < fstate[F_X3_SLIP]:
            y[X_BIT] = fstate[F_X3_SLIP]
        if force_on_bit(y, p, mc) <= 1.0:
            istate[I_STICK] = STICK
            if force_on_bit(y, p, mc) < -1.0:
                istate[I_BOUNCE] = 1
                istate[I_COUNT0 + EV_BOUNCE] += 1
        else:
            kind = EV_SLIP_ON
    elif kind == EV_IMPACT:
        istate[I_CONTACT] = contact_mode_at_impact(y, p)
        fstate[F_IMPACT_V] = y[V_HAMMER] - y[V_BIT]
        fstate[F_PEAK] = 0.0
    elif kind == EV_SEPARATION:
        istate[I_CONTACT] = FREE
    elif kind == EV_CLAMP:
        istate[I_CONTACT] = CLAMPED
    elif kind == EV_UNCLAMP:
        istate[I_CONTACT] = CONTACT
    elif kind == EV_BOUNCE:
        istate[I_BOUNCE] = 1
    elif kind == EV_BOUNCE_END:
        istate[I_BOUNCE] = 0
    istate[I_COUNT0 + kind] += 1
    return kind
