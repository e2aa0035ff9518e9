"""Pseudo-arclength continuation of a periodic orbit in one parameter, with the Floquet multipliers at every point.

The unknowns are the orbit's map coordinates ``s`` at phase 0 and the scaled
parameter ``q = value / scale`` (:class:`.Parameter`).  A step predicts along
the tangent ``t`` of the branch and corrects by Newton's method on

    P^n(s, q) - s = 0,     t . ((s, q) - (s_pred, q_pred)) = 0,

whose Jacobian is the monodromy minus the identity (:mod:`.monodromy`), the
parameter derivative of the map (central differences) and ``t``.  The step
grows after an easy correction and halves after a failed one; below
:data:`MIN_STEP` the continuation stops and says where and why.  When the
bit's stick/slip state at phase 0 changes along a branch, the coordinates
change (2 stuck, 3 slipping) and the branch goes on from a correction at
fixed parameter.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from hammerbit.model.params import Groups

from .monodromy import ContinuationError, period_map
from .orbit import NEWTON_TOL, PeriodicOrbit, correct_orbit, make_orbit
from .parameter import Parameter

__all__ = ["ContinuationOptions", "BranchPoint", "Branch", "follow_branch", "corrector", "tangent_at"]

#: relative step of the central difference of the map in the scaled parameter
PARAM_FD_STEP = 1e-7
#: a correction may move at most this many step lengths away from its prediction
REACH = 1.0
#: a multiplier beyond this says the branch runs into a non-smooth point (the sensitivity of a
#: vanishing slip phase or a grazing contact grows without bound): the branch ends there
MAX_MULTIPLIER = 1e3
#: at the step-size floor, a branch whose multiplier is beyond this has run into a non-smooth point
STEEP_MULTIPLIER = 10.0
#: a period-n orbit that repeats after m | n periods to this tolerance has joined the period-m branch
JOIN_TOL = 1e-7
#: the first bit velocity tried when the section's bit starts to slip at phase 0
SWITCH_BIT_VELOCITY = 1e-6
#: how far (map coordinates) the orbit in switched coordinates may lie from the prediction
SWITCH_REACH = 1e-2
#: a branch whose last CREEP_POINTS points span less than CREEP_SPAN (coordinates and scaled parameter)
#: is stuck at a corner
CREEP_POINTS = 20
CREEP_SPAN = 1e-6
#: smallest arclength step before the continuation gives up
MIN_STEP = 1e-7


@dataclass(frozen=True)
class ContinuationOptions:
    """Step control of the continuation (arclength in the map coordinates and the scaled parameter)."""

    step: float = 2e-3
    max_step: float = 1e-2
    min_step: float = MIN_STEP
    max_points: int = 2000
    newton_iter: int = 8
    #: corrections that converge in at most this many iterations let the step grow
    easy_iter: int = 4
    growth: float = 1.5


@dataclass
class BranchPoint:
    """One point of a branch: the parameter value and the orbit."""

    value: float
    orbit: PeriodicOrbit
    tangent: np.ndarray = field(repr=False, default=None)

    @property
    def stable(self) -> bool:
        return self.orbit.stable


@dataclass
class Branch:
    """A followed branch of period-n orbits, its points in the order of continuation."""

    period: int
    points: list = field(default_factory=list)
    #: why the continuation failed before the end of the range ("" when it did not)
    stopped: str = ""
    #: where and why the branch ends inside the range by itself (joins a lower period, a non-smooth end)
    ended: str = ""
    #: the points where it ends by itself, with the reason (one per direction followed)
    end_points: list = field(default_factory=list)
    #: the points where the continuation failed (the step-size floor), with the reason
    stop_points: list = field(default_factory=list)

    @property
    def values(self) -> np.ndarray:
        return np.array([p.value for p in self.points])


def _map_value(param: Parameter, base: Groups, s, q, n, jacobian=True):
    return period_map(param.at(base, q * param.scale), s, n, jacobian=jacobian)


def _param_derivative(param: Parameter, base: Groups, s, q, n) -> np.ndarray:
    h = PARAM_FD_STEP * max(1.0, abs(q))
    up = _map_value(param, base, s, q + h, n, jacobian=False).s_end
    dn = _map_value(param, base, s, q - h, n, jacobian=False).s_end
    return (up - dn) / (2 * h)


def tangent_at(param: Parameter, base: Groups, orbit: PeriodicOrbit, q: float, direction: float) -> np.ndarray:
    """The unit tangent (ds, dq) of the branch at an orbit, its dq of the sign of ``direction``."""
    k = orbit.s.shape[0]
    dpdq = _param_derivative(param, base, orbit.s, q, orbit.period)
    J = np.hstack([orbit.monodromy - np.eye(k), dpdq[:, None]])
    # the null vector of the k x (k + 1) Jacobian
    _, _, vt = np.linalg.svd(J)
    t = vt[-1]
    if t[-1] * direction < 0 or (t[-1] == 0 and direction < 0):
        t = -t
    return t


def corrector(param: Parameter, base: Groups, x_pred: np.ndarray, t: np.ndarray, n: int,
              max_iter: int, reach: float = np.inf) -> Optional[tuple[np.ndarray, object, int]]:
    """Newton's method on the pseudo-arclength system from ``x_pred``; (x, map result, iterations) or None.

    A correction that strays further than ``reach`` from the prediction is refused (it would jump to
    another branch).
    """
    x = x_pred.copy()
    k = x.shape[0] - 1
    for it in range(1, max_iter + 1):
        s, q = x[:k], x[k]
        try:
            res = _map_value(param, base, s, q, n)
        except ContinuationError:
            return None
        if res.s_end.shape[0] != k:
            return None
        r = res.s_end - s
        arc = float(t @ (x - x_pred))
        if np.max(np.abs(r)) <= NEWTON_TOL * max(1.0, float(np.max(np.abs(s)))) and abs(arc) < 1e-10:
            return x, res, it
        if it == 1:
            dpdq = _param_derivative(param, base, s, q, n)  # kept over the iterations (a chord in q)
        A = np.zeros((k + 1, k + 1))
        A[:k, :k] = res.jacobian - np.eye(k)
        A[:k, k] = dpdq
        A[k] = t
        try:
            dx = np.linalg.solve(A, -np.concatenate([r, [arc]]))
        except np.linalg.LinAlgError:
            return None
        x = x + dx
        if np.linalg.norm(x - x_pred) > reach:
            return None
        if k == 3 and x[2] <= 0.0:
            return None  # the bit stops at phase 0: the coordinates change
    return None


def _switch_coordinates(param, base, x_pred, n) -> Optional[PeriodicOrbit]:
    """The orbit at the predicted parameter in the other stick/slip coordinates of phase 0, or None."""
    k = x_pred.shape[0] - 1
    q = x_pred[k]
    g = param.at(base, q * param.scale)
    s = x_pred[:2].copy() if k == 3 else np.array([x_pred[0], x_pred[1], SWITCH_BIT_VELOCITY])
    try:
        orb = correct_orbit(g, s, n)
    except ContinuationError:
        return None
    if orb.s.shape[0] == k or np.linalg.norm(orb.s[:2] - x_pred[:2]) > SWITCH_REACH:
        return None  # not the other coordinates, or another orbit
    return orb


def _creeping(branch: Branch, param: Parameter) -> str:
    """The branch is stuck at a corner (a non-smooth fold) when its last points hardly move."""
    pts = branch.points[-CREEP_POINTS:]
    if len(pts) < CREEP_POINTS:
        return ""
    xs = np.array([np.concatenate([p.orbit.s[:2], [p.value / param.scale]]) for p in pts])
    if np.max(np.ptp(xs, axis=0)) < CREEP_SPAN:
        return (f"at {param.name} = {pts[-1].value:.9g} the branch turns at a corner (a non-smooth point where "
                f"its tangent jumps) and is not followed further")
    return ""


def _branch_end(param: Parameter, orbit: PeriodicOrbit) -> str:
    """Why the branch ends at this orbit ("" if it goes on): it has joined a branch of a lower period, or
    runs into a non-smooth point."""
    v = param.value(orbit.groups)
    if orbit.max_multiplier > MAX_MULTIPLIER:
        return (f"at {param.name} = {v:.9g} a multiplier passes {MAX_MULTIPLIER:g}: the branch runs into a "
                f"non-smooth point (a slip phase or a contact vanishing)")
    for m in range(1, orbit.period):
        if orbit.period % m:
            continue
        back = period_map(orbit.groups, orbit.s, m, jacobian=False).s_end
        if back.shape == orbit.s.shape and np.max(np.abs(back - orbit.s)) < JOIN_TOL:
            return f"at {param.name} = {v:.9g} the period-{orbit.period} branch joins the period-{m} branch"
    return ""


def follow_branch(param: Parameter, base: Groups, orbit: PeriodicOrbit, end: float, *,
                  options: ContinuationOptions = ContinuationOptions(),
                  on_point: Optional[Callable[[BranchPoint], None]] = None) -> Branch:
    """Follow the branch of ``orbit`` from its parameter value to ``end`` (the parameter's units).

    Returns the branch; ``stopped`` says where and why it ended before ``end``
    (a step-size floor: a fold it cannot turn, chaos, no convergence).
    """
    scale = param.scale
    q = param.value(orbit.groups) / scale
    q_end = end / scale
    direction = 1.0 if q_end >= q else -1.0
    branch = Branch(period=orbit.period)
    t = tangent_at(param, base, orbit, q, direction)
    point = BranchPoint(q * scale, orbit, t)
    branch.points.append(point)
    if on_point:
        on_point(point)
    h = options.step
    x = np.concatenate([orbit.s, [q]])
    while len(branch.points) < options.max_points:
        if (q_end - x[-1]) * direction <= 0:
            break
        x_pred = x + h * t
        if (x_pred[-1] - q_end) * direction > 0 and abs(t[-1]) > 1e-3:
            # the last step lands on the end of the range
            h_end = (q_end - x[-1]) / t[-1]
            x_pred = x + h_end * t
        got = corrector(param, base, x_pred, t, orbit.period, options.newton_iter,
                        reach=REACH * float(np.linalg.norm(x_pred - x)))
        if got is not None:
            x_new, res, iters = got
            orb = make_orbit(param.at(base, x_new[-1] * scale), orbit.period, x_new[:-1], res)
        else:
            orb = _switch_coordinates(param, base, x_pred, orbit.period)
            if orb is None:
                h /= 2
                if h < options.min_step:
                    last_point = branch.points[-1]
                    last = last_point.orbit
                    if last.max_multiplier > STEEP_MULTIPLIER:
                        branch.ended = (f"at {param.name} = {x[-1] * scale:.9g} the branch runs into a non-smooth "
                                        f"point (multiplier {last.max_multiplier:.3g} and growing)")
                        branch.end_points.append((branch.points[-1], branch.ended))
                    else:
                        branch.stopped = (f"step-size floor at {param.name} = {x[-1] * scale:.9g}: no orbit of "
                                          f"period {orbit.period} next to it (no convergence)")
                        branch.stop_points.append((last_point, branch.stopped))
                    break
                continue
            x_new, iters = np.concatenate([orb.s, [x_pred[-1]]]), options.newton_iter
        t_new = tangent_at(param, base, orb, x_new[-1], 1.0)
        if t_new.shape == t.shape and t_new @ t < 0 or t_new.shape != t.shape and t_new[-1] * t[-1] < 0:
            t_new = -t_new
        x, t = x_new, t_new
        point = BranchPoint(x[-1] * scale, orb, t)
        branch.points.append(point)
        if on_point:
            on_point(point)
        reason = _branch_end(param, orb) or _creeping(branch, param)
        if reason:
            branch.ended = reason
            branch.end_points.append((point, reason))
            break
        if iters <= options.easy_iter:
            h = min(h * options.growth, options.max_step)
    return branch
