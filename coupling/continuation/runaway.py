"""Runaway onset: where the stable stick–slip orbit of a scene that can run away ends at a fold, located along a branch and followed in two parameters.

The regime verdict calls a run a runaway when the bit slips and provably never
sticks again with the inputs held (:func:`hammerbit.model.regime.runaway_certified`,
possible only with the preload above the friction floor, ``b > mu``).  A
periodic orbit is never one: it sticks every period, or (slip only) its bit
velocity dips below ``v*`` each period, where the certificate cannot hold.  So
the verdict changes for the orbit where the family of stick–slip orbits ends:
at a fold (a multiplier +1), past which no periodic orbit is near and a run
from the last orbit's state drifts away.

A candidate is a fold on a branch whose orbit sticks, with ``b`` above the
friction floor (also a ``border-collision`` of the fold test, where the
multipliers jump across +1 at a non-smooth point); it is first refined by
Newton's method on the orbit and the fold test together, so that its orbit is
the fold's to the curve's tolerance, wherever the bisection along the branch
stopped.  It is a ``runaway`` point when the verdict of
runs from its orbit's state, :data:`VERDICT_PERIODS` forcing periods at the
fold's value ± :data:`VERDICT_OFFSET` (scaled), differs: a runaway proved on
one side, none on the other.  Followed in a second parameter as a fold
(:func:`.boundary.follow_boundary`); each point of the curve is checked the
same way, and the curve ends where the check fails (the fold no longer ends
the stick–slip family into a runaway).
"""
from __future__ import annotations

from typing import Callable, Optional

import numpy as np

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups
from hammerbit.model.regime import friction_floor
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.stepping import Stepper
from hammerbit.scene.flags import stepper_flags

from .bifurcation import Bifurcation
from .boundary import Curve, follow_boundary, refine
from .monodromy import ORBIT_SOLVER, ContinuationError
from .orbit import PeriodicOrbit
from .parameter import Parameter

__all__ = ["runaway_side", "detect_runaway", "follow_runaway", "runs_away_from_rest", "VERDICT_OFFSET",
           "VERDICT_PERIODS"]

#: the offset (scaled parameter) either side of a fold at which the verdict of a run from its orbit is read
VERDICT_OFFSET = 1e-6
#: forcing periods of those runs (past a fold the run lingers near the ghost of the orbit before it drifts away)
VERDICT_PERIODS = 400


def _runs_away(groups: Groups, orbit: Optional[PeriodicOrbit], periods: int = VERDICT_PERIODS) -> bool:
    """The verdict's runaway flag of a run of ``groups`` from the orbit's state at phase 0 (None: from rest)."""
    st = Stepper(groups, solver=ORBIT_SOLVER, y0=None if orbit is None else orbit.state, compile_helper=False)
    poin = np.zeros((periods + 1, 5))
    try:
        st.advance(periods * groups.period, poincare=poin)
    except SolverError:
        return False
    return bool(stepper_flags(groups, st, poin[:int(st.istate[KL.I_POIN_NEXT])]).runaway)


def runs_away_from_rest(groups: Groups) -> bool:
    """Whether a run from rest is a runaway by the regime verdict within :data:`VERDICT_PERIODS` periods."""
    return groups.b > friction_floor(groups) and _runs_away(groups, None)


def _candidate(orbit: PeriodicOrbit) -> bool:
    """A stick–slip orbit of a scene whose preload is above the friction floor (it can run away)."""
    sticks = np.any(orbit.events[:, KL.L_KIND].astype(int) == KL.EV_STICK)
    return bool(sticks) and orbit.groups.b > friction_floor(orbit.groups)


def runaway_side(param: Parameter, base: Groups, value: float, orbit: PeriodicOrbit,
                 offset: float = VERDICT_OFFSET) -> Optional[float]:
    """+1 or -1: the side of ``value`` (``offset`` away, scaled) where runs from ``orbit``'s state run away
    while on the other side they do not; None where the verdict does not change across ``value``."""
    verdicts = {}
    for side in (-1.0, 1.0):
        verdicts[side] = _runs_away(param.at(base, value + side * offset * param.scale), orbit)
    if verdicts[1.0] == verdicts[-1.0]:
        return None
    return 1.0 if verdicts[1.0] else -1.0


def detect_runaway(param: Parameter, base: Groups, bifs: list) -> list[Bifurcation]:
    """The ``runaway`` points among the folds ``bifs`` located along ``param`` (see the module docstring)."""
    found = []
    for bif in bifs:
        is_fold = bif.kind == "fold" or (bif.kind == "border-collision" and bif.detail.startswith("fold"))
        if not is_fold or not _candidate(bif.orbit):
            continue
        try:
            fold = refine(base, Bifurcation(kind="fold", value=bif.value, branch=bif.branch, orbit=bif.orbit),
                          param.name)
        except ContinuationError:
            continue
        if not _candidate(fold.orbit):
            continue
        side = runaway_side(param, base, fold.value, fold.orbit)
        if side is None:
            continue
        where = "above" if side > 0 else "below"
        found.append(Bifurcation(kind="runaway", value=fold.value, branch=bif.branch, orbit=fold.orbit,
                                 detail=f"the stick-slip orbits end at a fold (multiplier +1); {where} it a run "
                                        f"from the orbit slips and provably never sticks again"))
    return found


def follow_runaway(base: Groups, bif: Bifurcation, name: str, name2: str, start2: float, end2: float, *,
                   points: int = 21, on_point: Optional[Callable[[float, float], None]] = None) -> Curve:
    """The runaway onset ``bif`` (located along ``name``) over ``name2``: its fold followed, each point
    checked by the verdict of runs either side; the curve ends where a point fails the check."""
    if bif.kind != "runaway":
        raise ValueError(f"follow_runaway follows runaway points, not {bif.kind!r}")
    param = Parameter.on(name, base)
    fold = Bifurcation(kind="fold", value=bif.value, branch=bif.branch, orbit=bif.orbit, detail=bif.detail)
    curve = follow_boundary(base, fold, name, name2, start2, end2, points=points, on_point=on_point)
    curve.kind = "runaway"
    centre = min(range(len(curve.points)), key=lambda i: abs(curve.points[i][0] - bif.value)
                 + abs(curve.points[i][1] - Parameter.on(name2, base).value(bif.orbit.groups)))
    keep_from, keep_to = 0, len(curve.points)
    for step, stop in ((-1, -1), (1, len(curve.points))):
        for i in range(centre + step, stop, step):
            v, w = curve.points[i]
            orbit = curve.orbits[i]
            ok = _candidate(orbit) and runaway_side(param, orbit.groups, v, orbit) is not None
            if not ok:
                why = f"at {name2} = {w:.9g}: the fold no longer ends the stick-slip orbits into a runaway"
                curve.stopped = "; ".join(x for x in (curve.stopped, why) if x)
                if step < 0:
                    keep_from = i + 1
                else:
                    keep_to = i
                break
    curve.points = curve.points[keep_from:keep_to]
    curve.orbits = curve.orbits[keep_from:keep_to]
    return curve
