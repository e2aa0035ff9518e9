"""Where runs from rest change branch inside a coexistence interval (hammerbit.continuation.basin): the
state at rest crossing the stable manifold of the saddle orbit, against a brute-force bisection of long
``simulate`` runs from rest."""
import numpy as np
import pytest

from hammerbit.continuation import correct_orbit, orbit_from_simulation, period_map
from hammerbit.continuation.basin import MANIFOLD_TOL, rest_switch
from hammerbit.continuation.continuation import Branch, BranchPoint
from hammerbit.continuation.parameter import Parameter
from hammerbit.continuation.monodromy import ORBIT_SOLVER
from hammerbit.model.presets import preset
from hammerbit.model.stepping import Stepper
from hammerbit.scene.analysis import detect_period
from hammerbit.scene.simulate import Record, simulate

#: paper-fig9: P1 (stable down to its subcritical period-doubling at a = 0.1723) and a P2 (stable over the
#: whole interval) coexist here; runs from rest change from P2 to P1 inside it
LO, HI = 0.1735, 0.1765
#: the brute force: runs from rest this long, bisected to this bracket
PERIODS = 1000
BRACKET = 2e-4
#: the issue's bound on the distance of a change of period from rest to a located point
MATCH = 1e-3


def _period_from_rest(g):
    r = simulate(g, PERIODS, record=Record(poincare=True))
    rows = np.column_stack([r.poincare[n] for n in r.poincare.dtype.names])[-64:]
    return detect_period(rows, max_period=16, tol=1e-6)


def _bisect_rest_runs(base, lo, hi):
    p_lo = _period_from_rest(base.replace(a=lo))
    while hi - lo > BRACKET:
        m = 0.5 * (lo + hi)
        if _period_from_rest(base.replace(a=m)) == p_lo:
            lo = m
        else:
            hi = m
    return 0.5 * (lo + hi)


def _branch(orbits):
    return Branch(period=orbits[0].period, points=[BranchPoint(o.groups.a, o) for o in orbits])


@pytest.fixture(scope="module")
def fig9_coexistence():
    """Two-point branches over [LO, HI]: the stable P1, the stable P2 and the saddle P2 between them."""
    base = preset("paper-fig9")
    g_lo, g_hi = base.replace(a=LO), base.replace(a=HI)
    n1, s1 = orbit_from_simulation(g_hi)
    n2, s2 = orbit_from_simulation(g_lo)
    assert (n1, n2) == (1, 2)
    p1 = [correct_orbit(g, s1, 1) for g in (g_lo, g_hi)]
    p2 = [correct_orbit(g, s2, 2) for g in (g_lo, g_hi)]
    # the saddle: Newton on the period-2 map from the P1 orbit displaced along the eigenvector of its
    # multiplier near -1 (the unstable period-2 orbit born at the subcritical doubling lies there)
    mu, vec = np.linalg.eig(p1[0].monodromy)
    v = np.real(vec[:, np.argmin(np.abs(mu + 1))])
    saddle = [correct_orbit(g, p.s + 0.05 * v / np.max(np.abs(v)), 2) for g, p in zip((g_lo, g_hi), p1)]
    return base, [_branch(p1), _branch(p2), _branch(saddle)]


def test_the_saddle_is_the_unstable_period_2_orbit(fig9_coexistence):
    _, (p1, p2, saddle) = fig9_coexistence
    for pt in saddle.points:
        back = period_map(pt.orbit.groups, pt.orbit.s, 1, jacobian=False).s_end
        assert not pt.stable and np.max(np.abs(back - pt.orbit.s)) > 1e-3  # period 2, not the P1 orbit
    assert all(pt.stable for pt in p1.points + p2.points)


def test_runs_from_rest_switch_where_rest_crosses_the_saddles_stable_manifold(fig9_coexistence):
    base, branches = fig9_coexistence
    param = Parameter.on("a", base)
    sw = rest_switch(param, base, branches, LO, HI)
    assert sw is not None
    assert sw["located_by"] == "stable manifold" and sw["saddle"] == 2
    assert (sw["below"], sw["above"]) == (1, 0)  # P2 below the switch, P1 above it
    assert sw["uncertainty"] <= MANIFOLD_TOL
    oracle = _bisect_rest_runs(base, LO, HI)
    assert abs(sw["value"] - oracle) <= MATCH, (sw, oracle)
    # on the manifold a run from rest comes much closer to the saddle than at the ends of the bisection
    assert _closest_approach(base, branches[2], sw["value"]) < 1e-3 * _closest_approach(base, branches[2], oracle)


def _closest_approach(base, saddle, a):
    """The closest a run from rest at ``a`` comes to the saddle's two points at phase 0 (max norm)."""
    g = base.replace(a=a)
    (a0, o0), (a1, o1) = [(pt.value, pt.orbit) for pt in saddle.points]
    w = (a - a0) / (a1 - a0)
    orb = correct_orbit(g, (1 - w) * o0.s + w * o1.s, 2)
    assert not orb.stable
    pts = [orb.s, period_map(g, orb.s, 1, jacobian=False).s_end]
    st = Stepper(g, solver=ORBIT_SOLVER, compile_helper=False)
    poin = np.zeros((61, 5))
    st.advance(60 * g.period, poincare=poin)
    stuck = [y for y in poin[1:, 1:5] if y[3] == 0.0]
    return min(np.max(np.abs(np.array([y[0] - y[2], y[1]]) - p)) for y in stuck for p in pts)
