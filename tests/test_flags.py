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
from hammerbit.model.regime_codes import REGIME_RUNAWAY, REGIME_STALL
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


# --------------------------------------------------------------------------- late runaways, any horizon
#: The family's earliest last stick [periods]: at 0.95 of the horizon it leaves 60/19 > 3 periods, and
#: the certificate holds from the second Poincaré sample after the last stick on (2.5-2.6 periods).
EARLIEST_LAST_STICK = 60.0


def _late_runaways(mu, db, a_values, horizon=1200, earliest=EARLIEST_LAST_STICK):
    """Scenes of ``paper-fig9`` with ``b = mu + db`` that run away late, with their last stick [periods].

    Generated, not chosen: each ``a`` runs ``horizon`` periods from rest; a late runaway is a scene
    whose bit is sliding at the end, has not stuck since ``earliest`` periods or later, and whose
    speed at the end is far beyond any bounded stick-slip (the independent oracle: the long run).
    """
    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model.stepping import Stepper
    out = []
    for a in a_values:
        g = preset("paper-fig9").replace(mu=mu, b=mu + db, a=float(a))
        st = Stepper(g)
        st.advance(horizon * g.period)
        last = st.fstate[KL.F_T_STICK] / g.period
        if st.istate[KL.I_STICK] == KL.SLIP and earliest <= last <= 0.5 * horizon and st.y[3] > 5.0:
            out.append((g, float(last)))
    return out


def _flagged_at(g, last, fraction):
    """The scene's flags at the horizon that puts its last stick at ``fraction`` of it."""
    horizon = int(np.ceil(last / fraction))
    return horizon, simulate(g, horizon).flags


def test_a_generated_late_runaway_is_flagged_at_any_horizon_past_its_last_stick():
    """Fast representative of the family: a scan over a at mu = 0.65 gives runaways whose last
    stick falls from period 60 to a few hundred; each is flagged at horizons that put that stick at
    0.4 and 0.95 of the horizon, and at optimize's default of 200 periods when it falls in range."""
    fam = _late_runaways(0.65, 0.003, np.linspace(0.2414, 0.2451, 6))
    assert len(fam) >= 2 and max(last for _, last in fam) > 80      # the scan does give late ones
    for g, last in fam:
        for fraction in (0.4, 0.95):
            horizon, fl = _flagged_at(g, last, fraction)
            assert fl.runaway and fl.unusable, (g.a, last, horizon)
            assert fl.code & REGIME_RUNAWAY and "runaway" in fl.flags
        if 0.4 <= last / 200 <= 0.95:
            assert simulate(g, 200).flags.runaway, (g.a, last)
        # three periods after the last stick, wherever that falls between samples (the final state counts)
        between = simulate(g, last + 3.0).flags
        assert between.runaway and between.certified_at <= last + 3.0, (g.a, last, between.certified_at)


@pytest.mark.slow
@pytest.mark.parametrize("mu, db, lo, hi", [(0.7, 0.003, 0.200, 0.2125), (0.65, 0.003, 0.232, 0.2458),
                                            (0.7, 0.001, 0.205, 0.2125), (0.7, 0.006, 0.205, 0.2125)])
def test_the_late_runaway_family_is_flagged_at_every_fraction_of_the_horizon(mu, db, lo, hi):
    """Each scan gives 7 to 18 runaways whose last stick falls between period 60 and 750; every one
    is flagged at five horizons that put that stick at 0.4 to 0.95 of the horizon."""
    fam = _late_runaways(mu, db, np.linspace(lo, hi, 40), horizon=2000)
    assert len(fam) >= 5
    for g, last in fam:
        for fraction in (0.4, 0.55, 0.7, 0.85, 0.95):
            horizon, fl = _flagged_at(g, last, fraction)
            assert fl.runaway, (g.a, last, horizon)


def test_the_certificate_is_never_contradicted_by_a_later_stick():
    """Soundness: whenever a Poincaré state passes the certificate, the bit never sticks again in a
    run four times as long (the solver's own stick tracker, independent of the certificate)."""
    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model.regime import certificate_constants, runaway_certified
    from hammerbit.model.stepping import Stepper
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(24):
        mu = rng.uniform(0.55, 0.85)
        g = preset(rng.choice(["paper-fig9", "paper-fig12"])).replace(
            mu=mu, b=mu + 10 ** rng.uniform(-3.5, -1.5), a=rng.uniform(0.0, 0.35), eta=rng.uniform(0.5, 1.5))
        st = Stepper(g)
        poin = np.zeros((61, 5))
        st.advance(60 * g.period, poincare=poin)
        c = certificate_constants(g)
        k = next((k for k in range(61) if runaway_certified(c, *poin[k])), None)
        if k is None:
            continue
        st.advance(240 * g.period)
        assert st.fstate[KL.F_T_STICK] < poin[k, 0], (g, k)
        assert st.istate[KL.I_STICK] == KL.SLIP
        checked += 1
    assert checked >= 5


def test_the_certificate_is_refused_where_the_gap_may_close():
    """With the gap within reach of the relative oscillator's bound the linear bound does not hold:
    no certificate (the fallback decides)."""
    from hammerbit.model.regime import certificate_constants, runaway_certified
    g = preset("paper-fig9").replace(mu=0.7, b=0.72, a=0.1)
    y = (0.0, 0.75 + 20.0, 20.0, 20.0, 20.0)     # fast, near the quasi-static spring length
    assert runaway_certified(certificate_constants(g), *y)
    assert runaway_certified(certificate_constants(g.replace(r=0.8)), *y)     # beyond the bound: still linear
    assert not runaway_certified(certificate_constants(g.replace(r=0.72)), *y)


# --------------------------------------------------------------------------- stall
def test_stall_at_its_threshold_from_both_sides():
    """paper-fig9 at b = 0.6, a = 0.02 (below the drilling threshold 2 xi (1 - b)): the preload's
    overshoot from rest makes the bit slip once at the start, then it stays stuck.  Stall iff the
    last slip ended at least STALL_PERIODS periods before the end."""
    from hammerbit.model.regime import STALL_PERIODS
    g = preset("paper-fig9").replace(a=0.02, b=0.6)
    r = simulate(g, 40, record=Record(events=True))
    ev = r.events
    assert len(ev[ev["kind"] == "slip_start"]) >= 1
    last = float(ev[ev["kind"] == "stick"]["time"][-1]) / g.period
    assert last < 40 - STALL_PERIODS
    below = simulate(g, last + STALL_PERIODS - 0.5).flags
    above = simulate(g, last + STALL_PERIODS + 0.5).flags
    assert not below.stall and above.stall
    assert above.code & REGIME_STALL and not above.unusable
    assert not simulate(preset("paper-fig9").replace(a=0.2), 60).flags.stall   # P1: slips every period


# --------------------------------------------------------------------------- settling claims only what was seen
@pytest.mark.parametrize("name, changes, periods", [
    ("paper-fig12", dict(a=0.05, **UNCALIBRATED), 300),
    ("paper-fig9", dict(a=0.076633), 300),
    ("paper-fig9", dict(a=0.069), 200),
    ("chaos", {}, 300),
    ("paper-fig12", dict(a=0.044), 200),
])
def test_a_claimed_settling_period_repeats_in_the_run_itself(name, changes, periods):
    """``settling_period`` and ``settled_after`` are facts of the rows: from ``settled_after`` to the
    end the rows repeat with that period (numpy oracle), and nothing is claimed past the horizon."""
    g = preset(name).replace(**changes)
    r = simulate(g, periods, record=Record(poincare=True))
    f = r.flags
    if f.settling_period is None:
        assert f.settled_after is None
        return
    n = f.settling_period
    assert 0 <= f.settled_after < len(r.poincare)
    assert _settled_from(r.poincare, n) == f.settled_after
    # the claimed period repeats over at least the last quarter
    assert f.settled_after <= len(r.poincare) - len(r.poincare) // 4


def test_the_bifurcation_labels_periods_by_the_rule_of_simulate():
    """a = 0.076633 on paper-fig9: the kept tail alone looked like P6; the diagram now reads the period
    and the verdict of the whole run, as simulate does."""
    from hammerbit.studies.bifurcation import bifurcation
    from hammerbit.studies.executor import ExecutorOptions
    values = [0.076633, 0.083, 0.2]
    res = bifurcation(preset("paper-fig9"), "a", values, periods=300, keep=64,
                      options=ExecutorOptions(workers=1))
    for a, per, code in zip(values, res.periods, res.regime):
        fl = simulate(preset("paper-fig9").replace(a=a), 300).flags
        assert per == fl.period and code == fl.code


# --------------------------------------------------------------------------- the lowest drive between events
def test_the_lowest_drive_between_a_bounce_and_its_end_is_found():
    """The drive dips to -1.0063 F0 between two events inside one chunk of the exact stick solution:
    the minimum is searched up to the event, not only at the chunk's ends.  Oracle: the drive of
    2000 dense samples per period."""
    g = preset("chaos").replace(a=0.9941713300908208, b=0.12594126386331259, eta=1.4237915010033286)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r, s, drive = _dense(g, 10, per=2000)
    assert drive.min() < -1.0 - 1e-3                # the dip the test is about
    assert r.flags.min_drive <= drive.min() + 1e-9


# --------------------------------------------------------------------------- co-simulation verdict
def _cosim_result(t, x, stick, wob, *, set_point=50e3, top="auto-driller", counts=None):
    from hammerbit.cosim.config import CosimConfig, CosimResult, field_hammer, record_dtype
    from hammerbit.drillstring.top import TopCondition
    d = np.zeros(len(t), dtype=record_dtype(("wob", "bit_position", "stick")))
    d["time"], d["bit_position"], d["stick"], d["wob"] = t, x, stick, wob
    cfg = CosimConfig(stop=float(t[-1]), rig=field_hammer(), wob=set_point, top=TopCondition(top))
    return CosimResult(data=d, config=cfg, macro_steps=len(t), wall_time_s=0.0, setup_time_s=0.0,
                       penetration_m=float(x[-1]), stats={}, counts=counts or {})


def test_capacity_warning_at_the_rocks_sliding_capacity_from_both_sides():
    """mu_d F_N of the field hammer, recomputed here: 0.56/0.62 of F0 = 100 kN."""
    from hammerbit.cosim.config import CosimConfig, capacity_warning, field_hammer
    from hammerbit.drillstring.top import TopCondition
    cap = 100e3 * RIG.mu_kinetic / RIG.mu_static
    for top in (TopCondition("auto-driller"), TopCondition.feed(0.001)):
        above = capacity_warning(CosimConfig(rig=field_hammer(), wob=cap * (1 + 1e-9), top=top))
        assert above is not None and f"{cap:.6g} N" in above
        assert capacity_warning(CosimConfig(rig=field_hammer(), wob=cap * (1 - 1e-9), top=top)) is None
    # a fixed hook unloads the bit as it advances: no runaway to warn about
    assert capacity_warning(CosimConfig(rig=field_hammer(), wob=2 * cap)) is None


def test_cosim_stall_at_its_weight_fraction_from_both_sides():
    """The bit stuck for the whole run: stall iff the mean WOB over the stall window is at least
    STALL_WOB_FRACTION of the set point (the field hammer drives at 20 Hz: 20 periods = 1 s)."""
    from hammerbit.cosim.config import cosim_regime
    from hammerbit.model.regime import STALL_PERIODS, STALL_WOB_FRACTION
    t = np.linspace(0.0, 2.0, 2001)
    assert STALL_PERIODS / 20.0 < 2.0
    for factor, stall in ((1 + 1e-6, True), (1 - 1e-6, False)):
        wob = np.full_like(t, factor * STALL_WOB_FRACTION * 50e3)
        v = cosim_regime(_cosim_result(t, np.zeros_like(t), np.ones_like(t), wob))
        assert v["stall"] is stall and bool(v["code"] & REGIME_STALL) is stall
    # one slip inside the last STALL_PERIODS periods: no stall; just before them: stall
    T = 1 / 20.0
    for t_slip, stall in ((2.0 - STALL_PERIODS * T + 0.01, False), (2.0 - STALL_PERIODS * T - 0.01, True)):
        stick = np.where(np.abs(t - t_slip) < 0.002, 0.0, 1.0)
        v = cosim_regime(_cosim_result(t, np.zeros_like(t), stick, np.full_like(t, 50e3)))
        assert v["stall"] is stall


def test_cosim_runaway_from_a_drift_that_accelerates_and_not_from_a_steady_one():
    from hammerbit.cosim.config import cosim_regime
    t = np.linspace(0.0, 4.0, 4001)
    slide = np.zeros_like(t)
    wob = np.full_like(t, 100e3)                     # above mu_d F_N = 90.3 kN
    acc = cosim_regime(_cosim_result(t, 0.5 * t ** 2, slide, wob, set_point=100e3))
    steady = cosim_regime(_cosim_result(t, 0.5 * t, slide, wob, set_point=100e3))
    low = cosim_regime(_cosim_result(t, 0.5 * t ** 2, slide, np.full_like(t, 80e3), set_point=80e3))
    assert acc["runaway"] and acc["code"] & REGIME_RUNAWAY
    assert not steady["runaway"] and not low["runaway"]     # no acceleration / WOB below the floor
    # the JSON of the result carries the code and its names
    s = _cosim_result(t, 0.5 * t ** 2, slide, wob, set_point=100e3).summary()
    assert s["regime"] == acc["code"] and s["regime_names"] == ["runaway"]


@pytest.mark.slow
def test_the_cosim_above_the_sliding_capacity_is_warned_before_and_flagged_after(capsys):
    """The issue's run: warned before the run (with the capacity in N), flagged in the JSON and on
    stderr after it."""
    import json
    from cli_run import run_cli
    code, out, err = run_cli(["cosim", "--string", "field-2200m", "--stop", "60", "--set", "frequency=22.5",
                              "--set", "A=15000", "--top", "auto-driller", "--wob", "100000", "--json"], capsys)
    d = json.loads(out)
    cap = 100e3 * RIG.mu_kinetic / RIG.mu_static
    assert f"sliding capacity mu_d F_N = {cap:.6g} N" in err
    assert "runaway" in d["regime_names"] and d["regime"] & REGIME_RUNAWAY
    assert "warning: runaway" in err


@pytest.mark.parametrize("mu, db, a", [(0.7, 0.003, 0.29), (0.67, 0.003, 0.295), (0.6, 0.02, 0.35),
                                       (0.73, 0.001, 0.3)])
def test_no_state_of_a_bounded_stick_slip_passes_the_certificate(mu, db, a):
    """Soundness at every phase: scenes with b just above the friction floor whose bit keeps
    sticking (checked on the run's own events) never show a certified state at any of 100 dense
    samples per period while the bit slides, however fast it slides."""
    from hammerbit.model.regime import certificate_constants, runaway_certified
    g = preset("paper-fig9").replace(mu=mu, b=mu + db, a=a)
    periods = 60
    t = np.linspace(0.0, periods * g.period, periods * 100 + 1)
    r = simulate(g, periods, record=Record(times=t, events=True))
    sticks = r.events["time"][r.events["kind"] == "stick"]
    assert sticks.size and sticks[-1] > 0.9 * periods * g.period        # it keeps sticking to the end
    s = r.samples
    c = certificate_constants(g)
    fast = 0
    for k in np.nonzero((s["slip"] == 1) & (s["time"] < sticks[-1]))[0]:
        row = (s["time"][k], s["hammer_position"][k], s["hammer_velocity"][k], s["bit_position"][k],
               s["bit_velocity"][k])
        assert not runaway_certified(c, *row), row
        fast += s["bit_velocity"][k] > 2 * slip_speed_limit(g)
    assert fast > 100                         # states well above v* were tried


@pytest.mark.parametrize("gamma_hat, b, runaway", [(0.0, 0.9, False), (0.0, 1.02, True), (92.0, 0.9, True)])
def test_the_friction_floor_without_velocity_weakening_is_the_static_threshold(gamma_hat, b, runaway):
    """f_f = mu + (1 - mu) exp(-gamma_hat v): without weakening the friction is 1 at every speed, so
    only b > 1 can run away (the paper's rule and the scene's flag agree); with it, b > mu can."""
    g = preset("paper-fig9").replace(gamma_hat=gamma_hat, b=b, a=0.05)
    r = simulate(g, 120)
    assert r.flags.runaway is runaway
    assert ("b > mu" in r.flags.domain["outside"]) is runaway


@pytest.mark.slow
def test_a_cosim_whose_bit_stops_under_the_held_wob_is_flagged_stall(capsys):
    """Off resonance (14 Hz for the 20 Hz field hammer) under the auto-driller the bit does not slip
    while the WOB is held: stall, in the JSON and on stderr; the recorded stick series agrees."""
    import json
    from cli_run import run_cli
    code, out, err = run_cli(["cosim", "--string", "field-2200m", "--stop", "20", "--set", "frequency=14",
                              "--top", "auto-driller", "--json"], capsys)
    d = json.loads(out)
    assert d["regime_names"] == ["stall"] and d["regime"] == REGIME_STALL
    assert "warning: stall" in err
    assert d["counts"]["slips"] <= 4


@pytest.mark.parametrize("xi", [0.01, 0.071, 0.5, 2.0])
def test_the_oscillator_l1_norms_bound_scipys_impulse_responses(xi):
    """The certificate's L1 norms of the relative oscillator's impulse responses (z and z') are at
    least those of scipy.signal's impulse response, integrated finely, and at most 1.5 % above."""
    from scipy import signal
    from hammerbit.model.regime import C_L1W, C_L1Z, certificate_constants
    g = preset("paper-fig9").replace(xi=xi)
    k = 1.0 + 1.0 / g.rho
    c = certificate_constants(g)
    sigma = xi * k
    slow = sigma - np.sqrt(sigma ** 2 - k) if sigma ** 2 > k else sigma
    t = np.linspace(0.0, 25.0 / slow, 20_001)
    for num, slot in (([1.0], C_L1Z), ([1.0, 0.0], C_L1W)):
        _, h = signal.impulse(signal.lti(num, [1.0, 2.0 * xi * k, k]), T=t)
        l1 = np.trapezoid(np.abs(h), t)
        assert l1 <= c[slot] <= 1.015 * l1


def _ssp_above_capacity(hammer_fmu, out):
    """drilling.ssp of the issue's runaway: field-2200m, 22.5 Hz, A = 15 kN, the auto-driller holding
    100 kN, above mu_d F_N = 90.3 kN."""
    from hammerbit.cosim.config import field_hammer
    from hammerbit.drillstring.top import TopCondition
    from hammerbit.ssp.package import SSPOptions, build_ssp
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # the packed hammer's own start values are not the system's
        return build_ssp("field-2200m", out, SSPOptions(hammer=str(hammer_fmu), stop=2.0, step=1e-3, wob=100e3,
                                                        rig=field_hammer().replace(frequency=22.5, amplitude=15e3),
                                                        top=TopCondition("auto-driller")))


@pytest.mark.slow
def test_cosim_ssp_above_the_sliding_capacity_is_warned_before_the_run_and_carries_the_verdict(
        built_fmu, tmp_path, capsys):
    """``hammerbit cosim --ssp`` as ``hammerbit cosim``: the capacity in N on stderr before the run's
    own lines, and the verdict's capacity and set point in the JSON after it (recomputed here:
    mu_d / mu_e of F0 = 100 kN, and the package's 100 kN)."""
    import json
    from cli_run import run_cli
    ssp = _ssp_above_capacity(built_fmu, tmp_path / "drilling.ssp")
    code, out, err = run_cli(["cosim", "--ssp", str(ssp), "--stop", "0.2", "--json"], capsys)
    cap = 100e3 * RIG.mu_kinetic / RIG.mu_static
    first = err.splitlines()[0]
    assert first.startswith("hammerbit cosim: warning:") and f"sliding capacity mu_d F_N = {cap:.6g} N" in first
    d = json.loads(out)
    assert d["regime_detail"]["sliding_capacity_n"] == pytest.approx(cap, rel=1e-12)
    assert d["regime_detail"]["wob_set_point_n"] == pytest.approx(100e3, rel=1e-12)
    assert code in (0, 5)
