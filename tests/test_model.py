"""Core model: kernels against closed forms, the paper's results, invariants, solvers."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from hammerbit.analysis import detect_period, largest_lyapunov
from hammerbit.model import kernels as K
from hammerbit.model.params import (RIG, ParameterError, RigParameters, apply_settings,
                                    preset)
from hammerbit.model.stepping import EventStormError, SolverOptions, Stepper
from hammerbit.simulate import BounceWarning, Record, simulate

TIGHT = SolverOptions(rtol=1e-12, atol=1e-14)


# --------------------------------------------------------------------------- parameters
def test_rig_groups_match_spec_derived_values():
    g = RIG.to_groups()
    s = RIG.scales
    assert s.omega == pytest.approx(9.2612, abs=1e-4)
    assert s.length * 1e3 == pytest.approx(24.885, abs=1e-3)
    assert g.rho == pytest.approx(0.26482, abs=1e-5)
    assert g.mu == pytest.approx(0.90323, abs=1e-5)
    assert g.gamma_hat == pytest.approx(92.186, abs=1e-3)
    assert g.kc == pytest.approx(3.1955e4, rel=1e-4)
    assert g.lam_hat == pytest.approx(0.21894, abs=1e-5)
    assert s.omega / (2 * math.pi) == pytest.approx(1.4740, abs=1e-4)


def test_si_groups_round_trip():
    g = preset("paper-fig12").replace(a=0.07, eta=1.1)
    rig = g.to_rig(RIG.scales)
    g2 = rig.to_groups()
    for f in ("rho", "xi", "eta", "a", "b", "r", "mu", "gamma_hat", "kc", "n", "lam_hat", "phi"):
        assert getattr(g2, f) == pytest.approx(getattr(g, f), rel=1e-12)


@pytest.mark.parametrize("kw, name", [
    ({"hammer_mass": 0.0}, "hammer_mass"),
    ({"bit_mass": -1.0}, "bit_mass"),
    ({"mu_kinetic": 0.7}, "mu_kinetic"),
    ({"contact_exponent": 0.0}, "contact_exponent"),
    ({"stiffness": float("nan")}, "stiffness"),
    ({"preload": float("inf")}, "preload"),
])
def test_bad_si_parameters_name_value_and_range(kw, name):
    with pytest.raises(ParameterError) as ei:
        RigParameters(**kw)
    msg = str(ei.value)
    assert name in msg and "allowed" in msg and repr(list(kw.values())[0]) in msg
    assert ei.value.name == name


def test_bad_group_and_settings():
    with pytest.raises(ParameterError, match="'mu'"):
        preset("paper-fig9").replace(mu=1.5)
    with pytest.raises(ParameterError, match="'eta'"):
        preset("paper-fig9").replace(eta=0.0)
    with pytest.raises(ParameterError, match="nonsense"):
        apply_settings(preset("lab"), {"nonsense": 1.0})
    with pytest.raises(ParameterError, match="preset"):
        preset("nope")
    # SI setting converts through the rig scales
    g = apply_settings(preset("paper-fig9"), {"B": 32.4})
    assert g.b == pytest.approx(0.6)


@pytest.mark.parametrize("settings, x0, omega", [
    # x0 = F0 / K and Omega = sqrt(K / m1), computed by hand for each override
    ({"K": 4340.0}, 54.0 / 4340.0, math.sqrt(4340.0 / 25.3)),
    ({"m1": 50.6}, 54.0 / 2170.0, math.sqrt(2170.0 / 50.6)),
    ({"F_N": 100.0}, 0.62 * 100.0 / 2170.0, math.sqrt(2170.0 / 25.3)),
    ({"mu_e": 0.7, "F_N": 100.0, "mu_d": 0.6}, 0.7 * 100.0 / 2170.0, math.sqrt(2170.0 / 25.3)),
])
def test_si_overrides_carry_their_scales(settings, x0, omega):
    g = apply_settings(preset("paper-fig9"), settings)
    assert g.scales.length == pytest.approx(x0, rel=1e-14)
    assert g.scales.omega == pytest.approx(omega, rel=1e-14)
    assert g.length_m(2.0) == pytest.approx(2.0 * x0, rel=1e-14)
    rop = g.rop(0.5)
    period_s = 2 * math.pi / (g.eta * omega)
    assert rop["mm_per_period"] == pytest.approx(0.5 * x0 * 1e3, rel=1e-14)
    assert rop["m_per_h"] == pytest.approx(0.5 * x0 / period_s * 3600, rel=1e-14)
    # group overrides after SI overrides keep the scales
    assert g.replace(a=0.2).scales == g.scales


def test_si_override_reported_in_si_with_the_scene_scale():
    """The issue's case: K doubled halves x0, so the SI penetration is the x0 value times 54/4340."""
    out = subprocess.run([sys.executable, "-m", "hammerbit.cli", "simulate", "--preset", "paper-fig9",
                          "--set", "a=0.11", "--set", "K=4340", "--periods", "100", "--json"],
                         capture_output=True, text=True, check=True)
    d = json.loads(out.stdout)
    assert d["penetration_m"] == pytest.approx(d["penetration_x0"] * 54.0 / 4340.0, rel=1e-12)
    assert d["penetration_m"] == pytest.approx(0.00516, abs=5e-6)


def test_set_errors_use_the_typed_name():
    with pytest.raises(ParameterError) as ei:
        apply_settings(preset("paper-fig9"), {"mu_d": 0.9})
    assert ei.value.name == "mu_d" and "'mu_d'" in str(ei.value)
    with pytest.raises(ParameterError) as ei:
        apply_settings(preset("paper-fig9"), {"K": -1.0})
    assert ei.value.name == "K"


# --------------------------------------------------------------------------- closed forms
def forced_oscillator(t, b, a, eta, phi, xi):
    """x'' + 2 xi x' + x = b + a sin(eta t + phi), x(0) = x'(0) = 0 (xi < 1)."""
    D = (1 - eta ** 2) ** 2 + (2 * xi * eta) ** 2
    P = a * (1 - eta ** 2) / D
    Q = -a * 2 * xi * eta / D
    # particular: b + P sin(eta t + phi) + Q cos(eta t + phi)
    xp0 = b + P * math.sin(phi) + Q * math.cos(phi)
    vp0 = eta * (P * math.cos(phi) - Q * math.sin(phi))
    wd = math.sqrt(1 - xi ** 2)
    c1 = -xp0
    c2 = (-vp0 + xi * c1) / wd
    e = np.exp(-xi * t)
    return (b + P * np.sin(eta * t + phi) + Q * np.cos(eta * t + phi)
            + e * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t)))


def test_stick_phase_matches_forced_damped_oscillator():
    g = preset("paper-fig9").replace(a=0.03)  # F_d stays below the static threshold
    times = np.linspace(0, 20 * g.period, 2001)
    r = simulate(g, 20, record=Record(times=times), solver=TIGHT)
    assert r.counts["slip_start"] == 0
    exact = forced_oscillator(times, g.b, g.a, g.eta, g.phi, g.xi)
    assert np.max(np.abs(r.samples["hammer_position"] - exact)) < 1e-10
    assert np.all(r.samples["bit_position"] == 0.0)


def test_hunt_crossley_restitution_small_lam_v():
    lam = 0.02
    g = preset("paper-fig9").replace(a=0.0, b=0.0, xi=0.0, rho=1e3, r=1e-3, kc=1e7, n=1.5,
                                     lam_hat=lam)
    v0 = 1.0
    r = simulate(g, 0.05, record=Record(events=True), solver=TIGHT, y0=[0.0, v0, 0.0, 0.0])
    ev = r.events
    imp = ev[ev["kind"] == "impact"]
    sep = ev[ev["kind"] == "separation"]
    assert len(imp) == 1 and len(sep) == 1
    v_in = imp["relative_velocity"][0]
    v_out = sep["relative_velocity"][0]
    e = -v_out / v_in
    e_theory = 1 - 2.0 / 3.0 * lam * v_in  # Hunt & Crossley (1975), first order in lam v
    assert abs(e - e_theory) < 2 * (lam * v_in) ** 2
    assert sep["peak_contact_force"][0] > 0


# --------------------------------------------------------------------------- paper results
@pytest.mark.parametrize("a, n", [(0.069, 5), (0.083, 3), (0.11, 2), (0.2, 1)])
def test_paper_fig9_period_sequence(a, n):
    r = simulate(preset("paper-fig9").replace(a=a), 300, record=Record(poincare=True))
    assert detect_period(r.poincare) == n


def test_no_progression_below_threshold_and_impact_starts_earlier():
    # no impact: no drift below a ~ 2 xi (1 - b)
    g9 = preset("paper-fig9")
    assert simulate(g9.replace(a=0.05), 100).penetration == 0.0
    # the same amplitude drills with the impact device
    g12 = preset("paper-fig12")
    assert simulate(g12.replace(a=0.05), 100).penetration > 1.0
    # smallest drilling a on a grid, with and without impact
    grid = np.arange(0.02, 0.09, 0.005)
    first9 = next(a for a in grid if simulate(g9.replace(a=a), 100).penetration > 1e-6)
    first12 = next(a for a in grid if simulate(g12.replace(a=a), 100).penetration > 1e-6)
    assert first12 < first9


def test_penetration_grows_with_a_and_impact_matters_less_at_large_a():
    g9, g12 = preset("paper-fig9"), preset("paper-fig12")
    p9 = [simulate(g9.replace(a=a), 100).penetration for a in (0.1, 0.15, 0.2, 0.25)]
    assert all(np.diff(p9) > 0)
    big9 = simulate(g9.replace(a=0.4), 100).penetration  # large a, still below b (no bounce)
    big12 = simulate(g12.replace(a=0.4), 100).penetration
    small9 = simulate(g9.replace(a=0.08), 100).penetration
    small12 = simulate(g12.replace(a=0.08), 100).penetration
    assert abs(big12 - big9) / big9 < 0.05
    assert abs(small12 - small9) / max(small9, 1e-9) > abs(big12 - big9) / big9


# --------------------------------------------------------------------------- invariants
@pytest.mark.parametrize("name, a", [("paper-fig9", 0.11), ("paper-fig12", 0.06), ("lab", 0.3)])
def test_invariants_on_dense_samples(name, a):
    g = preset(name).replace(a=a)
    times = np.linspace(0, 30 * g.period, 30001)
    r = simulate(g, 30, record=Record(times=times, events=True))
    s = r.samples
    assert np.all(s["bit_velocity"] >= 0.0)
    assert np.all(np.diff(s["bit_position"]) >= 0.0)
    assert np.all(s["contact_force"] >= 0.0)
    assert np.all(np.isfinite(s["hammer_position"]))


def test_events_are_located_to_machine_precision():
    g = preset("paper-fig12")
    r = simulate(g, 20, record=Record(events=True))
    ev = r.events
    imp = ev[ev["kind"] == "impact"]
    assert len(imp) > 5
    d = imp["hammer_position"] - imp["bit_position"] - g.r
    # the event time is the root of the dense output (to a few ulp); the event
    # state is a real step of the method to that time, so the indicator there
    # sits within the dense output's accuracy (rtol 1e-8 -> ~1e-11), never before the switch
    assert np.all(d > -1e-14)
    assert np.all(np.abs(d) < 1e-9)
    sl = ev[ev["kind"] == "slip_start"]
    y = np.column_stack([sl["hammer_position"], sl["hammer_velocity"], sl["bit_position"], sl["bit_velocity"]])
    p = g.to_kernel()
    for row in y:
        mode_c = K.CONTACT if row[0] - row[2] - g.r > 0 else K.FREE
        # as above: crossed, and within the dense output's accuracy at rtol 1e-8 (in
        # contact F_d rises steeply, ~1e2-1e3 per unit tau, so 1e-10 in tau ~ 1e-7 in F_d)
        fd = K.force_on_bit(row, p, mode_c) - 1.0
        assert -1e-12 < fd < 1e-6


def test_deterministic():
    g = preset("paper-fig12")
    r1 = simulate(g, 30, record=Record(poincare=True))
    r2 = simulate(g, 30, record=Record(poincare=True))
    assert np.array_equal(r1.poincare, r2.poincare)


def test_bounce_is_reported_not_hidden():
    g = preset("paper-fig9").replace(a=0.8, b=0.3)
    with pytest.warns(BounceWarning):
        r = simulate(g, 10)
    assert r.counts["bounce"] > 0


def test_event_storm_raises_clear_error():
    g = preset("paper-fig12").replace(a=0.11)
    with pytest.raises(EventStormError, match="event storm"):
        simulate(g, 10, solver=SolverOptions(max_events_per_period=2))


def test_resumable_advance_equals_one_call():
    g = preset("paper-fig12")
    a = Stepper(g)
    a.advance(10 * g.period)
    b = Stepper(g)
    for k in range(1, 101):
        b.advance(k * 0.1 * g.period)
    assert a.y[2] == pytest.approx(b.y[2], rel=1e-6)  # different step sequences, rtol 1e-8
    s = b.get_state()
    c = Stepper(g)
    c.set_state(s)
    b.advance(12 * g.period)
    c.advance(12 * g.period)
    assert np.array_equal(b.y, c.y)


# --------------------------------------------------------------------------- solvers
@pytest.mark.parametrize("name, a", [("paper-fig9", 0.11), ("paper-fig12", 0.06)])
def test_rk4_and_adaptive_agree_within_rk4_error(name, a):
    g = preset(name).replace(a=a)
    ref = simulate(g, 30, solver=TIGHT).penetration
    ad = simulate(g, 30).penetration
    rk = simulate(g, 30, solver=SolverOptions(method="rk4")).penetration
    rk_err = abs(rk - ref)
    assert abs(ad - ref) <= max(rk_err, 1e-6 * abs(ref))
    assert abs(ad - rk) <= 2 * rk_err + 1e-9


@pytest.mark.parametrize("name, a", [("paper-fig9", 0.11), ("paper-fig12", 0.06)])
def test_adaptive_converges_as_rtol_falls(name, a):
    g = preset(name).replace(a=a)
    ref = simulate(g, 30, solver=SolverOptions(rtol=1e-13, atol=1e-15)).penetration
    errs = [abs(simulate(g, 30, solver=SolverOptions(rtol=tol, atol=tol * 1e-2)).penetration - ref)
            for tol in (1e-5, 1e-7, 1e-9, 1e-11)]
    assert errs[-1] < 1e-8 * abs(ref)
    assert errs[-1] < errs[0]
    assert max(errs[2:]) < errs[0]


def test_dp54_agrees():
    g = preset("paper-fig12")
    ref = simulate(g, 20, solver=TIGHT).penetration
    assert simulate(g, 20, solver=SolverOptions(method="dp54", rtol=1e-10, atol=1e-12)).penetration == \
        pytest.approx(ref, rel=1e-6)


def test_lyapunov_negative_on_periodic_orbit():
    lam = largest_lyapunov(preset("paper-fig9").replace(a=0.2), windows=10, transient=100)
    assert lam["lambda_per_period"] < -0.1


def test_chaos_preset_is_chaotic():
    g = preset("chaos")
    lam = largest_lyapunov(g, windows=40, transient=200)
    assert lam["lambda_per_period"] > 0.03
    r = simulate(g, 600, record=Record(poincare=True))
    assert detect_period(r.poincare, max_period=32) is None
    # sensitive dependence: two tolerances separate to the attractor's size
    r2 = simulate(g, 600, record=Record(poincare=True), solver=SolverOptions(rtol=1e-11, atol=1e-13))
    from hammerbit.analysis import relative_coordinates
    d = np.linalg.norm(relative_coordinates(r.poincare) - relative_coordinates(r2.poincare), axis=1)
    assert d[5] < 1e-5 and d[-200:].max() > 1e-2


# --------------------------------------------------------------------------- command line
def test_cli_simulate_reports_period_3():
    out = subprocess.run([sys.executable, "-m", "hammerbit.cli", "simulate", "--preset", "paper-fig9",
                          "--set", "a=0.083", "--periods", "300", "--json"],
                         capture_output=True, text=True, check=True)
    d = json.loads(out.stdout)
    assert d["period"] == 3
    # x0 = F0 / K = 54 N / 2170 N/m for the paper's rig (hand value, not the code's scales)
    assert d["penetration_x0"] > 0 and d["penetration_m"] == pytest.approx(d["penetration_x0"] * 54.0 / 2170.0)
    assert d["events"]["slip_start"] > 0
    assert 0 < d["wall_time_s"] < 5


def test_cli_bad_value_is_a_clear_error():
    out = subprocess.run([sys.executable, "-m", "hammerbit.cli", "simulate", "--set", "mu=2"],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert "'mu'" in out.stderr and "allowed" in out.stderr


def test_variable_communication_steps_leave_no_sliver():
    """Steps of mixed sizes ending a few ulp apart: the stepper never refuses a sliver."""
    from hammerbit.model.params import RigParameters
    rig = RigParameters()
    st = Stepper(rig.to_groups())
    om = rig.scales.omega
    rng = np.random.default_rng(7)
    t = 0.0
    for _ in range(400):
        h = float(rng.choice([1e-4, 1e-3, 7e-3, 0.02, 0.05]))
        st.advance((t + h) * om)
        t += h
    assert st.time == pytest.approx(t * om, rel=1e-14)
    assert st.y[2] > 0.0


def test_step_storm_raises_clear_error():
    from hammerbit.model.stepping import StepStormError
    g = preset("paper-fig9")
    with pytest.raises(StepStormError, match="step storm"):
        simulate(g, 5, solver=SolverOptions(rtol=1e-12, atol=1e-14, max_steps_per_period=10))
    # the default cap is far above what a real run needs
    simulate(g, 5, solver=SolverOptions(rtol=1e-13, atol=1e-15))
