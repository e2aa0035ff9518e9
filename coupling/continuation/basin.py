"""Runs from rest: the branch a run from rest reaches, and where that changes inside a coexistence interval (the state at rest crossing a saddle's stable manifold).

Where two stable branches coexist, which one a rig drills after start-up is
decided by the basin the state at rest lies in.  The basins are separated by
the stable manifold of a saddle orbit (at a subcritical period-doubling, the
unstable period-2n orbit born there).  As the parameter moves, the state at
rest crosses that manifold: runs from rest change branch although neither
orbit changes.  At the crossing the run from rest lands on the manifold and
approaches the saddle.

:func:`rest_switch` brackets the crossing by bisection of runs from rest, finds
the saddle (the unstable orbit of the diagram the runs pass closest to) and
then locates the crossing by the saddle's unstable coordinate: with ``p`` the
saddle's point the run comes closest to after ``i`` periods, ``z_i(v)`` the
run's state there and ``u`` the left eigenvector of the saddle's unstable
multiplier, the run from rest lies on the local stable manifold where

    F(v) = u . (z_i(v) - p(v)) = 0,

a smooth scalar equation in the parameter ``v`` solved by Brent's method.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy.optimize import brentq

from hammerbit.model.params import Groups
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.stepping import Stepper

from .monodromy import ORBIT_SOLVER, ContinuationError, period_map, relative_state
from .orbit import PeriodicOrbit, correct_orbit, orbit_from_simulation
from .parameter import Parameter

__all__ = ["RestRun", "rest_run", "branch_of", "on_branch", "rop_at", "rest_switch", "SWITCH_TOL", "SADDLE_REACH",
           "MANIFOLD_TOL"]

#: a run from rest is on a branch of its period when its rate of penetration matches the branch's within this
ROP_MATCH_TOL = 2e-3
#: ... plus this (x0 per period): a branch of no progression has ROP 0
ROP_MATCH_FLOOR = 1e-9
#: two corrected orbits closer than this (max norm, map coordinates) are the same
SAME_ORBIT_TOL = 1e-6
#: bracket (scaled parameter) of the bisection of runs from rest inside a coexistence interval
SWITCH_TOL = 1e-4
#: a run from rest that comes this close (max norm, map coordinates) to an unstable orbit passes its saddle
SADDLE_REACH = 1e-2
#: Brent's bracket (scaled parameter) on the saddle's unstable coordinate
MANIFOLD_TOL = 1e-12
#: periods run from rest when looking for the saddle
SADDLE_RUN_PERIODS = 200


@dataclass
class RestRun:
    """Where a run from rest settles at one parameter value: its period (None: none <= MAX_PERIOD) and branch."""

    value: float
    period: Optional[int]
    branch: Optional[int]
    rop_x0_per_period: Optional[float] = None


def rop_at(branch, value: float) -> list[float]:
    """The branch's ROP per period at ``value`` (one per crossing of the value: a folded branch has more)."""
    out = []
    pts = branch.points
    for a, b in zip(pts[:-1], pts[1:]):
        lo, hi = sorted((a.value, b.value))
        if lo <= value <= hi and hi > lo:
            w = (value - a.value) / (b.value - a.value)
            out.append((1 - w) * a.orbit.rop_x0_per_period + w * b.orbit.rop_x0_per_period)
    return out


def branch_of(branches: list, value: float, period: int, rop: float) -> Optional[int]:
    """The index of the branch of ``period`` whose ROP at ``value`` is ``rop``, or None."""
    for i, br in enumerate(branches):
        if br.period != period:
            continue
        for r in rop_at(br, value):
            # relative: the branch's ROP is interpolated linearly between its points
            if abs(r - rop) <= ROP_MATCH_TOL * abs(rop) + ROP_MATCH_FLOOR:
                return i
    return None


def on_branch(branches: list, value: float, orbit: PeriodicOrbit) -> Optional[int]:
    """The index of a branch that passes through ``orbit`` at ``value`` (any of its phase points), or None.

    For where the ROP interpolated between a branch's points is too coarse to tell (next to a corner): the
    branch's orbit at ``value``, corrected from the interpolation of its two points there, is compared with
    the orbit's phase points.
    """
    phases = _phase_points(orbit)
    for i, br in enumerate(branches):
        if br.period != orbit.period:
            continue
        for a, b in zip(br.points[:-1], br.points[1:]):
            lo, hi = sorted((a.value, b.value))
            if not (lo <= value <= hi and hi > lo) or a.orbit.s.shape != b.orbit.s.shape:
                continue
            w = (value - a.value) / (b.value - a.value)
            try:
                s = correct_orbit(orbit.groups, (1 - w) * a.orbit.s + w * b.orbit.s, br.period).s
            except ContinuationError:
                continue
            if any(p.shape == s.shape and np.max(np.abs(p - s)) < SAME_ORBIT_TOL for p in phases):
                return i
    return None


def rest_run(param: Parameter, base: Groups, value: float, branches: list) -> RestRun:
    """The period and branch a run from rest reaches at ``value``."""
    g = param.at(base, value)
    guess = orbit_from_simulation(g)
    if guess is None:
        return RestRun(value, None, None)
    n, s = guess
    try:
        orb = correct_orbit(g, s, n)
    except ContinuationError:
        return RestRun(value, n, None)
    branch = branch_of(branches, value, n, orb.rop_x0_per_period)
    if branch is None:
        branch = on_branch(branches, value, orb)
    return RestRun(value, n, branch, orb.rop_x0_per_period)


def _rest_rows(g: Groups, periods: int) -> np.ndarray:
    """The Poincaré rows [tau, x1..x4] of a run from rest, row k after k periods."""
    st = Stepper(g, solver=ORBIT_SOLVER, compile_helper=False)
    poin = np.zeros((periods + 1, 5))
    try:
        st.advance(periods * g.period, poincare=poin)
    except SolverError as e:
        raise ContinuationError(f"a run from rest failed: {e}") from None
    return poin


def _section_coords(y) -> np.ndarray:
    return relative_state(y, y[3] == 0.0)


def _phase_points(orbit: PeriodicOrbit) -> list[np.ndarray]:
    """The orbit's n points at phase 0 (each in the coordinates of its stick/slip state)."""
    pts = [orbit.s]
    for k in range(1, orbit.period):
        res = period_map(orbit.groups, orbit.s, k, jacobian=False)
        pts.append(relative_state(res.y_end, res.stuck_end))
    return pts


def _saddles_at(param: Parameter, base: Groups, branches: list, value: float) -> list[tuple[int, PeriodicOrbit]]:
    """The unstable orbits of the branches at ``value``, each corrected there: [(branch index, orbit)]."""
    g = param.at(base, value)
    out = []
    for i, br in enumerate(branches):
        for a, b in zip(br.points[:-1], br.points[1:]):
            lo, hi = sorted((a.value, b.value))
            if not (lo <= value <= hi and hi > lo) or a.stable or b.stable or a.orbit.s.shape != b.orbit.s.shape:
                continue
            w = (value - a.value) / (b.value - a.value)
            try:
                orb = correct_orbit(g, (1 - w) * a.orbit.s + w * b.orbit.s, br.period)
            except ContinuationError:
                continue
            if not orb.stable:
                out.append((i, orb))
    return out


def _nearest_saddle(param, base, branches, value):
    """(branch, orbit, phase index j, row i, distance) of the saddle point a run from rest at ``value`` passes
    closest to, or None."""
    rows = _rest_rows(param.at(base, value), SADDLE_RUN_PERIODS)
    best = None
    for i_br, orb in _saddles_at(param, base, branches, value):
        for j, p in enumerate(_phase_points(orb)):
            for i in range(1, rows.shape[0]):
                z = _section_coords(rows[i, 1:5])
                if z.shape != p.shape:
                    continue
                dist = float(np.max(np.abs(z - p)))
                if best is None or dist < best[4]:
                    best = (i_br, orb, j, i, dist)
    return best if best is not None and best[4] < SADDLE_REACH else None


def _unstable_coordinate(param, base, p_guess, n, row, u):
    """F(v) = u . (z_row(v) - p(v)): the run from rest's offset from the saddle along its unstable direction."""
    def f(v):
        g = param.at(base, v)
        p = correct_orbit(g, p_guess, n).s
        z = _section_coords(_rest_rows(g, row + 1)[row, 1:5])
        if z.shape != p.shape:
            raise ContinuationError("the run from rest is not in the saddle's stick/slip state there")
        return float(u @ (z - p))
    return f


def _on_manifold(param, base, saddle, x, y) -> Optional[float]:
    """The parameter value in [x, y] where the run from rest lies on the saddle's stable manifold, or None."""
    _, orb, j, row, _ = saddle
    p = _phase_points(orb)[j]
    at_p = correct_orbit(orb.groups, p, orb.period)
    mu, vecs = np.linalg.eig(at_p.monodromy.T)  # left eigenvectors
    k = int(np.argmax(np.abs(mu)))
    if abs(mu[k].imag) > 0:
        return None  # a complex unstable pair: no single unstable coordinate
    f = _unstable_coordinate(param, base, p, orb.period, row, np.real(vecs[:, k]))
    try:
        fx, fy = f(x), f(y)
        if fx * fy > 0:
            return None
        return brentq(f, x, y, xtol=MANIFOLD_TOL * param.scale)
    except (ContinuationError, ValueError):
        return None


def rest_switch(param: Parameter, base: Groups, branches: list, lo: float, hi: float) -> Optional[dict]:
    """Where, inside the coexistence interval [lo, hi], runs from rest change the branch they reach, or None.

    Returns ``{"value", "uncertainty", "below", "above", "saddle", "located_by"}``:
    ``below``/``above`` the branches reached on either side, ``saddle`` the branch of the unstable orbit whose
    stable manifold the state at rest crosses (None if no followed orbit is found), ``located_by``
    ``"stable manifold"`` (the value solves the manifold condition to :data:`MANIFOLD_TOL`) or
    ``"bisection"`` (the bracket of runs from rest, :data:`SWITCH_TOL`).
    """
    eps = 1e-3 * (hi - lo)
    a = rest_run(param, base, lo + eps, branches)
    b = rest_run(param, base, hi - eps, branches)
    if a.branch == b.branch:
        return None
    x, y = lo + eps, hi - eps
    while abs(y - x) > SWITCH_TOL * param.scale:
        m = 0.5 * (x + y)
        if rest_run(param, base, m, branches).branch == a.branch:
            x = m
        else:
            y = m
    out = {"value": 0.5 * (x + y), "uncertainty": abs(y - x), "below": a.branch, "above": b.branch,
           "saddle": None, "located_by": "bisection"}
    try:
        saddle = _nearest_saddle(param, base, branches, 0.5 * (x + y))
    except ContinuationError:
        saddle = None
    if saddle is None:
        return out
    out["saddle"] = saddle[0]
    v = _on_manifold(param, base, saddle, x, y)
    if v is not None:
        out.update(value=float(v), uncertainty=MANIFOLD_TOL * param.scale, located_by="stable manifold")
    return out
