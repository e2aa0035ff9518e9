"""A located smooth bifurcation followed in a second parameter: the boundary as a curve (period-doubling, fold, Neimark–Sacker).

At each value ``w`` of the second parameter, Newton's method solves for the
orbit ``s`` and the first parameter ``q`` together:

    P^n(s, q; w) - s = 0,     g(s, q; w) = 0,

with ``g`` the bifurcation's test function of the multipliers
(:func:`.bifurcation.test_values`), its derivatives by central differences.
The first guess at each new ``w`` is the secant through the last two points
of the curve.  Non-smooth boundaries (grazing, sliding) are not followed: their
indicator is not a smooth function of the orbit.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from hammerbit.model.params import Groups

from .bifurcation import SMOOTH_KINDS, Bifurcation, test_values
from .monodromy import ContinuationError, period_map
from .orbit import NEWTON_TOL, make_orbit
from .parameter import Parameter

__all__ = ["Curve", "follow_boundary", "refine", "CURVE_POINTS"]

#: points of a curve over the second parameter's range
CURVE_POINTS = 21
#: central-difference step (scaled units) of the derivatives of the test function
FD_STEP = 1e-6
#: Newton iterations per curve point
MAX_ITER = 12
#: halvings of a step in the second parameter before the curve stops
MAX_HALVINGS = 5
#: the test function's residual (relative to its scale: its derivative norm times 1e-9) accepted
TEST_TOL = 1e-9


@dataclass
class Curve:
    """A bifurcation boundary in two parameters: (value, value2) points, and why it stopped early ("")."""

    kind: str
    param: str
    param2: str
    points: list = field(default_factory=list)
    stopped: str = ""
    #: the orbit at each point (at the bifurcation's own point: its orbit as located along the branch)
    orbits: list = field(default_factory=list)


def _residual(param, param2, base, n, kind, x, w):
    k = x.shape[0] - 1
    g = param.at(base, x[k] * param.scale)
    if param2 is not None:
        g = param2.at(g, w * param2.scale)
    res = period_map(g, x[:k], n)
    if res.s_end.shape[0] != k:
        raise ContinuationError("the section's stick/slip state changed")
    orb = make_orbit(g, n, x[:k], res)
    return np.concatenate([res.s_end - x[:k], [test_values(orb)[kind]]]), orb


def _solve(param, param2, base, n, kind, x, w):
    for _ in range(MAX_ITER):
        F, orb = _residual(param, param2, base, n, kind, x, w)
        J = np.zeros((x.shape[0], x.shape[0]))
        for j in range(x.shape[0]):
            h = FD_STEP * max(1.0, abs(x[j]))
            e = np.zeros_like(x)
            e[j] = h
            J[:, j] = (_residual(param, param2, base, n, kind, x + e, w)[0]
                       - _residual(param, param2, base, n, kind, x - e, w)[0]) / (2 * h)
        k = x.shape[0] - 1
        scale_g = max(np.linalg.norm(J[k]), 1e-300)
        if np.max(np.abs(F[:k])) <= NEWTON_TOL * max(1.0, np.max(np.abs(x[:k]))) and abs(F[k]) <= TEST_TOL * scale_g:
            return x, orb
        x = x + np.linalg.solve(J, -F)
    raise ContinuationError(f"no convergence in {MAX_ITER} iterations")


def _reach(param, param2, base, bif, prev, w_to, depth=0):
    """The curve's point at ``w_to`` from its last points ``prev`` [(w, x)], halving the step in the second
    parameter where Newton's method fails from the secant guess."""
    w_from, x_from = prev[-1]
    guess = x_from
    if len(prev) >= 2:
        (w1, x1), (w2, x2) = prev[-2], prev[-1]
        guess = x2 + (x2 - x1) * ((w_to - w2) / (w2 - w1))
    try:
        return _solve(param, param2, base, bif.orbit.period, bif.kind, guess, w_to)
    except (ContinuationError, np.linalg.LinAlgError, ValueError):
        if depth >= MAX_HALVINGS:
            raise
    w_mid = 0.5 * (w_from + w_to)
    x_mid = _reach(param, param2, base, bif, prev, w_mid, depth + 1)[0]
    return _reach(param, param2, base, bif, prev + [(w_mid, x_mid)], w_to, depth + 1)


def follow_boundary(base: Groups, bif: Bifurcation, name: str, name2: str, start2: float, end2: float, *,
                    points: int = CURVE_POINTS,
                    on_point: Optional[Callable[[float, float], None]] = None) -> Curve:
    """The curve of the smooth bifurcation ``bif`` (located along ``name``) over ``name2`` from ``start2`` to ``end2``.

    The curve starts at the bifurcation's own value of ``name2`` and goes to both
    ends of the range; ``stopped`` says where and why a side ended early.
    """
    if bif.kind not in SMOOTH_KINDS:
        raise ValueError(f"only smooth bifurcations are followed in two parameters, not {bif.kind!r}")
    param = Parameter.on(name, base)
    param2 = Parameter.on(name2, base)
    w0 = param2.value(bif.orbit.groups) / param2.scale
    x0 = np.concatenate([bif.orbit.s, [bif.value / param.scale]])
    curve = Curve(kind=bif.kind, param=name, param2=name2)
    sides = []
    for w_end in (start2 / param2.scale, end2 / param2.scale):
        ws = np.linspace(w0, w_end, max(2, int(round(points * abs(w_end - w0) / max(abs(end2 - start2) /
                                                                                      param2.scale, 1e-300))) + 1))
        side, prev = [], [(w0, x0)]
        for w in ws[1:]:
            try:
                x, orbit = _reach(param, param2, base, bif, prev, w)
            except (ContinuationError, np.linalg.LinAlgError, ValueError) as e:
                curve.stopped = "; ".join(v for v in (curve.stopped, f"at {name2} = {w * param2.scale:.9g}: {e}") if v)
                break
            prev.append((w, x))
            side.append((x[-1] * param.scale, w * param2.scale, orbit))
            if on_point:
                on_point(*side[-1][:2])
        sides.append(side)
    rows = list(reversed(sides[0])) + [(bif.value, w0 * param2.scale, bif.orbit)] + sides[1]
    curve.points = [(v, v2) for v, v2, _ in rows]
    curve.orbits = [orb for _, _, orb in rows]
    return curve


def refine(base: Groups, bif: Bifurcation, name: str) -> Bifurcation:
    """The smooth bifurcation ``bif`` (located along ``name``) with its test function solved to zero by the
    curve's Newton iteration at its own values of the other parameters (orbit and ``name`` together).

    Raises
    ------
    ContinuationError
        Newton's method does not converge.
    """
    if bif.kind not in SMOOTH_KINDS:
        raise ValueError(f"only smooth bifurcations are refined, not {bif.kind!r}")
    param = Parameter.on(name, base)
    x0 = np.concatenate([bif.orbit.s, [bif.value / param.scale]])
    try:
        x, orbit = _solve(param, None, base, bif.orbit.period, bif.kind, x0, 0.0)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise ContinuationError(f"the {bif.kind} point is not refined: {e}") from None
    return Bifurcation(kind=bif.kind, value=float(x[-1] * param.scale), branch=bif.branch, orbit=orbit,
                       detail=bif.detail)
