"""The optimizer with a binding constraint, against a brute-force grid computed here.

Each grid point is simulated here with ``simulate`` (events recorded) and judged
with the constraints written out in the test: the peak contact force is the
largest peak of the logged contacts (start-up included; one still open at the end
is left out, which can only make the grid's best larger), the ROP the advance
between the Poincaré samples at half and full horizon, ``a + b <= 1`` from the
groups, no bounce from the event counts.  The optimum must be at least as good
as the best feasible grid point.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hammerbit.model.presets import preset
from hammerbit.model.settings import apply_settings
from hammerbit.scene.simulate import Record, simulate
from hammerbit.studies.executor import ExecutorOptions
from hammerbit.studies.optimize import Bound, OptimizeConfig, optimize

IN_PROCESS = ExecutorOptions(workers=1)


def _brute_force(g, bounds, periods, n, *, max_contact_force=math.inf):
    """Best feasible ROP [m/h] of an n x n grid, and whether a constraint cut a faster point."""
    best, cut = -math.inf, False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for x in np.linspace(bounds[0].lo, bounds[0].hi, n):
            for y in np.linspace(bounds[1].lo, bounds[1].hi, n):
                s = apply_settings(g, {bounds[0].name: float(x), bounds[1].name: float(y)})
                r = simulate(s, periods, record=Record(poincare=True, events=True))
                x3 = r.poincare["bit_position"]
                rop = s.rop((x3[periods] - x3[periods // 2]) / (periods - periods // 2))["m_per_h"]
                ev = r.events
                peaks = ev["peak_contact_force"][ev["kind"] == "separation"]
                # a contact still open at the end is left out: that can only admit more points
                peak = (peaks.max() if peaks.size else 0.0) * s.scales.friction_force
                ok = (s.a + s.b <= 1.0 and r.counts["bounce"] == 0 and peak <= max_contact_force)
                if ok:
                    best = max(best, rop)
                elif rop > best:
                    cut = True
    return best, cut


def test_contact_force_limit_binding_on_the_lab_rig_with_a_gap():
    """The lab rig with a 20 mm gap: the start-up impact and the steady impacts make the contact
    force grow with amplitude and ROP; a 1200 N limit cuts the fastest cells."""
    g = preset("lab").replace(r=0.8)
    bounds = (Bound("frequency", 1.0, 2.0), Bound("amplitude", 3.0, 30.0))
    periods, limit = 30, 1200.0
    res = optimize(g, OptimizeConfig(bounds=bounds, periods=periods, max_contact_force=limit),
                   options=IN_PROCESS)
    best, cut = _brute_force(g, bounds, periods, 21, max_contact_force=limit)
    assert cut, "the limit must bind for this test to mean anything"
    o = res.optimum
    assert o.feasible and o.peak_contact_force_n <= limit
    assert o.rop_m_per_h >= best
    # the optimum is on the constraint: within 2 % of the limit
    assert o.peak_contact_force_n >= 0.98 * limit
    # the ROP still grows along the limit between the grid's cells: a refinement that follows
    # the active constraint gains over the optimizer's own best cell
    assert o.rop_m_per_h > res.best_grid.rop_m_per_h * (1 + 1e-3)
    # simulate confirms the optimum's ROP and its contact force (one definition of both)
    r = simulate(o.groups, periods, record=Record(poincare=True))
    x3 = r.poincare["bit_position"]
    assert o.groups.rop((x3[periods] - x3[periods // 2]) / (periods - periods // 2))["m_per_h"] == \
        pytest.approx(o.rop_m_per_h, rel=1e-12)
    assert r.peak_contact_force_n() == pytest.approx(o.peak_contact_force_n, rel=1e-12)


def test_static_threshold_binding_over_amplitude_and_preload():
    """paper-fig9 with mu = 0.85 over (a, b) with b <= 0.84 < mu: the ROP grows with both, a + b <= 1
    binds."""
    g = preset("paper-fig9").replace(mu=0.85)
    bounds = (Bound("a", 0.05, 0.6), Bound("b", 0.3, 0.84))
    periods = 30
    res = optimize(g, OptimizeConfig(bounds=bounds, periods=periods), options=IN_PROCESS)
    best, cut = _brute_force(g, bounds, periods, 21)
    assert cut
    o = res.optimum
    assert o.feasible and o.groups.a + o.groups.b <= 1.0
    assert o.rop_m_per_h >= best
    assert o.margins["threshold"] < 0.02 * g.scales.friction_force     # on the line a + b = 1
    assert all(r.drilling and r.period != o.period for r in res.runners_up)


def test_runaway_binding_over_the_preload():
    """paper-fig9 at a = 0.1 over b: the ROP grows with the preload until the drift runs away
    just above mu = 0.85; the runaway cells drill fastest and must be left out.  Runaway is judged
    here by the momentum criterion on dense samples: over the last quarter the bit slides
    faster than v* everywhere, with no stop over the last half, and its mean speed grows."""
    from hammerbit.scene.flags import slip_speed_limit
    g = preset("paper-fig9").replace(a=0.1)
    bounds = (Bound("b", 0.5, 0.95),)
    periods = 100
    res = optimize(g, OptimizeConfig(bounds=bounds, periods=periods), options=IN_PROCESS)
    best, cut = -math.inf, False
    for b in np.linspace(0.5, 0.95, 41):
        s = g.replace(b=float(b))
        t = np.linspace(0.0, periods * s.period, periods * 200 + 1)
        r = simulate(s, periods, record=Record(times=t, poincare=True))
        x3, smp = r.poincare["bit_position"], r.samples
        rop = s.rop((x3[periods] - x3[periods // 2]) / (periods - periods // 2))["m_per_h"]
        n = len(smp)
        q3, q4 = smp[n // 2: 3 * n // 4], smp[3 * n // 4:]
        m3 = (q3["bit_position"][-1] - q3["bit_position"][0]) / (q3["time"][-1] - q3["time"][0])
        m4 = (q4["bit_position"][-1] - q4["bit_position"][0]) / (q4["time"][-1] - q4["time"][0])
        runaway = bool(np.all(smp["slip"][n // 2:] == 1) and q4["bit_velocity"].min() > slip_speed_limit(s)
                       and m4 > m3)
        if s.a + s.b <= 1.0 and r.counts["bounce"] == 0 and not runaway:
            best = max(best, rop)
        elif rop > best:
            cut = True
    assert cut
    o = res.optimum
    assert o.feasible and not o.flags["runaway"]
    assert o.rop_m_per_h >= best
