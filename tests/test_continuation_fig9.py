"""paper-fig9 along a: every change of the period that runs from rest show (a brute-force bisection of long
``simulate`` runs) is matched by the continuation's diagram (slow: a few minutes)."""
import numpy as np
import pytest

from hammerbit.continuation.diagram import continue_orbits
from hammerbit.model.presets import preset
from hammerbit.scene.analysis import detect_period
from hammerbit.scene.simulate import Record, simulate

RANGE = (0.22, 0.09)
#: the brute force: runs from rest this long, a grid, then bisection of each change to this bracket
PERIODS = 1000
GRID = 27
BRACKET = 2e-4
#: the diagram must match each change within this (the issue's bound)
MATCH = 1e-3


def _period_from_rest(g):
    r = simulate(g, PERIODS, record=Record(poincare=True))
    rows = np.column_stack([r.poincare[n] for n in r.poincare.dtype.names])[-64:]
    return detect_period(rows, max_period=16, tol=1e-6)


def _brute_force_changes(base):
    grid = np.linspace(*RANGE, GRID)
    per = [_period_from_rest(base.replace(a=a)) for a in grid]
    changes = []
    for i in range(GRID - 1):
        if per[i] == per[i + 1]:
            continue
        lo, hi = grid[i], grid[i + 1]
        while abs(hi - lo) > BRACKET:
            m = 0.5 * (lo + hi)
            if _period_from_rest(base.replace(a=m)) == per[i]:
                lo = m
            else:
                hi = m
        changes.append((per[i], per[i + 1], 0.5 * (lo + hi)))
    return changes


@pytest.mark.slow
def test_every_change_of_period_from_rest_is_a_located_point_of_the_diagram():
    base = preset("paper-fig9")
    d = continue_orbits(base, "a", *RANGE)
    changes = _brute_force_changes(base)
    assert {(1, 2), (2, 3)} <= {(p, q) for p, q, _ in changes}
    # tension onset changes no period: not a match
    located = [(b.value, b.kind) for b in d.bifurcations if b.kind != "tension"]
    located += [(c[k], "coexistence end") for c in d.coexistence for k in ("from", "to")]
    switches = [c["from_rest_switch"] for c in d.coexistence if c["from_rest_switch"]]
    located += [(sw["value"], sw["located_by"]) for sw in switches]
    for p, q, a in changes:
        value, how = min(located, key=lambda v: abs(v[0] - a))
        assert abs(value - a) <= MATCH, (p, q, a, located)
        # a change of branch from rest is located on the stable manifold of a saddle of the diagram, not by
        # bisecting runs from rest
        assert how != "bisection", (p, q, a, located)
    assert all(sw["saddle"] is not None for sw in switches)
    # the Fig. 9 sequence as stable branches: P1, P2 and P3
    stable_periods = {br.period for br in d.branches if any(pt.stable for pt in br.points)}
    assert {1, 2, 3} <= stable_periods
    assert not d.stops, d.stops
