"""Top conditions of the string side: fixed hook, constant feed, auto-driller (hammerbit.drillstring.top)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hammerbit.cosim.config import CosimConfig, field_hammer
from hammerbit.cosim.master import cosimulate
from hammerbit.cosim.reference import monolithic
from hammerbit.cosim.string_side import StringSide
from hammerbit.drillstring import load_string
from hammerbit.drillstring.top import M_PER_H, TopCondition, auto_driller_gains, series_stiffness


@pytest.fixture(scope="module")
def field():
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def lab():
    return load_string("lab")


def _oracle_step(side, xi0, coeffs, h):
    """The string side with an auto-driller over one step, integrated in *absolute* coordinates
    by a separate fine-tolerance integrator: the block's motion enters through the top spring
    (and the damping of the motion relative to it), never through its acceleration.
    Returns (string state relative to the block, u_top, z, int (F_i - W) dt)."""
    from scipy.integrate import solve_ivp
    ss, g = side.ss, side.gains
    n = ss.A.shape[0]
    nq = n // 2
    M, K, C = ss.mass_matrix, ss.stiffness_matrix, ss.damping_matrix
    Minv = np.linalg.inv(M)
    b = ss.B[nq:, 0] * 0.0
    b[ss.bottom_dof] = 1.0
    trow = ss.C[2, :nq]
    ki, ci = side.ki, side.ci
    ones = np.ones(nq)
    x0, v0, x1, v1, x2, v2 = coeffs

    def rhs(t, y):
        u, v, u_top, z = y[:nq], y[nq:2 * nq], y[2 * nq], y[2 * nq + 1]
        e = trow @ (u - u_top)              # top-element tension: k0 (u_1 - u_top) with the top node fixed
        v_top = g.proportional_gain * e + g.integral_gain * z
        xh = x0 + x1 * t + 0.5 * x2 * t * t
        vh = v0 + v1 * t + 0.5 * v2 * t * t
        f_int = ki * (xh - u[ss.bottom_dof]) + ci * (vh - v[ss.bottom_dof])   # on the string, downward
        acc = Minv @ (-K @ (u - u_top * ones) - C @ (v - v_top * ones) + b * f_int)
        return np.concatenate((v, acc, [v_top, e, -f_int]))

    xi0 = np.asarray(xi0, float)
    r, rd, u_top, z = xi0[:nq], xi0[nq:n], xi0[n], xi0[n + 1]
    v_top = g.proportional_gain * (trow @ r) + g.integral_gain * z
    y0 = np.concatenate((r + u_top, rd + v_top, [u_top, z, 0.0]))
    sol = solve_ivp(rhs, (0.0, h), y0, method="DOP853", rtol=1e-12, atol=1e-15)
    y = sol.y[:, -1]
    u_top, z = y[2 * nq], y[2 * nq + 1]
    v_top = g.proportional_gain * (trow @ (y[:nq] - u_top)) + g.integral_gain * z
    return np.concatenate((y[:nq] - u_top, y[nq:2 * nq] - v_top)), u_top, z, y[-1]


@pytest.mark.parametrize("h", [2e-3, 0.05])
def test_auto_driller_step_is_exact_against_an_absolute_coordinate_oracle(field, h):
    """The augmented string side (relative coordinates, the block's acceleration through the
    string's inertia) steps exactly what the string hung from a PI-driven block does.  Lumped
    mass: the oracle's top node then couples to the DOFs through the stiffness only."""
    cfg = CosimConfig(top=TopCondition.auto_driller(), string_step="dense", mass="lumped", stop=1.0)
    side = StringSide(field, cfg)
    n = side.ss.A.shape[0]
    rng = np.random.default_rng(3)
    xi0 = np.concatenate((rng.normal(0, 1e-5, n // 2), rng.normal(0, 1e-3, n - n // 2), [2e-4, 30.0]))
    coeffs = np.array([1e-4, 2e-3, 5e-3, -0.02, 0.1, 0.4])
    side.xi = xi0.copy()
    imp = side.step(coeffs, h)
    r, u_top, z, imp_ref = _oracle_step(side, xi0, coeffs, h)
    scale = np.max(np.abs(r))
    assert np.max(np.abs(side.xi[:n] - r)) < 1e-8 * scale
    assert side.xi[n] == pytest.approx(u_top, rel=1e-8)
    assert side.xi[n + 1] == pytest.approx(z, rel=1e-8)
    assert imp == pytest.approx(imp_ref, rel=1e-8)


def test_default_gains_follow_the_documented_derivation(field):
    """k_s from the compliances in series; w_n = a fifth of the first mode; critical damping."""
    rig = field_hammer()
    ki = 2e6
    g = auto_driller_gains(field, TopCondition.auto_driller(), interface_stiffness=ki,
                           hammer_stiffness=rig.stiffness)
    ms = field.mesh()
    k_s = 1.0 / (float(np.sum(ms.h / ms.ea)) + 1 / ki + 1 / rig.stiffness)
    assert g.series_stiffness == pytest.approx(k_s, rel=1e-12)
    assert series_stiffness(field, ki, rig.stiffness) == pytest.approx(k_s, rel=1e-12)
    # the first mode of a 2200 m string on its bottom springs: near the quarter wave c / 4L
    assert 0.3 < g.first_mode_hz < 1.5
    w_n = 2 * math.pi * 0.2 * g.first_mode_hz
    assert g.proportional_gain == pytest.approx(2 * w_n / k_s, rel=1e-12)
    assert g.integral_gain == pytest.approx(w_n ** 2 / k_s, rel=1e-12)
    assert g.damping_ratio == pytest.approx(1.0, rel=1e-12)
    assert g.settling_time_s == pytest.approx(6.0 / w_n, rel=1e-12)
    given = auto_driller_gains(field, TopCondition.auto_driller(1e-6, 2e-7), interface_stiffness=ki,
                               hammer_stiffness=rig.stiffness)
    assert (given.proportional_gain, given.integral_gain) == (1e-6, 2e-7)


def test_closed_loop_is_stable_around_the_default_tuning(field):
    """Every eigenvalue of the string side (hammer held) with the auto-driller has a negative
    real part, for the default gains and gains a hundred times smaller or larger."""
    base = StringSide(field, CosimConfig(top=TopCondition.auto_driller())).gains
    for f in (0.01, 1.0, 100.0):
        top = TopCondition.auto_driller(base.proportional_gain * f, base.integral_gain * f)
        side = StringSide(field, CosimConfig(top=top))
        lam = np.linalg.eigvals(side.A1)
        assert np.max(lam.real) < 0.0, f


def test_feed_drills_at_the_block_velocity(field):
    """Kinematics: with a constant feed the string's length stays bounded, so once the WOB has
    settled the bit advances at the block's velocity."""
    V = 100.0 * M_PER_H
    rig = field_hammer().replace(frequency=22.5, amplitude=15e3)
    cfg = CosimConfig(stop=8.0, step=1e-3, rig=rig, top=TopCondition.feed(V), estimate=False,
                      record=("wob", "bit_position", "string_bit_displacement"))
    r = cosimulate(field, cfg)
    d = r.data
    late = d["time"] >= 5.0
    t, x = d["time"][late], d["bit_position"][late]
    rop = (x[-1] - x[0]) / (t[-1] - t[0])
    assert rop == pytest.approx(V, rel=0.05)
    # the string's bottom follows the block: its displacement grows at V too
    s = d["string_bit_displacement"][late]
    assert (s[-1] - s[0]) / (t[-1] - t[0]) == pytest.approx(V, rel=0.05)
    fixed = cosimulate(field, cfg.replace(top=TopCondition.fixed()))
    assert r.penetration_m > 1.5 * fixed.penetration_m


def test_auto_driller_holds_the_wob_where_the_fixed_hook_unloads(field):
    rig = field_hammer().replace(frequency=22.5, amplitude=15e3)
    cfg = CosimConfig(stop=10.0, step=1e-3, rig=rig, top=TopCondition.auto_driller(), estimate=False,
                      record=("wob", "bit_position", "hook_load"))
    r = cosimulate(field, cfg)
    d = r.data
    late = d["time"] >= 8.0
    assert np.mean(d["wob"][late]) == pytest.approx(rig.preload, rel=0.02)
    # the hook load holds the buoyed weight minus the set point, in the mean
    side = StringSide(field, cfg)
    assert np.mean(d["hook_load"][late]) == pytest.approx(side.ss.hook_load, rel=0.01)
    fixed = cosimulate(field, cfg.replace(top=TopCondition.fixed()))
    assert np.mean(fixed.data["wob"][late]) < 0.9 * rig.preload


@pytest.mark.parametrize("top", [TopCondition.feed(60.0 * M_PER_H), TopCondition.auto_driller(1e-4, 1e-4)])
def test_top_conditions_converge_to_the_monolithic_reference(field, top):
    """The exchange's feed (a polynomial input) and the auto-driller's states against the
    reference that integrates the same system as one, the block a state of its own."""
    rig = field_hammer().replace(frequency=22.5, amplitude=15e3)
    cfg = CosimConfig(stop=1.0, step=2.5e-4, rig=rig, top=top, f_max=60.0, estimate=False,
                      record=("wob", "bit_position"))
    ref = monolithic(field, cfg)
    co = cosimulate(field, cfg)
    assert ref.counts["slips"] > 0
    assert co.penetration_m == pytest.approx(ref.penetration_m, rel=2e-3)
    err = np.max(np.abs(co.data["wob"] - ref.data["wob"]))
    assert err < 2e-3 * np.ptp(ref.data["wob"])
    # and the top condition matters at this resolution
    other = monolithic(field, cfg.replace(top=TopCondition.fixed()))
    assert abs(other.penetration_m - ref.penetration_m) > 10 * abs(co.penetration_m - ref.penetration_m)


def test_parse_and_bad_values():
    assert TopCondition.parse("fixed") == TopCondition.fixed()
    assert TopCondition.parse("feed:36").feed_velocity == pytest.approx(0.01)
    a = TopCondition.parse("auto-driller:kp=1e-6,ki=2e-7")
    assert (a.kind, a.proportional_gain, a.integral_gain) == ("auto-driller", 1e-6, 2e-7)
    for text, part in (("bogus", "allowed fixed"), ("feed", "RATE"), ("feed:abc", "'abc'"),
                       ("auto-driller:kd=1", "kd=1"), ("feed:1e9", "feed_velocity"),
                       ("auto-driller:kp=-1", "proportional_gain")):
        with pytest.raises(ValueError, match=part) as e:
            TopCondition.parse(text)
        assert str(e.value).startswith(f"--top {text}")


def test_cli_top_bad_value_exits_2(capsys):
    from cli_run import run_cli
    code, out, err = run_cli(["cosim", "--string", "field-2200m", "--stop", "0.1", "--top", "feed:fast"], capsys)
    assert code == 2
    assert "--top feed:fast" in err and "Traceback" not in err


def sustained_drilling(string, *, stop=60.0, step=1e-3):
    """The sustained-drilling run: 60 s on the field string with the auto-driller (the drilling
    case: A = 15 kN at 22.5 Hz), fixed 1 ms steps (also the benchmark's run)."""
    rig = field_hammer().replace(frequency=22.5, amplitude=15e3)
    cfg = CosimConfig(stop=stop, step=step, rig=rig, top=TopCondition.auto_driller(), estimate=False,
                      record=("wob", "bit_position", "stick"), progress=False)
    return cosimulate(string, cfg)


@pytest.mark.slow
def test_sustained_drilling_with_the_auto_driller(field):
    r = sustained_drilling(field)
    d = r.data
    t = d["time"]
    slip_starts = t[1:][(d["stick"][:-1] > 0.5) & (d["stick"][1:] < 0.5)]
    # slips continue to the end: every second of the last ten has some
    assert np.all(np.histogram(slip_starts, bins=np.arange(50.0, 60.01, 1.0))[0] > 0)
    last = t >= 50.0
    assert np.mean(d["wob"][last]) == pytest.approx(r.config.weight_on_bit, rel=0.02)
    half = np.searchsorted(t, 30.0)
    x = d["bit_position"]
    rop1 = (x[half] - x[0]) / (t[half] - t[0])
    rop2 = (x[-1] - x[half]) / (t[-1] - t[half])
    assert rop2 > 0.0 and rop1 == pytest.approx(rop2, rel=0.1)


def test_feed_is_an_exact_input_of_the_exchange(field):
    """No harmonic force and a fast feed: the hammer is pushed quasi-statically through the
    interface while the block moves. The string sees the feed as an exact polynomial over each
    long step, so the interface force follows the reference to a small fraction of the load
    the feed builds (a feed held constant over a step would be off by k_i V H / 2)."""
    V = 0.1
    rig = field_hammer().replace(amplitude=0.0)
    cfg = CosimConfig(stop=0.5, step=5e-3, rig=rig, top=TopCondition.feed(V), f_max=60.0, estimate=False,
                      check_step=False, record=("interface_force",))
    ref = monolithic(field, cfg)
    co = cosimulate(field, cfg)
    built = np.ptp(ref.data["interface_force"])
    err = np.max(np.abs(co.data["interface_force"] - ref.data["interface_force"]))
    assert built > 1e4
    assert err < 0.1 * cfg.interface_stiffness * V * cfg.step / 2
