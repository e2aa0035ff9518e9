"""The bifurcation diagram of one parameter range: branches seeded from runs from rest, followed, their bifurcations, period-doubled branches and coexistence.

:func:`continue_orbits` runs from rest at a few parameter values of the range
(what a rig reaches after start-up), follows every orbit not yet on a branch
across the whole range in both directions, locates the bifurcations of each
branch (:mod:`.bifurcation`), switches to the period-doubled branch at each
period-doubling, and reports where stable branches coexist and which of them
a run from rest reaches there: inside such an interval, the value where runs
from rest change from one branch to the other (a boundary of the basin of
the state at rest, not a bifurcation) is located on the stable manifold of
the saddle orbit between them (:mod:`.basin`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from hammerbit.model.params import Groups

from .basin import RestRun, branch_of, on_branch, rest_run, rest_switch
from .bifurcation import Bifurcation, detect, switch_period_doubling
from .continuation import Branch, BranchPoint, ContinuationOptions, follow_branch
from .monodromy import ContinuationError
from .orbit import MAX_PERIOD, correct_orbit, orbit_from_simulation
from .parameter import Parameter
from .runaway import detect_runaway, runs_away_from_rest
from .touch import detect_touches

__all__ = ["Diagram", "RestRun", "continue_orbits", "stable_intervals", "SEEDS", "MAX_BRANCHES"]

#: parameter values (evenly spread over the range, ends included) where a run from rest seeds branches
SEEDS = 9
#: branches followed at most (period-doubled ones included)
MAX_BRANCHES = 16
#: a branch stopped at the step-size floor this close (scaled parameter) to a located bifurcation of its
#: own has turned at a non-smooth point there (a corner), not failed
CORNER_DISTANCE = 1e-4


@dataclass
class Diagram:
    """Branches, bifurcations and coexistence of periodic orbits over one parameter range."""

    parameter: str
    start: float
    end: float
    branches: list = field(default_factory=list)
    bifurcations: list = field(default_factory=list)
    rest_runs: list = field(default_factory=list)
    coexistence: list = field(default_factory=list)
    #: why a branch stopped inside the range, in words with the parameter value ("" if none did)
    stops: list = field(default_factory=list)


def _follow_both_ways(param, base, orbit, start, end, options, on_point) -> Branch:
    fwd = follow_branch(param, base, orbit, end, options=options, on_point=on_point)
    back = follow_branch(param, base, orbit, start, options=options, on_point=on_point)
    br = Branch(period=orbit.period, points=list(reversed(back.points)) + fwd.points[1:])
    for p in br.points[:len(back.points)]:
        p.tangent = -p.tangent  # the tangents point along the merged branch
    br.stopped = "; ".join(s for s in (back.stopped, fwd.stopped) if s)
    br.ended = "; ".join(s for s in (back.ended, fwd.ended) if s)
    br.end_points = back.end_points + fwd.end_points
    br.stop_points = back.stop_points + fwd.stop_points
    return br


def _toward(param, base, orbit, start, end, origin, options, on_point) -> Branch:
    """A branch born at ``origin`` (a period-doubling) followed away from it to the range's end on its side."""
    v = param.value(orbit.groups)
    target = end if (end - origin) * (v - origin) > 0 else start
    return follow_branch(param, base, orbit, target, options=options, on_point=on_point)


def stable_intervals(branch: Branch) -> list[tuple[float, float, Optional[float], Optional[float]]]:
    """The parameter intervals where the branch is stable: (lo, hi) of its stable points, and the values of
    the unstable neighbours just outside each end (None at the branch's end); the stability changes
    between an end and its neighbour."""
    out = []
    pts = branch.points
    i = 0
    while i < len(pts):
        if not pts[i].stable:
            i += 1
            continue
        j = i
        while j + 1 < len(pts) and pts[j + 1].stable:
            j += 1
        ends = (pts[i].value, pts[j].value)
        outer = (pts[i - 1].value if i > 0 else None, pts[j + 1].value if j + 1 < len(pts) else None)
        (lo, lo_out), (hi, hi_out) = sorted(zip(ends, outer), key=lambda e: e[0])
        out.append((lo, hi, lo_out, hi_out))
        i = j + 1
    return out


def _snap(diagram: Diagram, i: int, value: float, outer: Optional[float]) -> float:
    """A stable interval's end moved onto the bifurcation of its branch located between it and its unstable
    neighbour, if any (the stability changes there)."""
    if outer is None:
        return value
    lo, hi = sorted((value, outer))
    near = [b.value for b in diagram.bifurcations if b.branch == i and lo <= b.value <= hi]
    return min(near, key=lambda v: abs(v - value)) if near else value


def _coexistence(diagram: Diagram, param, base) -> list[dict]:
    spans = [(i, _snap(diagram, i, lo, lo_out), _snap(diagram, i, hi, hi_out))
             for i, br in enumerate(diagram.branches) for lo, hi, lo_out, hi_out in stable_intervals(br)]
    out = []
    for x in range(len(spans)):
        for y in range(x + 1, len(spans)):
            i, lo1, hi1 = spans[x]
            j, lo2, hi2 = spans[y]
            lo, hi = max(lo1, lo2), min(hi1, hi2)
            if i != j and hi > lo:
                mid = 0.5 * (lo + hi)
                out.append({"from": lo, "to": hi, "branches": [i, j],
                            "from_rest": rest_run(param, base, mid, diagram.branches).branch,
                            "from_rest_switch": rest_switch(param, base, diagram.branches, lo, hi)})
    return out


def continue_orbits(base: Groups, name: str, start: float, end: float, *, seeds: int = SEEDS,
                    options: ContinuationOptions = ContinuationOptions(),
                    on_point: Optional[Callable[[BranchPoint], None]] = None) -> Diagram:
    """The periodic orbits of ``base`` along the parameter ``name`` from ``start`` to ``end``.

    Parameters
    ----------
    base : Groups
        The scene; the parameter's own value in it is replaced.
    name : str
        A group or SI parameter as ``--set`` names it (``a``, ``eta``, ``B``, ``frequency`` ...).
    start, end : float
        The range, in the parameter's units (SI names: SI units).
    """
    param = Parameter.on(name, base)
    param_base = base
    diagram = Diagram(parameter=name, start=float(start), end=float(end))
    for value in np.linspace(start, end, seeds):
        run = rest_run(param, param_base, float(value), diagram.branches)
        diagram.rest_runs.append(run)
        if run.period is None:
            g = param.at(param_base, float(value))
            why = ("runs away (the regime verdict: the bit slips and provably never sticks again)"
                   if runs_away_from_rest(g) else
                   f"settles to no period up to {MAX_PERIOD} (chaos, a long period or a long transient)")
            diagram.stops.append(f"{name} = {value:.9g}: a run from rest {why}")
        if run.period is None or run.branch is not None or len(diagram.branches) >= MAX_BRANCHES:
            continue
        g = param.at(param_base, float(value))
        n, s = orbit_from_simulation(g)
        try:
            orbit = correct_orbit(g, s, n)
        except ContinuationError as e:
            diagram.stops.append(f"{name} = {value:.9g}: {e}")
            continue
        _add_branch(diagram, param, param_base,
                    _follow_both_ways(param, param_base, orbit, start, end, options, on_point), options, on_point)
        run.branch = branch_of(diagram.branches, float(value), n, orbit.rop_x0_per_period)
        if run.branch is None:
            run.branch = on_branch(diagram.branches, float(value), orbit)
    diagram.coexistence = _coexistence(diagram, param, param_base)
    return diagram


def _add_branch(diagram: Diagram, param, base, branch: Branch, options, on_point) -> None:
    """Add a branch and its bifurcations; follow the period-doubled branch of each period-doubling."""
    index = len(diagram.branches)
    diagram.branches.append(branch)
    bifs = detect(param, base, branch.points, index) + detect_touches(param, base, branch.points, index)
    bifs += detect_runaway(param, base, bifs)
    diagram.bifurcations.extend(bifs)
    failed = []
    for point, why in branch.stop_points:
        near = [b for b in bifs if abs(b.value - point.value) <= CORNER_DISTANCE * param.scale]
        if near:
            reason = (f"at {param.name} = {point.value:.9g} the branch turns at a non-smooth point next to its "
                      f"{near[0].kind} (a corner the continuation does not pass)")
            branch.ended = "; ".join(x for x in (branch.ended, reason) if x)
            branch.end_points.append((point, reason))
        else:
            failed.append(why)
    branch.stopped = "; ".join(failed)
    diagram.stops.extend(failed)
    for point, reason in branch.end_points:
        diagram.bifurcations.append(Bifurcation(kind="branch-end", value=point.value, branch=index,
                                                orbit=point.orbit, detail=reason))
    for bif in bifs:
        if bif.kind != "period-doubling" or len(diagram.branches) >= MAX_BRANCHES:
            continue
        doubled = switch_period_doubling(param, base, bif)
        if doubled is None:
            diagram.stops.append(f"no period-{2 * branch.period} orbit found next to the period-doubling at "
                                 f"{param.name} = {bif.value:.9g}")
            continue
        child = _toward(param, base, doubled, diagram.start, diagram.end, bif.value, options, on_point)
        _add_branch(diagram, param, base, child, options, on_point)
