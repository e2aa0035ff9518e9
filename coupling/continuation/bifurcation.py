"""Bifurcations along a branch: their test functions, their location between two points and the switch to the period-doubled branch.

Smooth bifurcations are sign changes of a test function of the Floquet
multipliers ``mu``:

- period-doubling, a multiplier crosses -1: ``prod(mu + 1)``;
- fold, a multiplier crosses +1: ``prod(mu - 1)``;
- Neimark–Sacker, a complex pair crosses the unit circle: ``prod(mu_i mu_j - 1)``
  over the pairs, kept only where the critical pair is complex.

Where a test function changes sign because the multipliers jump across the
critical value at a non-smooth point (no multiplier within
:data:`CRITICAL_TOL` of it at the located point), the point is reported as a
``border-collision``.

Non-smooth ones change what happens along the orbit, read off the events of
one period (:data:`SIGNATURE_KINDS`): an impact appears or disappears (the
contact overlap's maximum touches zero: *grazing*), a stick phase appears or
disappears (the bit velocity's minimum touches zero in slip, or the drive's
maximum touches the static threshold in stick: *sliding*), a bounce appears.  A change in the number of impacts or stick phases per
period counts, not only their appearance from none.
A change is located by bisection of the arclength step between the two points
(each trial a pseudo-arclength correction), until the arclength bracket is
below :data:`LOCATE_TOL`.  The arclength, not the parameter: at a fold the
parameter is quadratic in the arclength, so a parameter bracket of 1e-9 can
still hold the two sides of the fold far apart, with the multiplier far from +1.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups

from .continuation import BranchPoint, corrector
from .monodromy import ContinuationError, period_map
from .orbit import PeriodicOrbit, correct_orbit, make_orbit
from .parameter import Parameter

__all__ = ["Bifurcation", "SMOOTH_KINDS", "SIGNATURE_KINDS", "test_values", "signature", "detect",
           "locate", "switch_period_doubling", "LOCATE_TOL"]

#: the arclength bracket (scaled state and parameter; it bounds the scaled parameter's) at which a
#: bifurcation counts as located
LOCATE_TOL = 1e-9
#: bisection steps at most (the bracket halves each time)
LOCATE_MAX_STEPS = 60
#: the smooth test functions by kind
SMOOTH_KINDS = ("period-doubling", "fold", "neimark-sacker")
#: the event kinds whose counts over a period make an orbit's signature, and the bifurcation a change names
SIGNATURE_KINDS = {KL.EV_IMPACT: "grazing", KL.EV_STICK: "sliding", KL.EV_BOUNCE: "bounce"}
#: a multiplier pair counts as complex at a Neimark–Sacker point above this imaginary part
COMPLEX_TOL = 1e-6
#: a located smooth bifurcation whose multiplier is further than this from the critical value is a jump of
#: the multipliers at a non-smooth point (a border collision), not a smooth crossing
CRITICAL_TOL = 1e-4
#: a multiplier below this is the structural zero of a stick phase (test_values)
ZERO_MULTIPLIER = 1e-8
#: distance from the period-n orbit that a period-2n orbit must keep to count as a new branch
NEW_ORBIT_TOL = 1e-6


@dataclass
class Bifurcation:
    """A located bifurcation: its kind, the parameter value, the branch (index) and the orbit there."""

    kind: str
    value: float
    branch: int
    orbit: PeriodicOrbit
    detail: str = ""


def test_values(orbit: PeriodicOrbit) -> dict:
    """The smooth test functions at an orbit (their sign changes mark a bifurcation)."""
    mu = orbit.multipliers
    # a stick phase collapses the bit-velocity direction of a slipping section: a structural zero that
    # comes and goes with the section's coordinates, not a bifurcation
    mu = mu[np.abs(mu) > ZERO_MULTIPLIER]
    pairs = [mu[i] * mu[j] - 1.0 for i in range(len(mu)) for j in range(i + 1, len(mu))]
    return {"period-doubling": float(np.real(np.prod(mu + 1.0))),
            "fold": float(np.real(np.prod(mu - 1.0))),
            "neimark-sacker": float(np.real(np.prod(pairs))) if pairs else 1.0}


def signature(orbit: PeriodicOrbit) -> dict:
    """Counts of the events of :data:`SIGNATURE_KINDS` over the orbit's period."""
    kinds = orbit.events[:, KL.L_KIND].astype(int) if orbit.events is not None else np.zeros(0, int)
    return {k: int(np.sum(kinds == k)) for k in SIGNATURE_KINDS}


def _changes(a: BranchPoint, b: BranchPoint) -> list[str]:
    out = []
    ta, tb = test_values(a.orbit), test_values(b.orbit)
    for kind in SMOOTH_KINDS:
        if ta[kind] * tb[kind] < 0:
            out.append(kind)
    sa, sb = signature(a.orbit), signature(b.orbit)
    for k, kind in SIGNATURE_KINDS.items():
        if sa[k] != sb[k]:
            out.append(kind)
    return out


def _is_critical(kind: str, orbit: PeriodicOrbit) -> bool:
    """A Neimark–Sacker sign change is one only where the critical pair is complex."""
    if kind != "neimark-sacker":
        return True
    mu = orbit.multipliers
    i = int(np.argmin(np.abs(np.abs(mu) - 1.0)))
    return abs(mu[i].imag) > COMPLEX_TOL


def _changed(kind: str, a: BranchPoint, b: PeriodicOrbit) -> bool:
    if kind in SMOOTH_KINDS:
        return test_values(a.orbit)[kind] * test_values(b)[kind] < 0
    k = next(k for k, v in SIGNATURE_KINDS.items() if v == kind)
    return signature(a.orbit)[k] != signature(b)[k]


def locate(param: Parameter, base: Groups, a: BranchPoint, b: BranchPoint, kind: str) -> Optional[PeriodicOrbit]:
    """The orbit at the ``kind`` bifurcation between the points ``a`` and ``b`` of one branch, or None.

    Bisection of the arclength step from ``a`` along its tangent; each trial is
    corrected onto the branch.  Returns the trial orbit on ``b``'s side of the
    change at the end (the arclength bracket below :data:`LOCATE_TOL`; the tangent is a unit vector,
    so the scaled parameter's bracket is below it too).
    """
    n = a.orbit.period
    xa = np.concatenate([a.orbit.s, [a.value / param.scale]])
    xb = np.concatenate([b.orbit.s, [b.value / param.scale]])
    if xa.shape != xb.shape:
        return None  # the section's coordinates changed between the two: no common arclength
    t = a.tangent
    lo, hi = 0.0, float(t @ (xb - xa))
    best = b.orbit
    for _ in range(LOCATE_MAX_STEPS):
        if abs(hi - lo) < LOCATE_TOL:
            break
        mid = 0.5 * (lo + hi)
        got = corrector(param, base, xa + mid * t, t, n, 12, reach=abs(hi - lo) + abs(mid))
        if got is None:
            return None
        x, res, _ = got
        orb = make_orbit(param.at(base, x[-1] * param.scale), n, x[:-1], res)
        if _changed(kind, a, orb):
            hi, best = mid, orb
        else:
            lo = mid
    return best


def detect(param: Parameter, base: Groups, points: list, branch_index: int) -> list[Bifurcation]:
    """Every bifurcation between consecutive points of a branch, located."""
    found = []
    for a, b in zip(points[:-1], points[1:]):
        for kind in _changes(a, b):
            orb = locate(param, base, a, b, kind)
            if orb is None:
                # not bracketed on one arclength (the section's coordinates changed): the nearer point
                orb = b.orbit
            if not _is_critical(kind, orb):
                continue
            detail = _detail(kind, orb)
            if kind in SMOOTH_KINDS and _critical_distance(kind, orb) > CRITICAL_TOL:
                # the multipliers jumped across the critical value at a non-smooth point
                detail = f"{kind}: the multipliers jump across its critical value at a non-smooth point; {detail}"
                kind = "border-collision"
            found.append(Bifurcation(kind=kind, value=param.value(orb.groups), branch=branch_index, orbit=orb,
                                     detail=detail))
    return found


def _critical_distance(kind: str, orbit: PeriodicOrbit) -> float:
    """How far the orbit's nearest multiplier is from the critical value of ``kind`` (-1, +1, the unit circle)."""
    mu = orbit.multipliers
    if kind == "period-doubling":
        return float(np.min(np.abs(mu + 1.0)))
    if kind == "fold":
        return float(np.min(np.abs(mu - 1.0)))
    return float(np.min(np.abs(np.abs(mu) - 1.0)))


def _detail(kind: str, orbit: PeriodicOrbit) -> str:
    if kind in SMOOTH_KINDS:
        mu = orbit.multipliers
        target = {"period-doubling": -1.0, "fold": 1.0}.get(kind)
        i = int(np.argmin(np.abs(mu - target))) if target is not None else int(np.argmin(np.abs(np.abs(mu) - 1)))
        return f"multiplier {mu[i].real:+.9f}{mu[i].imag:+.9f}j"
    return "an event kind appears or disappears along the orbit"


def _unstable_side(param: Parameter, base: Groups, bif: Bifurcation, q0: float, offset: float) -> float:
    """+1 or -1: the side of the period-doubling where its period-n orbit is unstable (+1 if unknown)."""
    g = param.at(base, (q0 + offset) * param.scale)
    try:
        orb = correct_orbit(g, bif.orbit.s, bif.orbit.period)
    except ContinuationError:
        return 1.0
    return 1.0 if not orb.stable else -1.0


def switch_period_doubling(param: Parameter, base: Groups, bif: Bifurcation, *, offset: float = 1e-3,
                           amplitude: float = 0.03) -> Optional[PeriodicOrbit]:
    """A period-2n orbit next to a period-doubling point, or None.

    Steps ``offset`` (then a tenth of it, with a tenth of the amplitude) to either side and starts Newton's method
    on the period-2n map from the orbit displaced by ``amplitude`` along the
    eigenvector of the multiplier -1 (a period-doubled orbit grows like the
    square root of the distance from the point); keeps the first that converges
    away from the period-n orbit.
    """
    orb = bif.orbit
    mu, vecs = np.linalg.eig(orb.monodromy)
    v = np.real(vecs[:, int(np.argmin(np.abs(mu + 1.0)))])
    v /= np.max(np.abs(v))
    q0 = bif.value / param.scale
    # first the side where the period-n orbit is unstable (a supercritical doubling's period-2n is there)
    first = _unstable_side(param, base, bif, q0, offset)
    for side, off, amp in ((first, offset, amplitude), (-first, offset, amplitude),
                           (first, 0.1 * offset, 0.1 * amplitude), (-first, 0.1 * offset, 0.1 * amplitude)):
        g = param.at(base, (q0 + side * off) * param.scale)
        for sign in (1.0, -1.0):
            s0 = orb.s + sign * amp * v
            if s0.shape[0] == 3 and s0[2] <= 0:
                continue
            try:
                cand = correct_orbit(g, s0, 2 * orb.period)
                back = period_map(g, cand.s, orb.period, jacobian=False).s_end
            except ContinuationError:
                continue
            if back.shape == cand.s.shape and np.max(np.abs(back - cand.s)) > NEW_ORBIT_TOL:
                return cand
    return None
