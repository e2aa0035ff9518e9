"""Event localisation within a step: sign changes, grazing, safeguarded Newton and bisection (numba kernels).

Newton runs on the dense output or the exact stick solution
(``localise_newton``), bisection for the paper's fixed-step method
(``localise_bisect``); ``state_at`` evaluates the state inside the current
step whichever way the step was taken.
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_events import drive_rate, watch_slope, watch_slope_drive, watch_value
from .kernel_forces import contact_force_at, force_on_bit, rhs
from .kernel_layouts import (DRIVE_GATE, EPS, EV_BOUNCE, EV_IMPACT, F_PEAK, HOW_DENSE,
                             HOW_RESTEP, HOW_STICK)
from .kernel_runge_kutta import dense_eval, dense_eval_rate, rk_step
from .kernel_stick import stick_rate, stick_state

@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def state_at(tq, step, tableau, field, stages2, ytmp, out):
    """State at time ``tq`` inside the current ``step`` (its ``how``: HOW_*).

    Adaptive methods evaluate their dense output.  The fixed-step method (the
    paper's RK4 with bisection) re-integrates one step of length tq - t0
    (``stages2[0]`` must hold f(t0, y0)).  A stick chunk evaluates the exact solution.
    """
    t0, y0, h, how, interp, act, n_act = step
    if how == HOW_RESTEP:
        rk_step(t0, y0, tq - t0, tableau, stages2, out, ytmp, act, n_act, field)
    elif how == HOW_STICK:
        stick_state(tq, y0, interp, field[0], out)
    else:
        x = (tq - t0) / h
        dense_eval(x, y0, interp, act, n_act, out)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def localise_bisect(kind, ta, tb, tols, step, tableau, field, scratch):
    """The paper's localisation for the fixed-step method: bisection down to ``tol``
    (``tols = (tol, wtol)``).

    Each trial state is a fresh step of the method from (t0, y0) (``stages2[0]`` must
    hold f(t0, y0)).  Returns the end of the final bracket, where w > 0: after
    the reset the event cannot re-trigger.  (Adaptive methods use
    ``localise_newton``.)
    """
    tol, wtol = tols
    t0, y0, _, _, _, act, n_act = step
    stages2, ytmp, ys, _ = scratch
    p, _, mc, _ = field
    for it in range(200):
        if tb - ta <= tol:
            break
        tm = 0.5 * (ta + tb)
        rk_step(t0, y0, tm - t0, tableau, stages2, ys, ytmp, act, n_act, field)
        if watch_value(kind, ys, p, mc) - wtol > 0.0:
            tb = tm
        else:
            ta = tm
    return tb


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def state_rate_at(tq, step, p, ys, fs):
    """State and its rate at ``tq`` inside ``step``: exact stick solution or the dense output."""
    t0, y0, h, how, interp, act, n_act = step
    if how == HOW_STICK:
        sn = stick_state(tq, y0, interp, p, ys)
        stick_rate(ys, sn, p, fs)
    else:
        dense_eval_rate((tq - t0) / h, y0, interp, act, n_act, h, ys, fs)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def localise_newton(kind, ta, tb, wtol, step, p, mc, ys, fs):
    """Event time in (ta, tb] where w(ta) <= wtol < w(tb), by safeguarded Newton.

    Works on the exact stick solution or on the dense output; both give the
    indicator's slope along the curve at no extra cost, so
    Newton (kept inside the bracket, bisecting when it leaves it or every
    eighth step) needs a handful of evaluations where false position needs
    about twenty.  Returns the end of the final bracket, where w > 0, once
    the bracket is a few ulp wide.
    """
    state_rate_at(tb, step, p, ys, fs)
    wb = watch_value(kind, ys, p, mc) - wtol
    sb = watch_slope(kind, ys, fs, p, mc)
    state_rate_at(ta, step, p, ys, fs)
    wa = watch_value(kind, ys, p, mc) - wtol
    # start from the end whose Newton step stays inside the bracket, else the secant
    t = ta - wa * (tb - ta) / (wb - wa) if wb > wa else 0.5 * (ta + tb)
    if sb > 0.0:
        tn = tb - wb / sb
        if ta < tn < tb:
            t = tn
    if not (ta < t < tb):
        t = 0.5 * (ta + tb)
    for it in range(100):
        if tb - ta <= 4.0 * EPS * max(abs(tb), 1.0):
            break
        state_rate_at(t, step, p, ys, fs)
        w = watch_value(kind, ys, p, mc) - wtol
        if w > 0.0:
            tb = t
        else:
            ta = t
        if tb - ta <= 4.0 * EPS * max(abs(tb), 1.0):
            break
        sl = watch_slope(kind, ys, fs, p, mc)
        ulp2 = 2.0 * EPS * max(abs(t), 1.0)
        tn = t - w / sl if sl > 0.0 else 0.5 * (ta + tb)
        if w > 0.0 and tn > t - ulp2:
            tn = t - ulp2     # converged from above: probe just below
        elif w <= 0.0 and tn < t + ulp2:
            tn = t + ulp2     # converged from below: probe just above
        if not (ta < tn < tb) or it % 8 == 7:
            tn = 0.5 * (ta + tb)
        t = tn
    return tb


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def find_extremum(kind, t1, step, field, ys, fs):
    """Time in (t0, t1) where the slope of w changes from + to - (a local max of w);
    ``step`` starts at t0 and is evaluated by its ``how`` (stick solution or dense output)."""
    t0, y0, h, how, interp, act, n_act = step
    p, _, mc, _ = field
    ta = t0
    tb = t1
    for it in range(60):
        tm = 0.5 * (ta + tb)
        if how == HOW_STICK:
            stick_state(tm, y0, interp, p, ys)
        else:
            dense_eval((tm - t0) / h, y0, interp, act, n_act, ys)
        rhs(tm, ys, field, fs)
        if watch_slope(kind, ys, fs, p, mc) > 0.0:
            ta = tm
        else:
            tb = tm
        if tb - ta <= 1e-9 * (t1 - t0):
            break
    return 0.5 * (ta + tb)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def sign_change(kind, y, ynew, f0, f1, p, mc, w, h, graze_ok):
    """Sign-change detection of one indicator over a step.

    ``w = (w0, w1, wtol, s0, r1)``: the indicator at the step's ends (``watch_value``),
    its round-off level, its slope at the start (``watch_slope``, NaN if not
    known: then computed here when needed) and the drive's rate at the end
    (``drive_rate``; used only by the drive indicators).  The caller carries w1
    and the returned end slope on to the next step.

    Returns (code, s1): code 1 when the indicator ends above its round-off
    level (a crossing inside the step), 2 when its slope turns from + to - with
    a cheap Hermite estimate of the maximum near zero (a possible grazing
    extremum, only if ``graze_ok``), else 0; s1 the slope at the end (NaN when
    not needed).
    """
    w0, w1, wtol, s0, r1 = w
    if w1 > wtol or not graze_ok:
        return (1 if w1 > wtol else 0), math.nan
    s1 = watch_slope_drive(kind, ynew, f1, p, mc, r1)
    if not s1 < 0.0:
        return 0, s1
    if s0 != s0:
        s0 = watch_slope(kind, y, f0, p, mc)
    if s0 > 0.0 and hermite_peak(w0, w1, s0 * h, s1 * h) > -0.1 * (
            abs(w0) + abs(w1) + abs(s0 * h) + abs(s1 * h)):
        return 2, s1
    return 0, s1


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def locate_event(kind, code, t1, step, tols, tableau, field, scratch):
    """Event time of one indicator in (t0, t1] for a ``sign_change`` code, or -1.

    ``tols = (bisect_tol, graze, wtol)``; ``step``, ``tableau``, ``field`` and
    ``scratch = (stages2, ytmp, ys, fscr)`` are the groups of :mod:`.kernel_layouts`.

    A grazing candidate (code 2) counts only if the indicator's maximum inside
    the step exceeds max(graze, wtol); the event is then localised between the
    step start and that maximum.
    """
    bisect_tol, graze, wtol = tols
    t0, how = step[0], step[3]
    p, _, mc, _ = field
    stages2, ytmp, ys, fscr = scratch
    tb = t1
    if code == 2:
        tm = find_extremum(kind, t1, step, field, ys, fscr)
        state_at(tm, step, tableau, field, stages2, ytmp, ys)
        if watch_value(kind, ys, p, mc) <= max(graze, wtol):
            return -1.0
        tb = tm
    if how == HOW_STICK or how == HOW_DENSE:
        return localise_newton(kind, t0, tb, wtol, step, p, mc, ys, fscr)
    return localise_bisect(kind, t0, tb, (bisect_tol, wtol), step, tableau, field, scratch)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def peak_in_step(t1, step, field, ys, fs, fstate):
    """Contact force at the deepest penetration inside a step (d' changes sign), on its dense
    output, into ``fstate[F_PEAK]``."""
    t0, y0, h, _, interp, act, n_act = step
    dense = (t0, y0, h, plain(HOW_DENSE, n_act), interp, act, n_act)
    tm = find_extremum(plain(EV_IMPACT, n_act), t1, dense, field, ys, fs)
    dense_eval((tm - t0) / h, y0, interp, act, n_act, ys)
    f_contact = contact_force_at(ys, field[0], field[2])
    if f_contact > fstate[F_PEAK]:
        fstate[F_PEAK] = f_contact


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def drive_dips(d0, s0, d1, s1, d_min):
    """True when a step holds an interior minimum of the drive on the bit worth locating.

    ``d0``, ``d1`` are the drive at the step's ends, ``s0``, ``s1`` its rate
    there times the step, ``d_min`` the lowest drive so far (``d1`` included).
    The rate must turn from - to + and the cubic Hermite estimate of the minimum
    come near ``d_min`` (``drive_inside`` then locates it).
    """
    if not (s0 < 0.0 and s1 > 0.0):
        return False
    low = -hermite_peak(-d0, -d1, -s0, -s1)
    return low <= d_min + DRIVE_GATE * (abs(s0) + abs(s1))


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def drive_inside(t1, step, field, ys, fs, d_min):
    """The lowest drive so far, ``d_min``, lowered by the drive's minimum inside a step (its rate
    turns from - to +), on the dense output or the exact stick solution."""
    t0, y0, h, how, interp, act, n_act = step
    p, _, mc, _ = field
    tm = find_extremum(plain(EV_BOUNCE, n_act), t1, step, field, ys, fs)
    if how == HOW_STICK:
        stick_state(tm, y0, interp, p, ys)
    else:
        dense_eval((tm - t0) / h, y0, interp, act, n_act, ys)
    d = force_on_bit(ys, p, mc)
    return d if d < d_min else d_min


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def drive_before_event(t_hit, step, field, drive_start, ys, fs, d_min):
    """The lowest drive so far, ``d_min``, lowered by the drive's minimum inside ``[t0, t_hit]``,
    the part of a step (dense output or exact stick solution, ``step``'s interpolant ready) that
    ends on an event: a dip between two events would otherwise be seen at neither.
    ``drive_start = (drive, its rate)`` at ``t0``."""
    t0 = step[0]
    p, _, mc, _ = field
    state_rate_at(t_hit, step, p, ys, fs)
    d1 = force_on_bit(ys, p, mc)
    h = t_hit - t0
    if drive_dips(drive_start[0], drive_start[1] * h, d1, drive_rate(ys, fs, p, mc) * h, min(d_min, d1)):
        return drive_inside(t_hit, step, field, ys, fs, d_min)
    return d_min


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def hermite_peak(w0, w1, m0, m1):
    """Maximum over [0, 1] of the cubic Hermite interpolant of (w0, m0), (w1, m1).

    A cheap gate: the exact (dense-output) search for a grazing extremum runs
    only when this estimate comes near zero.
    """
    a = 6.0 * w0 + 3.0 * m0 - 6.0 * w1 + 3.0 * m1
    b = -6.0 * w0 - 4.0 * m0 + 6.0 * w1 - 2.0 * m1
    c = m0
    best = max(w0, w1)
    if a == 0.0:
        roots0 = -c / b if b != 0.0 else -1.0
        roots1 = -1.0
    else:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            return best
        sq = math.sqrt(disc)
        roots0 = (-b - sq) / (2.0 * a)
        roots1 = (-b + sq) / (2.0 * a)
    for x in (roots0, roots1):
        if 0.0 < x < 1.0:
            x2 = x * x
            x3 = x2 * x
            v = ((2 * x3 - 3 * x2 + 1) * w0 + (x3 - 2 * x2 + x) * m0
                 + (-2 * x3 + 3 * x2) * w1 + (x3 - x2) * m1)
            if v > best:
                best = v
    return best



@njit(cache=True, inline="always", _nrt=False, no_cpython_wrapper=True)
def plain(k, n):
    """The integer constant ``k`` as a plain int64 (``n``: any integer variable).

    numba compiles a callee once per literal value of an argument; a constant
    passed through ``plain`` lets every caller share one compiled callee
    (fewer specialisations to compile, the same results).
    """
    return k + 0 * n
