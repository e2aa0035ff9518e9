"""Boundaries where an indicator's extremum along the periodic orbit touches zero (grazing, tension onset): located along a branch and followed in two parameters.

Two boundaries are not zeros of a test function of the multipliers
(:mod:`.boundary`) but of an extremum along the orbit, a continuous function
of the parameters on both sides though not a smooth one of the orbit:

``grazing``
    an impact appears or disappears: the largest contact overlap
    ``max_t (x1 - x3 - r)`` crosses zero (negative: the gap stays open;
    positive: the peak overlap of an impact);
``tension``
    the spring starts to pull the bit: the smallest drive on the bit
    ``min_t (f_k + f_c)`` crosses zero (the library's Stepper tracks it,
    locating each dip between its steps).

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

__all__ = ["max_overlap", "min_drive", "INDICATORS", "detect_touches", "follow_touch", "SAMPLES_PER_PERIOD",
           "BRACKET_STEP", "ROOT_TOL"]

#: samples of the orbit per forcing period when looking for the largest overlap
SAMPLES_PER_PERIOD = 2000
#: samples over the two sample intervals around the coarse maximum
FINE_SAMPLES = 400
#: first half-width (scaled first parameter) of the bracket searched around the predicted point
BRACKET_STEP = 1e-3
#: doublings of the bracket's half-width before the point counts as lost
BRACKET_DOUBLINGS = 8
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


def _overlap_samples(orbit: PeriodicOrbit, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The overlap d = x1 - x3 - r and its rate x2 - x4 along the orbit at ``times`` (from phase 0)."""
    g = orbit.groups
    samples = np.zeros((times.size, KL.N_SAMPLE_COLS))
    st = Stepper(g, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False)
    try:
        st.advance(times[-1], sample_times=times, samples=samples)
    except SolverError as e:
        raise ContinuationError(f"the orbit could not be sampled: {e}") from None
    return samples[:, 0] - samples[:, 2] - g.r, samples[:, 1] - samples[:, 3]


def min_drive(orbit: PeriodicOrbit) -> float:
    """The smallest drive on the bit ``f_k + f_c`` along the orbit over its period [F_s]."""
    st = Stepper(orbit.groups, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False)
    try:
        st.advance(orbit.period * orbit.groups.period)
    except SolverError as e:
        raise ContinuationError(f"the orbit could not be integrated: {e}") from None
    return float(st.fstate[KL.F_DRIVE_MIN])


#: the indicators by boundary kind, and what their zero means
INDICATORS = {"grazing": (max_overlap, "the contact overlap's maximum touches zero (an impact appears)"),
              "tension": (min_drive, "the drive's minimum on the bit touches zero (the spring starts to pull it)")}


def _indicator_at(kind: str, g: Groups, s_guess: np.ndarray, n: int) -> tuple[float, PeriodicOrbit]:
    orb = correct_orbit(g, s_guess, n)
    for m in range(1, n):
        # Newton's method on the period-n map may land on an orbit of a period dividing n: another family
        if n % m == 0:
            back = period_map(g, orb.s, m, jacobian=False).s_end
            if back.shape == orb.s.shape and np.max(np.abs(back - orb.s)) < JOIN_TOL:
                raise ContinuationError(f"the period-{n} orbit has joined the period-{m} orbit")
    return INDICATORS[kind][0](orb), orb


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
                val, state["orbit"] = _indicator_at(kind, param.at(base, v), (1 - w) * a.orbit.s + w * b.orbit.s,
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


def _point(kind: str, param: Parameter, param2: Parameter, base: Groups, n: int, w: float, q_guess: float,
           s_guess: np.ndarray) -> tuple[float, PeriodicOrbit]:
    """The boundary's point (q, orbit) at the scaled second parameter ``w``, near ``q_guess``."""
    state = {"s": s_guess}

    def indicator(q):
        g = param2.at(param.at(base, q * param.scale), w * param2.scale)
        val, orb = _indicator_at(kind, g, state["s"], n)
        state["s"], state["orbit"] = orb.s, orb
        return val

    f0 = indicator(q_guess)
    if f0 == 0.0:
        return q_guess, state["orbit"]
    s0 = state["s"]
    step = BRACKET_STEP * max(1.0, abs(q_guess))
    for _ in range(BRACKET_DOUBLINGS):
        for q in (q_guess + step, q_guess - step):
            state["s"] = s0
            if indicator(q) * f0 < 0:
                lo, hi = sorted((q_guess, q))
                state["s"] = s0
                q_root = brentq(indicator, lo, hi, xtol=ROOT_TOL * max(1.0, abs(q_guess)))
                indicator(q_root)
                return q_root, state["orbit"]
        step *= 2
    raise ContinuationError(f"no {kind} point within {step / 2:.3g} of the predicted {param.name}")


def _reach(kind: str, scene: tuple, prev: list, w_to: float, depth: int = 0) -> list:
    """The curve's points ``prev`` [(w, q, s)] extended to ``w_to``, halving the step in the second parameter
    (at most :data:`MAX_HALVINGS` times) where the point is not found from the secant's guess."""
    param, param2, base, n = scene
    (w1, q1, _), (w2, q2, s2) = (prev[-2] if len(prev) > 1 else prev[-1]), prev[-1]
    guess = q2 + (q2 - q1) * (w_to - w2) / (w2 - w1) if w2 != w1 else q2
    try:
        q, orb = _point(kind, param, param2, base, n, w_to, guess, s2)
        return prev + [(w_to, q, orb.s)]
    except (ContinuationError, ValueError):
        if depth >= MAX_HALVINGS:
            raise
    prev = _reach(kind, scene, prev, 0.5 * (w2 + w_to), depth + 1)
    return _reach(kind, scene, prev, w_to, depth + 1)


def follow_touch(base: Groups, bif: Bifurcation, name: str, name2: str, start2: float, end2: float, *,
                 points: int = 21, on_point: Optional[Callable[[float, float], None]] = None) -> Curve:
    """The boundary of ``bif`` (a ``grazing`` or ``tension`` point located along ``name``) over ``name2``.

    The curve starts at the bifurcation's own value of ``name2`` and goes to both ends of
    ``[start2, end2]``; ``stopped`` says where and why a side ended early (no points: the boundary's point
    itself could not be refined).
    """
    if bif.kind not in INDICATORS:
        raise ValueError(f"follow_touch follows {' and '.join(INDICATORS)} points, not {bif.kind!r}")
    param = Parameter.on(name, base)
    param2 = Parameter.on(name2, base)
    n = bif.orbit.period
    w0 = param2.value(bif.orbit.groups) / param2.scale
    curve = Curve(kind=bif.kind, param=name, param2=name2)
    try:
        q0, orb0 = _point(bif.kind, param, param2, base, n, w0, bif.value / param.scale, bif.orbit.s)
    except (ContinuationError, ValueError) as e:
        curve.stopped = f"at {name2} = {w0 * param2.scale:.9g}: the {bif.kind} point is not refined: {e}"
        return curve
    sides = []
    span = max(abs(end2 - start2) / param2.scale, 1e-300)
    for w_end in (start2 / param2.scale, end2 / param2.scale):
        ws = np.linspace(w0, w_end, max(2, int(round(points * abs(w_end - w0) / span)) + 1))
        side, prev = [], [(w0, q0, orb0.s)]
        for w in ws[1:]:
            try:
                prev = _reach(bif.kind, (param, param2, base, n), prev, w)
            except (ContinuationError, ValueError) as e:
                curve.stopped = "; ".join(x for x in (curve.stopped, f"at {name2} = {w * param2.scale:.9g}: {e}")
                                          if x)
                break
            side.append((prev[-1][1] * param.scale, w * param2.scale))
            if on_point:
                on_point(*side[-1])
        sides.append(side)
    curve.points = list(reversed(sides[0])) + [(q0 * param.scale, w0 * param2.scale)] + sides[1]
    return curve
