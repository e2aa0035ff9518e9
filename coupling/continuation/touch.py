"""Boundaries where an indicator's extremum along the periodic orbit touches zero (grazing, sliding, tension and bounce onset): located along a branch and followed in two parameters.

These boundaries are not zeros of a test function of the multipliers
(:mod:`.boundary`) but of an indicator along the orbit, a continuous function
of the parameters on both sides though not a smooth one of the orbit:

``grazing``
    an impact appears or disappears: the largest contact overlap
    ``max_t (x1 - x3 - r)`` crosses zero (negative: the gap stays open;
    positive: the peak overlap of an impact);
``sliding``
    a stick phase appears (or one splits by a short slip): on the side
    without it, the margin to it, the smallest interior minimum of the bit
    velocity in slip or of ``1 - drive`` in stick; on the side with it, minus
    the new phase's duration (:func:`sliding_indicator`);
``tension``
    the spring starts to pull the bit: the smallest drive on the bit
    ``min_t (f_k + f_c)`` crosses zero (the library's Stepper tracks it,
    locating each dip between its steps);
``bounce``
    the stuck bit's drive would need the rock to pull it back (the regime
    verdict's bounce: ``F_d < -F_s`` while stuck): the smallest drive plus the
    static threshold over the stick phases, ``min_{stuck} (f_k + f_c) + 1``,
    crosses zero (:func:`bounce_margin`; the same tracker, reset at each stick
    and slip event of the orbit).

The periodic-orbit system is augmented with the indicator,

    P^n(s, q; w) - s = 0,      indicator(s, q, w) = 0,

and solved at each value ``w`` of the second parameter by elimination: the
orbit by Newton's method on the map at fixed ``(q, w)`` (:func:`.correct_orbit`),
the first parameter ``q`` by Brent's method on the indicator, in a bracket
around the secant through the curve's last two points.

The largest overlap is read off the orbit sampled :data:`SAMPLES_PER_PERIOD`
times a period, sampled again :data:`FINE_SAMPLES` times around the largest
sample, and refined there by the cubic Hermite interpolant of ``d`` and
``d' = x2 - x4`` (error ~ h^4: below 1e-12 even inside a stiff contact).
"""
from __future__ import annotations

import math
from typing import Callable, Optional

import numpy as np
from scipy.optimize import brentq

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.stepping import Stepper

from .bifurcation import Bifurcation
from .boundary import Curve
from .continuation import JOIN_TOL
from .monodromy import ORBIT_SOLVER, ContinuationError, period_map
from .orbit import PeriodicOrbit, correct_orbit
from .parameter import Parameter

__all__ = ["max_overlap", "min_drive", "bounce_margin", "INDICATORS", "detect_touches", "follow_touch",
           "SAMPLES_PER_PERIOD", "BRACKET_STEP", "ROOT_TOL"]

#: samples of the orbit per forcing period when looking for the largest overlap
SAMPLES_PER_PERIOD = 2000
#: samples over the two sample intervals around the coarse maximum
FINE_SAMPLES = 400
#: first half-width (scaled first parameter) of the bracket searched around the predicted point
BRACKET_STEP = 1e-5
#: doublings of the bracket's half-width before the point counts as lost
BRACKET_DOUBLINGS = 14
#: a stick or slip phase shorter than this fraction of a forcing period at a located sliding point is the one
#: being born
NEW_PHASE = 1e-2
#: the indicator's value (sign of the far side) where a family that ends at its boundary has no orbit
ENDED = 1e-12
#: halvings of a step in the second parameter before the curve stops
MAX_HALVINGS = 5
#: Brent's tolerance on the scaled first parameter
ROOT_TOL = 1e-10


def _hermite_max(h, d0, d1, v0, v1) -> float:
    """The largest value of the cubic Hermite interpolant on [0, h] of values d0, d1 and slopes v0, v1."""
    # d(t) = d0 + v0 t + c2 t^2 + c3 t^3
    c2 = (3 * (d1 - d0) / h - 2 * v0 - v1) / h
    c3 = (v0 + v1 - 2 * (d1 - d0) / h) / h ** 2
    best = max(d0, d1)
    # roots of d'(t) = v0 + 2 c2 t + 3 c3 t^2 inside the interval
    if abs(c3) > 1e-300:
        disc = c2 * c2 - 3 * c3 * v0
        roots = [(-c2 + sgn * math.sqrt(disc)) / (3 * c3) for sgn in (1.0, -1.0)] if disc >= 0 else []
    elif abs(c2) > 1e-300:
        roots = [-v0 / (2 * c2)]
    else:
        roots = []
    for t in roots:
        if 0.0 <= t <= h:
            best = max(best, d0 + v0 * t + c2 * t * t + c3 * t ** 3)
    return best


def max_overlap(orbit: PeriodicOrbit) -> float:
    """The largest contact overlap ``x1 - x3 - r`` along the orbit over its period [x0].

    Raises
    ------
    ValueError
        The scene has no gap (r infinite): there is no contact to graze.
    """
    g = orbit.groups
    if not math.isfinite(g.r):
        raise ValueError("the scene has no gap (r = inf): no contact to graze")
    t_end = orbit.period * g.period
    times = np.linspace(0.0, t_end, SAMPLES_PER_PERIOD * orbit.period + 1)
    k = int(np.argmax(_overlap_samples(orbit, times)[0]))
    # the maximum lies within a sample interval of sample k: sampled again finely there (a contact is stiff:
    # the overlap's higher derivatives are large, the coarse interpolant would be off by 1e-9)
    fine = np.linspace(times[max(k - 1, 0)], times[min(k + 1, times.size - 1)], FINE_SAMPLES + 1)
    d, v = _overlap_samples(orbit, fine)
    h = fine[1] - fine[0]
    j = int(np.argmax(d))
    best = float(d[j])
    for i in (j - 1, j):
        if 0 <= i < fine.size - 1:
            best = max(best, _hermite_max(h, d[i], d[i + 1], v[i], v[i + 1]))
    return best


def _orbit_samples(orbit: PeriodicOrbit, times: np.ndarray) -> np.ndarray:
    """The library's sample rows of the orbit at ``times`` (from phase 0)."""
    samples = np.zeros((times.size, KL.N_SAMPLE_COLS))
    st = Stepper(orbit.groups, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False)
    try:
        st.advance(times[-1], sample_times=times, samples=samples)
    except SolverError as e:
        raise ContinuationError(f"the orbit could not be sampled: {e}") from None
    return samples


def _overlap_samples(orbit: PeriodicOrbit, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The overlap d = x1 - x3 - r and its rate x2 - x4 along the orbit at ``times`` (from phase 0)."""
    samples = _orbit_samples(orbit, times)
    return samples[:, 0] - samples[:, 2] - orbit.groups.r, samples[:, 1] - samples[:, 3]


def min_drive(orbit: PeriodicOrbit) -> float:
    """The smallest drive on the bit ``f_k + f_c`` along the orbit over its period [F_s]."""
    st = Stepper(orbit.groups, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False)
    try:
        st.advance(orbit.period * orbit.groups.period)
    except SolverError as e:
        raise ContinuationError(f"the orbit could not be integrated: {e}") from None
    return float(st.fstate[KL.F_DRIVE_MIN])


def bounce_margin(orbit: PeriodicOrbit) -> float:
    """The smallest drive on the stuck bit plus the static threshold, ``min_{stuck} (f_k + f_c) + 1``, over the
    orbit's period [F_s]: negative where the verdict flags a bounce (the rock would have to pull the bit back).

    The orbit is integrated from one stick or slip event to the next with the Stepper's drive tracker reset at
    each; a phase counts as stuck by the bit's mode at its middle (robust to where the event lands on the
    phase's first step).

    Raises
    ------
    ValueError
        The orbit never sticks: there is no stuck bit to bounce.
    """
    g = orbit.groups
    t_n = orbit.period * g.period
    kinds = orbit.events[:, KL.L_KIND].astype(int)
    switches = orbit.events[(kinds == KL.EV_STICK) | (kinds == KL.EV_SLIP_START), KL.L_T]
    bounds = np.unique(np.concatenate([[0.0], switches[(switches > 0.0) & (switches < t_n)], [t_n]]))
    st = Stepper(g, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False)
    lowest = math.inf
    try:
        for t0, t1 in zip(bounds[:-1], bounds[1:]):
            st.fstate[KL.F_DRIVE_MIN] = math.inf
            st.advance(0.5 * (t0 + t1))
            stuck = st.istate[KL.I_STICK] == KL.STICK
            st.advance(t1)
            if stuck:
                lowest = min(lowest, float(st.fstate[KL.F_DRIVE_MIN]))
    except SolverError as e:
        raise ContinuationError(f"the orbit could not be integrated: {e}") from None
    if lowest == math.inf:
        raise ValueError("the orbit never sticks: no stuck bit to bounce")
    return lowest + 1.0


#: the indicators by boundary kind, and what their zero means
INDICATORS = {"grazing": (max_overlap, "the contact overlap's maximum touches zero (an impact appears)"),
              "tension": (min_drive, "the drive's minimum on the bit touches zero (the spring starts to pull it)"),
              "bounce": (bounce_margin, "the drive's minimum on the stuck bit touches -F_s (the rock would have to "
                                        "pull it back: a bounce)")}


def _phase_durations(orbit: PeriodicOrbit) -> np.ndarray:
    """The durations of the orbit's stick and slip phases over its period (cyclic)."""
    kinds = orbit.events[:, KL.L_KIND].astype(int)
    starts = orbit.events[(kinds == KL.EV_STICK) | (kinds == KL.EV_SLIP_START), KL.L_T]
    if starts.size == 0:
        return np.array([np.inf])
    t_n = orbit.period * orbit.groups.period
    return np.diff(np.concatenate([starts, [starts[0] + t_n]]))


def _stick_margin(orbit: PeriodicOrbit) -> float:
    """How far the orbit is from a new stick or slip phase: the smallest interior minimum of the bit velocity
    in slip, or of ``1 - drive`` in stick (the drive's interior maxima below the static threshold 1)."""
    g = orbit.groups
    times = np.linspace(0.0, orbit.period * g.period, SAMPLES_PER_PERIOD * orbit.period + 1)
    samples = _orbit_samples(orbit, times)
    slip = samples[:, 6] == KL.SLIP
    drive = samples[:, 0] - samples[:, 2] + 2 * g.xi * (samples[:, 1] - samples[:, 3]) + samples[:, 4]
    margin = np.where(slip, samples[:, 3], 1.0 - drive)
    inner = (slip[1:-1] == slip[:-2]) & (slip[1:-1] == slip[2:])  # both neighbours in the same mode
    m = margin[1:-1]
    local = inner & (m <= margin[:-2]) & (m <= margin[2:])
    return float(np.min(m[local])) if np.any(local) else np.inf


def sliding_indicator(orbit: PeriodicOrbit) -> Callable[[PeriodicOrbit], float]:
    """The signed indicator of the stick/slip phase count change at ``orbit`` (a located ``sliding`` point).

    With ``k`` the lower count of stick phases: positive on the side with ``k`` (the margin to a new phase,
    :func:`_stick_margin`), minus the shortest phase's duration on the side with ``k + 1``; both tend to
    zero where the new phase is born.
    """
    count = int(np.sum(orbit.events[:, KL.L_KIND].astype(int) == KL.EV_STICK))
    # at a located point the phase being born is far shorter than the others
    k = count - 1 if np.min(_phase_durations(orbit)) < NEW_PHASE * orbit.groups.period else count

    def indicator(orb: PeriodicOrbit) -> float:
        c = int(np.sum(orb.events[:, KL.L_KIND].astype(int) == KL.EV_STICK))
        if c == k:
            return _stick_margin(orb)
        if c == k + 1 and np.min(_phase_durations(orb)) < NEW_PHASE * orb.groups.period:
            return -float(np.min(_phase_durations(orb)))
        raise ContinuationError(f"the orbit has {c} stick phases, not {k} or {k + 1} with a new short phase")
    # the orbits with the new phase often exist only in a narrow window past the boundary (the family
    # ends at a non-smooth fold there): where none converges counts as past the boundary
    indicator.ends_at_boundary = True
    return indicator


def _indicator_at(fn: Callable, g: Groups, s_guess: np.ndarray, n: int) -> tuple[float, PeriodicOrbit]:
    orb = correct_orbit(g, s_guess, n)
    for m in range(1, n):
        # Newton's method on the period-n map may land on an orbit of a period dividing n: another family
        if n % m == 0:
            back = period_map(g, orb.s, m, jacobian=False).s_end
            if back.shape == orb.s.shape and np.max(np.abs(back - orb.s)) < JOIN_TOL:
                raise ContinuationError(f"the period-{n} orbit has joined the period-{m} orbit")
    return fn(orb), orb


def detect_touches(param: Parameter, base: Groups, points: list, branch_index: int,
                   kinds: tuple = ("tension",)) -> list[Bifurcation]:
    """The zeros of the ``kinds`` indicators between consecutive points of a branch, located by Brent's method
    in the parameter (each trial the branch's orbit corrected from the two points' interpolation).

    Grazing is located by :func:`.bifurcation.detect` (an impact event appears); tension has no event.
    """
    found = []
    for kind in kinds:
        fn = INDICATORS[kind][0]
        try:
            vals = [fn(p.orbit) for p in points]
        except (ContinuationError, ValueError):
            continue
        for (a, b), fa, fb in zip(zip(points[:-1], points[1:]), vals[:-1], vals[1:]):
            if fa * fb >= 0 or a.orbit.s.shape != b.orbit.s.shape or a.value == b.value:
                continue
            state = {}

            def f(v, a=a, b=b):
                w = (v - a.value) / (b.value - a.value)
                val, state["orbit"] = _indicator_at(fn, param.at(base, v), (1 - w) * a.orbit.s + w * b.orbit.s,
                                                    a.orbit.period)
                return val
            lo, hi = sorted((a.value, b.value))
            try:
                v = brentq(f, lo, hi, xtol=ROOT_TOL * param.scale)
                f(v)
            except (ContinuationError, ValueError):
                continue
            found.append(Bifurcation(kind=kind, value=float(v), branch=branch_index, orbit=state["orbit"],
                                     detail=INDICATORS[kind][1]))
    return found


def _first_value(indicator: Callable, q_guess: float, ends_at_boundary: bool) -> tuple[float, float]:
    """(q, indicator(q)) at the predicted ``q_guess``; for a family that ends at its boundary, the nearest
    value on either side where its orbit exists when the prediction lies past the end."""
    try:
        return q_guess, indicator(q_guess)
    except ContinuationError:
        if not ends_at_boundary:
            raise
    step = BRACKET_STEP * max(1.0, abs(q_guess))
    for _ in range(BRACKET_DOUBLINGS):
        for q in (q_guess - step, q_guess + step):
            try:
                return q, indicator(q)
            except ContinuationError:
                pass
        step *= 2
    raise ContinuationError("no orbit of the family next to the predicted point")


def _point(fn: Callable, param: Parameter, param2: Parameter, base: Groups, n: int, w: float, q_guess: float,
           s_guess: np.ndarray) -> tuple[float, PeriodicOrbit]:
    """The boundary's point (q, orbit) at the scaled second parameter ``w``, near ``q_guess``."""
    state = {"s": s_guess, "sign": 0.0}

    def indicator(q):
        g = param2.at(param.at(base, q * param.scale), w * param2.scale)
        try:
            val, orb = _indicator_at(fn, g, state["s"], n)
        except ContinuationError:
            if not getattr(fn, "ends_at_boundary", False) or not state["sign"]:
                raise
            # the family ends just past its boundary (a non-smooth fold): no orbit counts as the other side
            return -state["sign"] * ENDED
        state["s"], state["orbit"] = orb.s, orb
        return val

    q_guess, f0 = _first_value(indicator, q_guess, getattr(fn, "ends_at_boundary", False))
    state["sign"] = math.copysign(1.0, f0)
    if f0 == 0.0:
        return q_guess, state["orbit"]
    s0 = state["s"]
    step = BRACKET_STEP * max(1.0, abs(q_guess))
    # each side marches outward from its last orbit (Newton's method from far away may not converge)
    last = {1.0: (q_guess, s0), -1.0: (q_guess, s0)}
    for _ in range(BRACKET_DOUBLINGS):
        for side in (1.0, -1.0):
            q = q_guess + side * step
            state["s"] = last[side][1]
            try:
                value = indicator(q)
            except ContinuationError:
                continue  # no orbit of the family here (it may end at a non-smooth fold): try further out
            if value * f0 < 0:
                lo, hi = sorted((last[side][0], q))
                state["s"] = last[side][1]
                q_root = brentq(indicator, lo, hi, xtol=ROOT_TOL * max(1.0, abs(q_guess)))
                indicator(q_root)
                return q_root, state["orbit"]
            last[side] = (q, state["s"])
        step *= 2
    raise ContinuationError(f"no boundary point within {step / 2:.3g} of the predicted {param.name}")


def _reach(fn: Callable, scene: tuple, prev: list, w_to: float, depth: int = 0) -> list:
    """The curve's points ``prev`` [(w, q, s, orbit)] extended to ``w_to``, halving the step in the second parameter
    (at most :data:`MAX_HALVINGS` times) where the point is not found from the secant's guess."""
    param, param2, base, n = scene
    (w1, q1, _, _), (w2, q2, s2, _) = (prev[-2] if len(prev) > 1 else prev[-1]), prev[-1]
    guess = q2 + (q2 - q1) * (w_to - w2) / (w2 - w1) if w2 != w1 else q2
    try:
        q, orb = _point(fn, param, param2, base, n, w_to, guess, s2)
        return prev + [(w_to, q, orb.s, orb)]
    except (ContinuationError, ValueError):
        if depth >= MAX_HALVINGS:
            raise
    prev = _reach(fn, scene, prev, 0.5 * (w2 + w_to), depth + 1)
    return _reach(fn, scene, prev, w_to, depth + 1)


def follow_touch(base: Groups, bif: Bifurcation, name: str, name2: str, start2: float, end2: float, *,
                 points: int = 21, on_point: Optional[Callable[[float, float], None]] = None) -> Curve:
    """The boundary of ``bif`` (a ``grazing`` or ``tension`` point located along ``name``) over ``name2``.

    The curve starts at the bifurcation's own value of ``name2`` and goes to both ends of
    ``[start2, end2]``; ``stopped`` says where and why a side ended early (no points: the boundary's point
    itself could not be refined).
    """
    if bif.kind not in INDICATORS and bif.kind != "sliding":
        raise ValueError(f"follow_touch follows {', '.join(INDICATORS)} and sliding points, not {bif.kind!r}")
    fn = sliding_indicator(bif.orbit) if bif.kind == "sliding" else INDICATORS[bif.kind][0]
    param = Parameter.on(name, base)
    param2 = Parameter.on(name2, base)
    n = bif.orbit.period
    w0 = param2.value(bif.orbit.groups) / param2.scale
    curve = Curve(kind=bif.kind, param=name, param2=name2)
    try:
        q0, orb0 = _point(fn, param, param2, base, n, w0, bif.value / param.scale, bif.orbit.s)
    except (ContinuationError, ValueError) as e:
        curve.stopped = f"at {name2} = {w0 * param2.scale:.9g}: the {bif.kind} point is not refined: {e}"
        return curve
    sides = []
    span = max(abs(end2 - start2) / param2.scale, 1e-300)
    for w_end in (start2 / param2.scale, end2 / param2.scale):
        if w_end == w0:
            sides.append([])
            continue
        ws = np.linspace(w0, w_end, max(2, int(round(points * abs(w_end - w0) / span)) + 1))
        side, prev = [], [(w0, q0, orb0.s, orb0)]
        for w in ws[1:]:
            try:
                prev = _reach(fn, (param, param2, base, n), prev, w)
            except (ContinuationError, ValueError) as e:
                curve.stopped = "; ".join(x for x in (curve.stopped, f"at {name2} = {w * param2.scale:.9g}: {e}")
                                          if x)
                break
            side.append((prev[-1][1] * param.scale, w * param2.scale, prev[-1][3]))
            if on_point:
                on_point(*side[-1])
        sides.append(side)
    rows = list(reversed(sides[0])) + [(q0 * param.scale, w0 * param2.scale, orb0)] + sides[1]
    curve.points = [(v, v2) for v, v2, _ in rows]
    curve.orbits = [orb for _, _, orb in rows]
    return curve
