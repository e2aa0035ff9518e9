"""Co-simulation master: string stepped exactly, hammer as FMU / in process."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hammerbit.cosim.config import CosimConfig, CouplingInstabilityError, field_hammer
from hammerbit.cosim.exchange import extrapolation_weights
from hammerbit.cosim.master import cosimulate
from hammerbit.cosim.reference import monolithic
from hammerbit.cosim.string_side import StringSide
from hammerbit.drillstring import load_string
from hammerbit.model.params import RigParameters


# The done criterion: full example string (220 elements, 440 states), H = 1 ms,
# 3 s of simulated time; amplitude over the second half (1.5 .. 3 s).
STOP = 3.0


@pytest.fixture(scope="module")
def string():
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def base():
    return CosimConfig(stop=STOP, step=1e-3, estimate=False)


@pytest.fixture(scope="module")
def reference(string, base):
    return monolithic(string, base)


def test_field_hammer_keeps_groups():
    rig = field_hammer()
    g_lab, g = RigParameters().to_groups(), rig.to_groups()
    for name in ("rho", "xi", "eta", "a", "b", "mu", "gamma_hat", "kc", "n", "lam_hat", "phi"):
        assert getattr(g, name) == pytest.approx(getattr(g_lab, name), rel=1e-12), name
    assert rig.hammer_mass == 400.0
    assert rig.scales.omega / (2 * math.pi) == pytest.approx(20.0)
    assert rig.preload == pytest.approx(55e3)


def test_starts_in_static_equilibrium(string):
    """No harmonic force: nothing moves, the WOB stays the requested one."""
    cfg = CosimConfig(stop=0.5, step=1e-3, rig=field_hammer().replace(amplitude=0.0), wob=40e3,
                      record=("wob", "interface_force", "hammer_velocity", "string_bit_displacement",
                              "hook_load"))
    r = cosimulate(string, cfg)
    assert np.max(np.abs(r.data["wob"] - 40e3)) < 1e-6 * 40e3
    assert np.max(np.abs(r.data["interface_force"] - 40e3)) < 1e-6 * 40e3
    assert np.max(np.abs(r.data["hammer_velocity"])) < 1e-9
    assert np.max(np.abs(r.data["string_bit_displacement"])) < 1e-9
    side = StringSide(string, cfg)
    assert r.data["hook_load"][0] == pytest.approx(side.ss.hook_load, rel=1e-9)


def test_matches_monolithic_wob_amplitude(string, base, reference):
    """Done criterion: extrapolated co-simulation at H = 1 ms within 1e-3 of the monolithic
    dynamic WOB amplitude."""
    r = cosimulate(string, base.replace(extrapolation=2))
    rel = abs(r.wob_amplitude() / reference.wob_amplitude() - 1.0)
    print(f"\nWOB amplitude: cosim {r.wob_amplitude():.3f} N, monolithic "
          f"{reference.wob_amplitude():.3f} N, relative error {rel:.3e}")
    assert rel < 1e-3
    assert reference.wob_amplitude() > 0.2 * reference.wob_mean()   # a real dynamic load
    assert r.penetration_m == pytest.approx(reference.penetration_m, rel=1e-2)
    assert np.array_equal(r.data["time"], reference.data["time"])


@pytest.mark.parametrize("scheme", ["jacobi", "gauss-seidel"])
def test_schemes_and_extrapolation_orders(string, base, reference, scheme):
    errs = []
    for order in (0, 1, 2):
        r = cosimulate(string, base.replace(scheme=scheme, extrapolation=order))
        errs.append(float(np.max(np.abs(r.data["wob"] - reference.data["wob"]))))
    print(f"\n{scheme}: max |WOB error| for order 0, 1, 2: {errs}")
    assert errs[2] < errs[1] < errs[0]
    assert errs[2] < 2e-3 * reference.wob_amplitude() * 2


def test_instability_detected_stiff_interface(string):
    from hammerbit.cosim.error import StepResolutionError
    cfg = CosimConfig(stop=1.0, step=5e-3, interface_stiffness=1e10, estimate=False)
    with pytest.raises(StepResolutionError, match="string mode") as ei:   # refused before the run ...
        cosimulate(string, cfg)
    assert ei.value.limit.frequency_hz == pytest.approx(689.0, rel=1e-2)
    cfg = cfg.replace(check_step=False)                             # ... or caught while it runs
    with pytest.raises(CouplingInstabilityError) as ei:
        cosimulate(string, cfg)
    assert ei.value.step < 50


def test_instability_detected_by_energy_residual(string):
    """With the force blow-up guard off, the power-bond residual alone catches it."""
    cfg = CosimConfig(stop=1.0, step=2e-3, interface_stiffness=2e8, blowup=1e300, estimate=False,
                      check_step=False)
    with pytest.raises(CouplingInstabilityError) as ei:
        cosimulate(string, cfg)
    assert "energy residual" in str(ei.value)
    assert ei.value.residual > ei.value.reference


def test_communication_times_not_accumulated(string):
    cfg = CosimConfig(start=0.1, stop=0.4, step=1e-3, record=("wob",), estimate=False)
    r = cosimulate(string, cfg)
    n = np.arange(len(r.data))
    assert np.array_equal(r.data["time"], 0.1 + n * 1e-3)
    assert len(r.data) == 301


def test_records_only_requested_and_csv(string, tmp_path):
    cfg = CosimConfig(stop=0.2, step=1e-3, record=("wob", "energy_residual"), record_every=10, estimate=False)
    r = cosimulate(string, cfg)
    assert r.data.dtype.names == ("time", "wob", "energy_residual")
    assert len(r.data) == 21
    p = r.to_csv(tmp_path / "r.csv")
    assert p.read_text().splitlines()[0] == "time [s],wob [N],energy_residual [J]"     # SI units for people
    back = np.loadtxt(p, delimiter=",", skiprows=1)
    assert np.array_equal(back[:, 1], r.data["wob"])


def test_config_validation():
    with pytest.raises(ValueError):
        CosimConfig(scheme="newton")
    with pytest.raises(ValueError):
        CosimConfig(extrapolation=3)
    with pytest.raises(ValueError):
        CosimConfig(record=("nonsense",))
    with pytest.raises(TypeError):
        CosimConfig(1.0)  # keyword-only


def test_extrapolation_weights_exact_for_polynomials():
    for order in (0, 1, 2):
        for deg in range(order + 1):
            f = lambda s: s ** deg  # noqa: E731
            mean = 1.0 / (deg + 1)      # mean over [0, 1]
            w = extrapolation_weights(order)
            assert w @ np.array([f(0.0), f(-1.0), f(-2.0)]) == pytest.approx(mean, abs=1e-14)


def test_extrapolation_weights_non_uniform():
    """Any spacing: the mean over [0, r] of the polynomial through t = 0, -1, -1 - q is exact for
    polynomials of the order (a shorter last step, adaptive steps)."""
    for order in (0, 1, 2):
        for r, q in ((0.3, 1.0), (1.0, 2.0), (2.0, 0.5), (0.125, 4.0)):
            w = extrapolation_weights(order, ratio=r, ratio_past=q)
            for deg in range(order + 1):
                mean = r ** deg / (deg + 1)
                vals = np.array([0.0, -1.0, -1.0 - q]) ** deg
                assert w @ vals == pytest.approx(mean, abs=1e-13), (order, r, q, deg)


@pytest.mark.parametrize("form", ["auto", "dense"])
def test_exact_string_step_against_ode(string, form):
    """The exact step (modal and dense forms) with a quadratic hammer motion equals a tight
    ODE solution, state and interface impulse."""
    from scipy.integrate import solve_ivp
    s = string.with_elements([20, 4])
    side = StringSide(s, CosimConfig(string_step=form))
    H = 2e-3
    rng = np.random.default_rng(1)
    xi0 = rng.normal(size=side.n) * 1e-4
    coeffs = np.array([1e-3, 0.1, 5.0, -2.0, 300.0, 50.0])
    side.xi = xi0.copy()
    integ = side.step(coeffs, H)
    assert side.modal is (form == "auto")

    def rhs(t, y):
        w = coeffs[0:2] + coeffs[2:4] * t + 0.5 * coeffs[4:6] * t * t
        xi = y[:-1]
        f = side.frow @ xi - side.ki * w[0] - side.ci * w[1]
        return np.r_[side.A1 @ xi + side.E @ w, f]

    sol = solve_ivp(rhs, (0, H), np.r_[xi0, 0.0], method="DOP853", rtol=1e-12, atol=1e-16)
    assert np.max(np.abs(side.xi - sol.y[:-1, -1])) < 1e-9 * max(1.0, np.max(np.abs(sol.y[:-1, -1])))
    assert integ == pytest.approx(sol.y[-1, -1], rel=1e-7)


def test_with_the_fmu(string, built_fmu):
    """The same run through HammerBitRock.fmu (fmpy FMU2Slave) equals the in-process hammer."""
    fmu = built_fmu
    cfg = CosimConfig(stop=0.5, step=1e-3)
    a = cosimulate(string, cfg, fmu=fmu)
    b = cosimulate(string, cfg)
    assert np.max(np.abs(a.data["wob"] - b.data["wob"])) < 1e-6 * 55e3
    assert a.counts == {k: b.counts[k] for k in a.counts}      # the FMU's counters = the kernels'
    assert a.estimate.wob_amplitude_rel == pytest.approx(b.estimate.wob_amplitude_rel, rel=1e-3, abs=1e-9)
    # equilibrium start through the FMU's initial_hammer_position
    c = cosimulate(string, cfg.replace(rig=field_hammer().replace(amplitude=0.0), stop=0.1), fmu=fmu)
    assert np.max(np.abs(c.data["wob"] - 55e3)) < 1e-6 * 55e3


def test_linear_sweep_matches_frf_and_modes(string):
    """Small excitation (bit stays stuck): the swept WOB amplitude is A |FRF| and its peak
    sits at a natural frequency of the coupled system (bit on bottom, hammer as boundary)."""
    from hammerbit.cosim.linear_modes import coupled_modes
    from hammerbit.studies.sweep import sweep, wob_frf
    cfg = CosimConfig(stop=4.0, step=1e-3, rig=field_hammer().replace(amplitude=2e3), estimate=False)
    freqs = np.array([22.0, 22.5, 23.0])
    res = sweep(string, freqs, cfg)
    assert np.all(res["rop_m_per_h"] == 0.0)           # linear regime: no slip
    lin = 2e3 * np.abs(wob_frf(string, freqs, cfg))
    assert np.max(np.abs(res["wob_amplitude_n"] / lin - 1.0)) < 0.02
    f_peak = freqs[np.argmax(res["wob_amplitude_n"])]
    modes = coupled_modes(string, cfg, f_max=40.0)
    assert np.min(np.abs(modes - f_peak)) < 0.5       # grid spacing 0.5 Hz


def test_cli_cosim_json(tmp_path, capsys):
    import json
    from hammerbit.cli.main import main
    out = tmp_path / "r.csv"
    rc = main(["cosim", "--string", "field-2200m", "--stop", "0.3", "--step", "1e-3", "--scheme",
               "gauss-seidel", "--extrapolation", "1", "--json", "--out", str(out)])
    d = json.loads(capsys.readouterr().out)
    for key in ("wob_mean_n", "wob_amplitude_n", "penetration_m", "macro_steps", "wall_time_s", "counts",
                "error_estimate", "meets_tolerance"):
        assert key in d
    assert rc == (0 if d["meets_tolerance"] else 5)
    assert d["macro_steps"] == 300 and d["stop_s"] == pytest.approx(0.3, abs=1e-15)
    assert set(d["counts"]) == {"slips", "sticks", "impacts", "bounce_violations"}
    assert out.exists()
    head = out.read_text().splitlines()[0].split(",")
    names = [h.split(" [")[0] for h in head]
    assert head[0] == "time [s]" and "stick" in names and "contact" in names


def test_cli_sweep(tmp_path, capsys):
    import json
    from hammerbit.cli.main import main
    rc = main(["sweep", "--string", "field-2200m", "--frequencies", "20", "24", "3", "--duration", "1",
               "--csv", str(tmp_path / "s.csv"), "--plot", str(tmp_path / "s.png"), "--json"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    assert len(d["rows"]) == 3 and (tmp_path / "s.png").exists() and (tmp_path / "s.csv").exists()


# ---------------------------------------------------------------------------
# outputs: shorter last step, counts and flags, ramp, energy residual, dense exchange
# ---------------------------------------------------------------------------
DRILL = field_hammer().replace(frequency=22.5)      # sustained drilling: a slip every cycle


def test_stop_not_a_whole_number_of_steps_ends_with_a_shorter_step(string):
    cfg = CosimConfig(stop=0.0105, step=2e-3, record=("wob", "step_size"), estimate=False)
    assert cfg.macro_steps == 6
    r = cosimulate(string, cfg)
    t = r.data["time"]
    assert t[-1] == 0.0105 and r.summary()["stop_s"] == 0.0105
    assert np.allclose(np.diff(t)[:-1], 2e-3, rtol=0, atol=1e-15)
    assert r.data["step_size"][-1] == pytest.approx(0.5e-3, rel=1e-9)


def test_counts_and_stick_flag_follow_the_bit(string):
    """Drilling: the bit moves only while the stick flag is 0; slips counted = sticks (+1 if it
    ends slipping); the monolithic reference counts the same slips."""
    cfg = CosimConfig(stop=0.5, step=1e-3, rig=DRILL, estimate=False,
                      record=("wob", "bit_position", "bit_velocity", "stick", "contact"))
    r = cosimulate(string, cfg)
    d = r.data
    assert r.counts["slips"] >= 5
    assert r.counts["slips"] - r.counts["sticks"] in (0, 1)
    stuck = d["stick"] == 1.0
    assert np.all(d["bit_velocity"][stuck] == 0.0) and np.all(d["bit_velocity"][~stuck] >= 0.0)
    assert np.any(~stuck) and np.any(stuck)
    assert np.all(d["contact"] == 0.0)                 # no impact device (gap = inf)
    ref = monolithic(string, cfg)
    assert abs(ref.counts["slips"] - r.counts["slips"]) <= 1
    assert np.array_equal(ref.data["stick"][:50], d["stick"][:50])


def test_ramp_rises_from_rest_and_reaches_the_same_steady_state(string):
    cfg = CosimConfig(stop=3.0, step=1e-3, estimate=False, rig=field_hammer().replace(amplitude=2e3),
                      record=("wob",))
    full = cosimulate(string, cfg)
    ramp = cosimulate(string, cfg.replace(ramp=1.0))
    early = slice(1, 60)                               # first 60 ms
    dev = lambda r: np.max(np.abs(r.data["wob"][early] - 55e3))  # noqa: E731
    assert dev(ramp) < 0.1 * dev(full)
    assert ramp.summary()["steady_window_start_s"] == 1.5
    assert ramp.wob_amplitude(2.0) == pytest.approx(full.wob_amplitude(2.0), rel=0.02)


def test_energy_residual_of_the_steady_window(string):
    """The steady window's residual is reported beside the maximum over all windows, which the
    start-up window sets."""
    r = cosimulate(string, CosimConfig(stop=1.0, step=1e-3, estimate=False))
    st = r.stats
    assert 0.0 < st["steady_window_energy_residual_j"] <= st["max_window_energy_residual_j"]
    assert st["steady_window_energy_residual_j"] < 0.5 * st["max_window_energy_residual_j"]


def test_dense_exchange_equals_modal(string):
    """The dense string step (no eigenbasis) gives the modal step's run."""
    cfg = CosimConfig(stop=0.3, step=1e-3, rig=DRILL, estimate=False,
                      record=("wob", "interface_force", "hook_load", "string_bit_displacement"))
    a = cosimulate(string, cfg)
    b = cosimulate(string, cfg.replace(string_step="dense"))
    assert a.stats["modal"] and not b.stats["modal"]
    for name in cfg.record:
        scale = max(np.max(np.abs(a.data[name])), 1e-3)
        assert np.max(np.abs(a.data[name] - b.data[name])) < 1e-8 * scale, name


# ---------------------------------------------------------------------------
# the coupling-error estimate
# ---------------------------------------------------------------------------
def test_step_that_cannot_resolve_is_refused(string):
    from hammerbit.cosim.error import StepResolutionError
    with pytest.raises(StepResolutionError, match="slip dynamics") as ei:
        cosimulate(string, CosimConfig(stop=1.0, step=0.015, rig=DRILL))
    assert ei.value.limit.name == "slip"
    assert ei.value.limit.frequency_hz == pytest.approx(43.7, abs=0.05)      # sqrt(K (1/m1 + 1/m2)) / 2 pi
    assert ei.value.limit.max_step_s == pytest.approx(0.01144, abs=1e-5)
    with pytest.raises(StepResolutionError, match="forcing period"):
        cosimulate(string, CosimConfig(stop=1.0, step=0.012, rig=field_hammer().replace(frequency=45.0)))
    # the same step passes with the check off (the benchmark's coarse end)
    cosimulate(string, CosimConfig(stop=0.05, step=0.015, rig=DRILL, check_step=False, estimate=False))


@pytest.mark.parametrize("case, H", [("stuck", 5e-3), ("stuck", 10e-3), ("drilling", 2e-3), ("drilling", 5e-3)])
def test_estimate_within_a_factor_3_of_the_true_error(string, case, H):
    """Against the monolithic reference (independent: one hybrid system, no exchange)."""
    rig = field_hammer().replace(amplitude=2e3) if case == "stuck" else DRILL
    cfg = CosimConfig(stop=0.5, step=H, rig=rig, record=("wob",))      # >= 8 slips when drilling
    ref = monolithic(string, cfg)
    r = cosimulate(string, cfg)
    e = r.estimate
    true_amp = abs(r.wob_amplitude() / ref.wob_amplitude() - 1.0)
    assert true_amp > 1e-4                              # a real error to estimate
    assert true_amp / 3 <= e.wob_amplitude_rel <= 3 * true_amp
    if case == "drilling":
        assert r.counts["slips"] >= 8
        true_pen = abs(r.penetration_m / ref.penetration_m - 1.0)
        assert true_pen / 3 <= e.penetration_rel <= 3 * true_pen
    else:
        assert r.penetration_m == 0.0 and e.penetration_m == 0.0
    assert e.meets_tolerance is (e.worst <= 1e-3)


@pytest.mark.parametrize("kw", [dict(step=1e-3, estimate=False), dict(step=1e-3, f_max=100.0, estimate=False),
                                dict()], ids=["fixed-nodal", "fixed-modal", "adaptive"])
def test_compiled_entry_points_give_the_dispatchers_bits(kw, monkeypatch):
    """The master calls the exchange through entry points kept per step length; through numba's
    dispatcher on every call the run is the same to the bit (adaptive: many step lengths, rollbacks)."""
    import hammerbit.cosim.lane as cs
    string = load_string("field-2200m")
    c = CosimConfig(stop=0.4, record=("wob", "hammer_position", "hook_load"), progress=False, **kw)
    fast = cosimulate(string, c)
    monkeypatch.setattr(cs, "entry_point", lambda dispatcher, args: dispatcher)
    plain = cosimulate(string, c)
    for name in fast.data.dtype.names:
        assert np.array_equal(fast.data[name], plain.data[name]), name
    assert fast.stats.get("rollbacks") == plain.stats.get("rollbacks")


# ---------------------------------------------------------------------------
# the exchange's polynomials against the interpolation polynomials they stand for
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("gs, order", [(False, 0), (False, 1), (False, 2), (True, 0), (True, 1), (True, 2)],
                         ids=["jacobi-0", "jacobi-1", "jacobi-2", "gs-0", "gs-1", "gs-2"])
def test_taylor_coefficients_are_those_of_the_interpolation_polynomial(gs, order):
    """The hammer motion the string sees over [t_n, t_n + h] is the polynomial through the last
    communication points (Jacobi) or through the new value (Gauss–Seidel), uneven spacings: its
    value, slope and second derivative at t_n, from numpy's fit through the same points."""
    from hammerbit.cosim.exchange import taylor_coefficients
    a, a2, h = 1.3e-3, 0.7e-3, 2.1e-3
    wh = np.array([[0.31, -1.7], [0.12, 2.3], [-0.45, 0.9]])      # (x, v) at t_n, t_{n-1}, t_{n-2}
    x_new, v_new = 0.77, -0.35
    c = np.zeros(6)
    taylor_coefficients(gs, order, a, a2, h, wh, x_new, v_new, c)
    for k, new in ((0, x_new), (1, v_new)):
        if gs and order == 0:
            ts, ws = [0.0], [new]                 # the new value held over the step
        elif gs:
            ts, ws = [h, 0.0, -a][:order + 1], [new, wh[0, k], wh[1, k]][:order + 1]
        else:
            ts, ws = [0.0, -a, -a - a2][:order + 1], list(wh[:order + 1, k])
        poly = np.polyfit(ts, ws, len(ts) - 1)
        want = [np.polyval(np.polyder(poly, d), 0.0) if d < len(poly) else 0.0 for d in range(3)]
        got = [c[k], c[2 + k], c[4 + k]]
        assert got == pytest.approx(want, rel=1e-9, abs=1e-9), (k, got, want)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_held_force_is_the_mean_of_the_extrapolation_polynomial(order):
    """The force the hammer holds is the mean over [t_n, t_n + h] of the polynomial through the
    last forces (uneven spacings), integrated by numpy."""
    from hammerbit.cosim.exchange import held_force
    a, a2, h = 1.3e-3, 0.7e-3, 2.1e-3
    th = np.array([0.5, 0.5 - a, 0.5 - a - a2])
    Fh = np.array([1.0e4, 1.3e4, 0.8e4])
    got = held_force(order, th, Fh, h, np.zeros(3))
    poly = np.polyfit([0.0, -a, -a - a2][:order + 1], Fh[:order + 1], order)
    prim = np.polyint(poly)
    assert got == pytest.approx((np.polyval(prim, h) - np.polyval(prim, 0.0)) / h, rel=1e-12)


class _PrescribedHammer:
    """A hammer side moving on a given smooth trajectory, whatever force it holds."""

    x_eq = 0.0
    master_harmonic = None

    def __init__(self, x, v):
        self.x, self.v, self.t = x, v, 0.0

    def step(self, t, h, force):
        self.t = t + h

    def read(self):
        return np.array([self.x(self.t), self.v(self.t), 0.0, 0.0, 0.0])


@pytest.mark.parametrize("f_max", [None, 100.0], ids=["dense", "modal"])
def test_energy_residual_is_the_step_energy_balance(string, f_max):
    """The energy residual of each step is the energy the string side delivers through the
    interface (trapezoid of F_i v_h on the step ends, with the extrapolated motion at the end,
    here from numpy's polynomial through the last three points) minus the work the held force
    does on the hammer, F_held (x_h(t_n+1) - x_h(t_n)) (Jacobi, order 2, uneven steps)."""
    from hammerbit.cosim.exchange import EXCHANGE_OUT_ENERGY_RESIDUAL, EXCHANGE_OUT_STRING_FORCE
    from hammerbit.cosim.lane import Lane
    cfg = CosimConfig(scheme="jacobi", extrapolation=2, estimate=False, f_max=f_max)
    side = StringSide(string, cfg)
    w = 2 * math.pi * 17.0
    hammer = _PrescribedHammer(lambda t: 1e-4 * math.sin(w * t), lambda t: 1e-4 * w * math.cos(w * t))
    lane = Lane(side, hammer, cfg, 1e-3)
    ki, ci, W = side.ki, side.ci, side.wob
    t = 0.0
    for h in [1e-3, 1e-3, 1e-3, 5e-4, 1e-3, 2e-3, 1e-3, 1e-3]:
        ts = lane.th.copy() - lane.th[0]
        hist = lane.wh.copy()
        F_before = lane.F
        lane.step(t, h)
        x0, v0 = hist[0]
        xe, ve = (np.polyval(np.polyfit(ts, hist[:, k], 2), h) for k in (0, 1))
        F_end = W + lane.sc[EXCHANGE_OUT_STRING_FORCE] - ki * xe - ci * ve
        x_new = hammer.x(t + h)
        want = 0.5 * h * (F_before * v0 + F_end * ve) - lane.F_held * (x_new - x0)
        got = lane.sc[EXCHANGE_OUT_ENERGY_RESIDUAL]
        assert got == pytest.approx(want, rel=1e-7, abs=1e-9 * abs(F_before * v0 * h)), (t, got, want)
        t += h
