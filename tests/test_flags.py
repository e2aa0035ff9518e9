"""The scene's own flags (runaway, bounce, tension, transient period) against criteria
computed here from the trajectory, on each side of each condition, from rest and preloaded.

The oracles are dense samples of ``simulate`` (4000 per forcing period) and the
drive f_k + f_c computed in the test from them; the flags come from the solver's
trackers and :mod:`hammerbit.scene.flags`.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from hammerbit.model.presets import RIG, preset
from hammerbit.scene.analysis import relative_coordinates, PERIOD_TOL
from hammerbit.scene.flags import slip_speed_limit
from hammerbit.scene.simulate import Record, simulate

SAMPLES_PER_PERIOD = 4000


def _dense(g, periods, y0=None, per=SAMPLES_PER_PERIOD):
    t = np.linspace(0.0, periods * g.period, periods * per + 1)
    r = simulate(g, periods, record=Record(times=t), y0=y0)
    s = r.samples
    drive = ((s["hammer_position"] - s["bit_position"]) + 2 * g.xi * (s["hammer_velocity"] - s["bit_velocity"])
             + s["contact_force"])
    return r, s, drive


def _preloaded(g):
    return [g.b, 0.0, 0.0, 0.0]


# --------------------------------------------------------------------------- tension and bounce
@pytest.mark.parametrize("name, changes, start", [
    ("paper-fig9", dict(a=0.11), "rest"),                   # the drive never goes below its start, 0
    ("paper-fig9", dict(a=0.27, b=0.3, eta=0.2), "rest"),  # just below the tension threshold
    ("paper-fig9", dict(a=0.31, b=0.3, eta=0.2), "rest"),  # just above it
    ("paper-fig9", dict(a=0.3, b=0.3), "rest"),
    ("paper-fig9", dict(a=0.1), "preloaded"),               # lowest drive 0.057 F0 above zero
    ("chaos", {}, "rest"),
])
def test_tension_and_lowest_drive_match_the_sampled_trajectory(name, changes, start):
    g = preset(name).replace(**changes)
    r, s, drive = _dense(g, 40, y0=_preloaded(g) if start == "preloaded" else None)
    low = float(drive.min())
    assert r.flags.tension == (low < 0.0)
    # the solver locates the minimum between samples: never above the sampled one, close to it
    assert r.flags.min_drive <= low + 1e-9
    assert r.flags.min_drive == pytest.approx(low, abs=2e-5)


@pytest.mark.parametrize("a, start", [(0.8, "rest"), (0.9, "rest"), (0.8, "preloaded"), (0.95, "preloaded")])
def test_bounce_flag_and_count_match_the_sampled_trajectory(a, start):
    """b = 0.3, eta = 0.2: the drive reaches -F_s while stuck between a = 0.8 and 0.9."""
    g = preset("paper-fig9").replace(a=a, b=0.3, eta=0.2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # the BounceWarning of the scenes that bounce
        r, s, drive = _dense(g, 10, y0=_preloaded(g) if start == "preloaded" else None)
    below = (s["slip"] == 0) & (drive < -1.0)
    assert r.flags.bounce == bool(below.any())
    # each violation is one stretch of stuck samples below -F_s
    stretches = int(np.count_nonzero(np.diff(below.astype(int)) == 1) + below[0])
    assert r.flags.bounces == stretches


# --------------------------------------------------------------------------- runaway
def _runaway_oracle(g, periods, y0):
    """Runaway by the momentum argument: over the last quarter the bit slides without a stop
    and faster than v* everywhere (friction below the preload), and its mean speed grows."""
    r, s, _ = _dense(g, periods, y0=y0, per=200)
    n = len(s)
    q3, q4 = s[n // 2: 3 * n // 4], s[3 * n // 4:]
    v_star = slip_speed_limit(g)
    mean3 = (q3["bit_position"][-1] - q3["bit_position"][0]) / (q3["time"][-1] - q3["time"][0])
    mean4 = (q4["bit_position"][-1] - q4["bit_position"][0]) / (q4["time"][-1] - q4["time"][0])
    sliding = bool(np.all(s["slip"][n // 2:] == 1))
    return r, sliding and bool(q4["bit_velocity"].min() > v_star) and mean4 > mean3


@pytest.mark.parametrize("changes, start", [
    (dict(b=0.9, a=0.02), "rest"),          # from rest the preload overshoots and kicks the bit into sliding
    (dict(b=0.9, a=0.005), "preloaded"),    # the same preload applied gently: no drift at all
    (dict(b=0.86, a=0.0), "rest"),
    (dict(b=0.86, a=0.0), "preloaded"),
    (dict(b=0.852, a=0.02), "rest"),        # just above mu = 0.85
    (dict(b=0.848, a=0.02), "rest"),        # just below
    (dict(mu=0.5, b=0.52, a=0.1), "rest"),  # b > mu, bounded stick-slip
    (dict(gamma_hat=2.0, b=0.9, a=0.1), "rest"),
    (dict(gamma_hat=0.5, b=0.86, a=0.1), "rest"),
])
def test_runaway_flag_matches_the_momentum_criterion(changes, start):
    g = preset("paper-fig9").replace(**changes)
    r, expected = _runaway_oracle(g, 200, _preloaded(g) if start == "preloaded" else None)
    assert r.flags.runaway == expected
    if g.b <= g.mu:
        assert not r.flags.runaway          # friction exceeds the preload at every speed


def test_runaway_flags_differ_from_the_papers_rule():
    """b > mu is only the paper's domain: a preloaded start with b = 0.9 stays stuck (no runaway),
    the same scene from rest runs away."""
    g = preset("paper-fig9").replace(b=0.9, a=0.005)
    rest = simulate(g, 200)
    pre = simulate(g, 200, y0=_preloaded(g))
    assert rest.flags.runaway and not pre.flags.runaway
    assert pre.penetration == 0.0
    assert rest.flags.domain == pre.flags.domain == {"inside": False, "outside": ["b > mu"]}


# --------------------------------------------------------------------------- transient period
def _settled_from(poincare, n):
    s = relative_coordinates(poincare)
    dev = np.max(np.abs(s[n:] - s[:-n]) / (1 + np.abs(s[n:])), axis=1)
    bad = np.nonzero(~(dev <= PERIOD_TOL))[0]
    return 0 if bad.size == 0 else int(bad[-1] + 1)


#: The uncalibrated paper-fig12 scene (the rig's damping, mu = 0.85), whose orbit at a = 0.05
#: wanders through P4 for hundreds of periods before it settles into P2.
UNCALIBRATED = {"xi": RIG.to_groups().xi, "mu": 0.85}


def test_paper_fig12_at_a_005_is_a_transient_p4_at_300_periods_and_p2_at_1000():
    g = preset("paper-fig12").replace(a=0.05, **UNCALIBRATED)
    long = simulate(g, 1000, record=Record(poincare=True))
    short = simulate(g, 300, record=Record(poincare=True))
    assert long.flags.period == 2 and not long.flags.transient
    assert long.flags.settled_after == _settled_from(long.poincare, 2)
    assert short.flags.transient and short.flags.period != 2 and short.flags.settling_period == 2
    # it settles into P2 before the end of the short run, at the same period as in the long run
    assert short.flags.settled_after == long.flags.settled_after < 300


def test_a_settled_orbit_is_not_transient():
    g = preset("paper-fig9").replace(a=0.083)
    r = simulate(g, 300, record=Record(poincare=True))
    assert r.flags.period == 3 and not r.flags.transient
    assert r.flags.settled_after == _settled_from(r.poincare, 3) < 150
