"""The first event of a step: the watched indicators at its ends, their sign changes and the located event time (numba kernels).

The indicators watched in a mode (:mod:`.kernel_events`) are compared at the
two ends of a step; a sign change, or a grazing that the slopes reveal, is
located inside the step (:mod:`.kernel_localise`), and the earliest event wins.
A Runge–Kutta step and a chunk of the exact stick solution each have their own
loop on purpose: one loop shared by both measured 5-7 % slower (the per-path
constants no longer fold).  The groups ``rk``, ``sol``, ``work``, ``watch`` and
``kit`` are those of :func:`.kernel_driver.advance`.
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_events import drive_rate, watch_tol, watch_value, watch_value_drive, watched
from .kernel_forces import contact_force_at, force_on_bit, spring_damper_force
from .kernel_localise import locate_event, sign_change
from .kernel_runge_kutta import interpolant


@njit(inline="always")
def open_watch(istate, y, p, mc, carried, watch):
    """The indicators watched from ``y``: ``(their number, the first already positive (an
    immediate event) or -1)``.  ``carried``: their values at ``y`` carry from the last step's end."""
    kinds, w0s, w1s, s1s, wtols = watch
    nw = watched(istate, p, kinds)
    immediate = -1
    for q in range(nw):
        w0s[q] = w1s[q] if carried else watch_value(kinds[q], y, p, mc)
        if not carried:
            s1s[q] = math.nan
        wtols[q] = watch_tol(kinds[q], y, p)
        if w0s[q] > wtols[q]:
            immediate = kinds[q]
            break
    return nw, immediate


@njit(inline="always")
def rk_step_events(span, nw, n_act, field, ctx):
    """The first event inside the Runge–Kutta step ``span = (t, t1, h)`` to ``ynew``.

    Returns ``(kind or -1, its time, its indicator's tolerance, whether the dense
    output is ready, the contact force, the drive and its rate at the step end)``.
    """
    t, t1, h = span
    (tableau, method), sol, work, watch, kit, _, _, _ = ctx
    y, istate, _, _ = sol
    stages, stages2, interp, ynew, ytmp, ys, fs, act = work
    kinds, w0s, w1s, s1s, wtols = watch
    fixed, how_rk, _, _, no_act, _, bisect, graze, _, _ = kit
    p, _, mc, _ = field
    ns = tableau[3]
    hit_kind = -1
    t_hit = 0.0
    wtol_hit = 0.0
    # (the step group (t, y, h, how, interp, act, n_act) is built where it is passed, not once
    # per step: its arrays' reference counts cost about 3 % of a step that passes it nowhere)
    dense_ok = no_act > 0  # False, as a plain bool (see ``plain``)
    # the drive on the bit at the step end, for the drive indicators and the drive tracker
    f_contact1 = contact_force_at(ynew, p, mc)  # 0 out of contact
    d1 = spring_damper_force(ynew, p) + f_contact1  # = force_on_bit(ynew, p, mc)
    r1 = 0.0 if fixed else drive_rate(ynew, stages[ns], p, mc)  # (no grazing search in fixed steps)
    for q in range(nw):
        kd = kinds[q]
        w1s[q] = watch_value_drive(kd, ynew, p, mc, d1)
        code, s1s[q] = sign_change(kd, y, ynew, stages[0], stages[ns], p, mc, (w0s[q], w1s[q], wtols[q], s1s[q], r1),
                                   h, not fixed)
        if code == 0:
            continue
        dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                               ynew, tableau, method[5], stages, stages2, ytmp, istate, field)
        te = locate_event(kd, code, t1, (t, y, h, how_rk, interp, act, n_act),
                          (bisect, graze, wtols[q]), tableau, field,
                          (stages2, ytmp, ys, fs))
        if te > 0.0 and (hit_kind < 0 or te < t_hit):
            hit_kind = kd
            t_hit = te
            wtol_hit = wtols[q]
    return hit_kind, t_hit, wtol_hit, dense_ok, f_contact1, d1, r1


@njit(inline="always")
def stick_chunk_events(span, nw, n_act, field, ctx):
    """The first event inside the chunk of the exact stick solution ``span = (t, t1, h)`` to
    ``ynew`` (its rate in ``fs``): ``(kind or -1, its time, the drive and its rate at the end)``."""
    t, t1, h_chunk = span
    (tableau, _), sol, work, watch, kit, _, _, _ = ctx
    y = sol[0]
    stages, stages2, interp, ynew, ytmp, ys, fs, act = work
    kinds, w0s, w1s, s1s, wtols = watch
    _, _, how_stick, _, _, graze_stick, bisect, graze, _, _ = kit
    p, _, mc, _ = field
    hit_kind = -1
    t_hit = 0.0
    d1 = force_on_bit(ynew, p, mc)
    r1 = drive_rate(ynew, fs, p, mc)
    for q in range(nw):
        kd = kinds[q]
        w1s[q] = watch_value_drive(kd, ynew, p, mc, d1)
        code, s1s[q] = sign_change(kd, y, ynew, stages[0], fs, p, mc, (w0s[q], w1s[q], wtols[q], s1s[q], r1),
                                   h_chunk, graze_stick)
        if code == 0:
            continue
        te = locate_event(kd, code, t1, (t, y, h_chunk, how_stick, interp, act, n_act),
                          (bisect, graze, wtols[q]), tableau, field,
                          (stages2, ytmp, ys, ytmp))
        if te > 0.0 and (hit_kind < 0 or te < t_hit):
            hit_kind = kd
            t_hit = te
    return hit_kind, t_hit, d1, r1
