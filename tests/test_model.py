"""Core model: kernels against closed forms, the paper's results, invariants, solvers."""
import json
import math

import numpy as np
import pytest
from cli_run import run_cli

from hammerbit.scene.analysis import detect_period, largest_lyapunov
from hammerbit.model import kernel_forces, kernel_layouts
from hammerbit.model.params import RigParameters
from hammerbit.model.presets import RIG, preset
from hammerbit.model.settings import apply_settings
from hammerbit.model.validation import ParameterError
from hammerbit.model.solver_errors import EventStormError
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper
from hammerbit.scene.simulate import BounceWarning, Record, simulate

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


def test_si_override_reported_in_si_with_the_scene_scale(capsys):
    """K doubled halves x0 = F0 / K: the SI penetration is the x0 value times 54 N / 4340 N/m."""
    code, out, err = run_cli(["simulate", "--preset", "paper-fig9", "--set", "a=0.11", "--set", "K=4340",
                           "--periods", "100", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["penetration_m"] == pytest.approx(d["penetration_x0"] * 54.0 / 4340.0, rel=1e-12)
    assert d["penetration_m"] == pytest.approx(0.00516, abs=5e-6)


@pytest.mark.parametrize("settings, x0", [
    # x0 = F0 / K = mu_e F_N / K by hand (paper rig: mu_e = 0.62, F_N = 87.1 N, K = 2170 N/m)
    ({"m1": 50.6}, 54.0 / 2170.0),
    ({"F_N": 100.0}, 0.62 * 100.0 / 2170.0),
    ({"K": 4340.0, "m1": 12.65}, 54.0 / 4340.0),
])
def test_simulation_result_in_si_uses_the_scene_scale(settings, x0):
    g = apply_settings(preset("paper-fig9"), settings).replace(a=0.3, eta=1.0)   # a drilling scene
    r = simulate(g, 20)
    assert r.penetration > 0.0
    assert r.penetration_m == pytest.approx(r.penetration * x0, rel=1e-13)


def test_set_errors_use_the_typed_name():
    with pytest.raises(ParameterError) as ei:
        apply_settings(preset("paper-fig9"), {"mu_d": 0.9})
    assert ei.value.name == "mu_d" and "'mu_d'" in str(ei.value)
    with pytest.raises(ParameterError) as ei:
        apply_settings(preset("paper-fig9"), {"K": -1.0})
    assert ei.value.name == "K"


# --------------------------------------------------------------------------- force formulas
def test_force_formulas_against_hand_values():
    """The public force formulas of the kernels at hand-computed points (model.md)."""
    g = preset("paper-fig12").replace(xi=0.1, mu=0.8, gamma_hat=5.0, kc=1e4, n=1.5, lam_hat=0.3, r=0.5)
    p = g.to_kernel()
    # kinetic friction mu + (1 - mu) exp(-gamma_hat v): 1 at rest, mu at high speed
    assert kernel_forces.kinetic_friction(0.0, p) == pytest.approx(1.0, rel=1e-15)
    assert kernel_forces.kinetic_friction(0.2, p) == pytest.approx(0.8 + 0.2 * math.exp(-1.0), rel=1e-15)
    assert kernel_forces.kinetic_friction(100.0, p) == pytest.approx(0.8, rel=1e-15)
    # Hunt-Crossley kc d^n (1 + lam d') in contact, 0 when free or clamped, odd in d
    assert kernel_forces.contact_force(0.01, 0.5, p, kernel_layouts.CONTACT) == pytest.approx(1e4 * 1e-3 * 1.15, rel=1e-14)
    assert kernel_forces.contact_force(0.04, -1.0, p, kernel_layouts.CONTACT) == pytest.approx(1e4 * 0.008 * 0.7, rel=1e-14)
    assert kernel_forces.contact_force(-0.01, 0.0, p, kernel_layouts.CONTACT) == pytest.approx(-10.0, rel=1e-14)
    assert kernel_forces.contact_force(0.01, 0.5, p, kernel_layouts.FREE) == 0.0
    assert kernel_forces.contact_force(0.01, 0.5, p, kernel_layouts.CLAMPED) == 0.0
    y = np.array([1.5, 0.7, 0.96, 0.2])
    assert kernel_forces.overlap(y, p) == pytest.approx(1.5 - 0.96 - 0.5, rel=1e-14)
    fk = (1.5 - 0.96) + 2 * 0.1 * (0.7 - 0.2)                       # 0.64
    assert kernel_forces.spring_damper_force(y, p) == pytest.approx(fk, rel=1e-15)
    fc = 1e4 * 0.04 ** 1.5 * (1 + 0.3 * 0.5)                        # 92
    assert kernel_forces.force_on_bit(y, p, kernel_layouts.CONTACT) == pytest.approx(fk + fc, rel=1e-14)
    assert kernel_forces.force_on_bit(y, p, kernel_layouts.FREE) == pytest.approx(fk, rel=1e-15)


@pytest.mark.parametrize("kw, flags", [
    # bounce: a >= b; overload: a + b > 1; runaway: b above the kinetic floor (mu, or 1 if gamma_hat = 0)
    (dict(a=0.1, b=0.55, mu=0.85, gamma_hat=92.0), (False, False, False)),
    (dict(a=0.55, b=0.55, mu=0.85, gamma_hat=92.0), (True, True, False)),
    (dict(a=0.45, b=0.55, mu=0.85, gamma_hat=92.0), (False, False, False)),   # a + b = 1 exactly
    (dict(a=0.1, b=0.9, mu=0.85, gamma_hat=92.0), (False, False, True)),
    (dict(a=0.1, b=0.9, mu=0.85, gamma_hat=0.0), (False, False, False)),      # floor 1 without decay
    (dict(a=0.3, b=0.2, mu=0.85, gamma_hat=0.0), (True, False, False)),
    (dict(a=0.1, b=0.85, mu=0.85, gamma_hat=92.0), (False, False, False)),    # b = mu exactly
    (dict(a=0.1, b=0.85, mu=0.85, gamma_hat=1e-9), (False, False, False)),    # any decay: floor mu
    (dict(a=0.1, b=0.86, mu=0.85, gamma_hat=1e-9), (False, False, True)),
])
def test_regime_flags(kw, flags):
    from hammerbit.model.regime import regime
    r = regime(preset("paper-fig9").replace(**kw))
    assert (r.bounce, r.overload, r.runaway) == flags


# --------------------------------------------------------------------------- closed forms
def stuck_hammer_exact(g, t0, x1, v1, x3, times):
    """Exact (x1, x1') of the stuck system x1'' + 2 xi x1' + x1 = x3 + b + a sin(eta t + phi)
    from (x1, v1) at t0, at each of ``times``.

    Written as the autonomous linear system z' = M z, z = (x1, x1', sin, cos, 1) of the
    forcing phase, so z(t) = expm(M (t - t0)) z(t0): no particular solution, no modes,
    nothing shared with the kernels' closed form (and valid for any xi, also xi >= 1).
    """
    from scipy.linalg import expm
    M = np.zeros((5, 5))
    M[0, 1] = 1.0
    M[1, 0], M[1, 1], M[1, 2], M[1, 4] = -1.0, -2.0 * g.xi, g.a, g.b + x3
    M[2, 3], M[3, 2] = g.eta, -g.eta
    th = g.eta * t0 + g.phi
    z0 = np.array([x1, v1, math.sin(th), math.cos(th), 1.0])
    z = np.array([expm(M * (t - t0)) @ z0 for t in np.asarray(times, dtype=float)])
    return z[:, 0], z[:, 1]


def _closed_form_used(r):
    """An exact stick chunk evaluates one right-hand side (for its events); a Runge-Kutta
    step evaluates at least 4."""
    return r.stats["rhs"] < 2 * r.stats["steps"]


@pytest.mark.parametrize("label, xi, solver, energy, closed_form, tol", [
    ("adaptive, exact stick chunks", None, TIGHT, False, True, 1e-11),
    ("dp54, exact stick chunks", None, SolverOptions(method="dp54", rtol=1e-12, atol=1e-14), False, True,
     1e-11),
    # the energy block and the fixed-step method integrate the stick phase with Runge-Kutta
    ("adaptive, Runge-Kutta (energy)", None, TIGHT, True, False, 2e-11),
    ("dp54, Runge-Kutta (energy)", None, SolverOptions(method="dp54", rtol=1e-12, atol=1e-14), True, False,
     2e-11),
    ("rk4, 1000 steps per period", None, SolverOptions(method="rk4"), False, False, 2e-10),
    # overdamped (xi >= 1): no closed form in the kernels, Runge-Kutta
    ("adaptive, overdamped", 1.5, TIGHT, False, False, 2e-12),
])
def test_stick_phase_matches_exact_linear_solution(label, xi, solver, energy, closed_form, tol):
    g = preset("paper-fig9").replace(a=0.03)  # F_d stays below the static threshold
    if xi is not None:
        g = g.replace(xi=xi)
    times = np.linspace(0, 20 * g.period, 2001)
    r = simulate(g, 20, record=Record(times=times, energy=energy), solver=solver)
    assert r.counts["slip_start"] == 0
    assert _closed_form_used(r) == closed_form, (label, r.stats)
    x1, v1 = stuck_hammer_exact(g, 0.0, 0.0, 0.0, 0.0, times)
    assert np.max(np.abs(r.samples["hammer_position"] - x1)) < tol, label
    assert np.max(np.abs(r.samples["hammer_velocity"] - v1)) < tol, label
    assert np.all(r.samples["bit_position"] == 0.0) and np.all(r.samples["bit_velocity"] == 0.0)


def test_rk4_stick_error_falls_with_the_fourth_power_of_the_step():
    g = preset("paper-fig9").replace(a=0.03)
    times = np.linspace(0, 10 * g.period, 501)
    x1, _ = stuck_hammer_exact(g, 0.0, 0.0, 0.0, 0.0, times)
    err = [np.max(np.abs(simulate(g, 10, record=Record(times=times),
                                  solver=SolverOptions(method="rk4", steps_per_period=n)
                                  ).samples["hammer_position"] - x1)) for n in (100, 200)]
    assert err[0] / err[1] == pytest.approx(16.0, rel=0.15), err


def test_slip_start_at_the_exact_threshold_crossing():
    """paper-fig9 at a = 0.069: after the first stick, the exact stuck motion drives F_d over
    the static threshold near tau = 70.50 by only 1.8e-4 for 0.06 in tau (a check of the sign
    at step ends would miss it).  The slip must start at the root of the exact F_d - 1."""
    from scipy.optimize import brentq
    g = preset("paper-fig9").replace(a=0.069)
    ev = simulate(g, 15, record=Record(events=True)).events
    assert list(ev["kind"][:3]) == ["slip_start", "stick", "slip_start"]
    s = ev[1]
    t0, x1, v1, x3 = s["time"], s["hammer_position"], s["hammer_velocity"], s["bit_position"]

    def fd_minus_1(t):
        x, v = stuck_hammer_exact(g, t0, x1, v1, x3, [t])
        return (x[0] - x3) + 2.0 * g.xi * v[0] - 1.0

    grid = np.linspace(t0 + 0.1, ev["time"][2] + 1.0, 4001)
    x, v = stuck_hammer_exact(g, t0, x1, v1, x3, grid)
    above = np.nonzero((x - x3) + 2.0 * g.xi * v > 1.0)[0]
    k = above[0]
    t_exact = brentq(fd_minus_1, grid[k - 1], grid[k], xtol=1e-14, rtol=1e-15)
    assert abs(ev["time"][2] - t_exact) < 1e-9
    assert ev["hammer_position"][2] == pytest.approx(stuck_hammer_exact(g, t0, x1, v1, x3, [t_exact])[0][0],
                                                     abs=1e-9)


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
    # the impact is located to machine precision: the indicator x1 - x3 - r at the event state
    # is a few dozen ulp of the positions it subtracts, never before the switch
    ulp = np.finfo(float).eps * (np.abs(imp["hammer_position"]) + np.abs(imp["bit_position"]) + g.r)
    assert np.all(d > -4 * ulp)
    assert np.all(np.abs(d) < 64 * ulp)
    sl = ev[ev["kind"] == "slip_start"]
    y = np.column_stack([sl["hammer_position"], sl["hammer_velocity"], sl["bit_position"], sl["bit_velocity"]])
    p = g.to_kernel()
    for row in y:
        mode_c = kernel_layouts.CONTACT if row[0] - row[2] - g.r > 0 else kernel_layouts.FREE
        # as above: crossed, and within the dense output's accuracy at rtol 1e-8 (in
        # contact F_d rises steeply, ~1e2-1e3 per unit tau, so 1e-10 in tau ~ 1e-7 in F_d)
        fd = kernel_forces.force_on_bit(row, p, mode_c) - 1.0
        assert -1e-12 < fd < 1e-6


@pytest.mark.parametrize("phase", [0.25, 0.7])
def test_poincare_phase_samples_the_right_time(phase):
    """Poincaré rows at tau = (k + phase) T equal dense samples requested at those times
    (an impact scene: both come from the same steps) and, in a stuck scene, the exact
    solution; a sample at phase 0 is a different point."""
    g = preset("paper-fig12").replace(a=0.06)
    P = 30
    T = g.period
    t_k = (np.arange(P) + phase) * T
    r = simulate(g, P, record=Record(poincare=True, poincare_phase=phase, times=t_k))
    pc = r.poincare
    assert len(pc) == P                        # (k + phase) T <= P T for k = 0 .. P - 1
    assert np.max(np.abs(pc["time"] - t_k)) <= 1e-12 * P * T
    for name in ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity"):
        assert np.max(np.abs(pc[name] - r.samples[name])) < 1e-12, name
    assert r.counts["impact"] > 10
    zero = simulate(g, P, record=Record(poincare=True)).poincare
    assert np.max(np.abs(zero["hammer_velocity"][1:P] - pc["hammer_velocity"][1:P])) > 1e-2
    # stuck scene: the exact linear solution at the phase
    g9 = preset("paper-fig9").replace(a=0.03)
    pc9 = simulate(g9, 10, record=Record(poincare=True, poincare_phase=phase)).poincare
    x1, v1 = stuck_hammer_exact(g9, 0.0, 0.0, 0.0, 0.0, pc9["time"])
    assert np.max(np.abs(pc9["hammer_position"] - x1)) < 1e-9
    assert np.max(np.abs(pc9["hammer_velocity"] - v1)) < 1e-9


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
    """Both methods against the independent solve_ivp reference (benchmarks.scipy_reference)."""
    from benchmarks.scipy_reference import simulate_reference
    g = preset(name).replace(a=a)
    ref = simulate_reference(g, 30, rtol=1e-12, atol=1e-14).penetration
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
    from benchmarks.scipy_reference import simulate_reference
    g = preset("paper-fig12")
    ref = simulate_reference(g, 20, rtol=1e-12, atol=1e-14).penetration
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
    from hammerbit.scene.analysis import relative_coordinates
    d = np.linalg.norm(relative_coordinates(r.poincare) - relative_coordinates(r2.poincare), axis=1)
    assert d[5] < 1e-5 and d[-200:].max() > 1e-2


# --------------------------------------------------------------------------- command line
def test_cli_simulate_reports_period_3(capsys):
    code, out, err = run_cli(["simulate", "--preset", "paper-fig9", "--set", "a=0.083", "--periods", "300",
                           "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["period"] == 3
    # x0 = F0 / K = 54 N / 2170 N/m for the paper's rig (hand value, not the code's scales)
    assert d["penetration_x0"] > 0 and d["penetration_m"] == pytest.approx(d["penetration_x0"] * 54.0 / 2170.0)
    assert d["events"]["slip_start"] > 0
    assert d["wall_time_s"] > 0 and math.isfinite(d["wall_time_s"])


def test_cli_bad_value_is_a_clear_error(capsys):
    code, _, err = run_cli(["simulate", "--set", "mu=2"], capsys)
    assert code == 2
    assert "'mu'" in err and "allowed" in err and "Traceback" not in err


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
    from hammerbit.model.solver_errors import StepStormError
    g = preset("paper-fig9")
    with pytest.raises(StepStormError, match="step storm"):
        simulate(g, 5, solver=SolverOptions(rtol=1e-12, atol=1e-14, max_steps_per_period=10))
    # the default cap is far above what a real run needs
    simulate(g, 5, solver=SolverOptions(rtol=1e-13, atol=1e-15))
