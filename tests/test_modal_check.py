"""Hammer/bit frequency avoidance check: receptance, damping, continuity, windows, CLI.

Independent oracles written here (not with the library's transfer matrix):

* uniform bar, top fixed, undamped, ``k = w/c``: force at a free bit
  ``H = tan(kL)/(EA k)``; prescribed displacement ``D = EA k cot(kL)``;
* a damped piecewise-uniform string: :func:`tm_dynamic_stiffness` below,
  the transfer matrix on ``[u, EA u']`` with ``EA* = EA (1 + i eta)`` and
  ``m* = m' - i c'/w`` (complex modulus and viscous drag);
* natural frequencies of two sections: the explicit equations of
  ``test_drillstring.two_section_closed_form``.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from hammerbit.cli import main as cli
from hammerbit.drillstring import (
    Boundary,
    DampingModel,
    DrillString,
    Section,
    assemble,
    bit_dynamic_stiffness,
    bit_receptance,
    exact_dynamic_stiffness,
    load_string,
    modes,
    state_space,
    static_compliance,
)
from hammerbit.check.frequency import (
    FAIL,
    MARGIN,
    NOMINAL_ONLY,
    RECEPTANCE,
    CheckConfig,
    check,
    plot_campbell,
    plot_check,
    plot_receptance,
    resonance_factor,
)
from hammerbit.model.validation import ParameterError
from test_drillstring import lab_closed_form, two_section_closed_form, LAB_HOLDER, LAB_ROD


@pytest.fixture(scope="module")
def field() -> DrillString:
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def well() -> DrillString:
    """400 m water-well string: 3.5 in drill pipe over 4.75 in collars, 2 % damping."""
    return DrillString((Section("dp 3.5in", 340.0, 0.0889, 0.0702), Section("dc 4.75in", 60.0, 0.1207, 0.0572)),
                       name="well-400m", modal_damping_ratio=0.02, on_bottom=Boundary.fixed())


@pytest.fixture(scope="module")
def lab() -> DrillString:
    return load_string("lab")


@pytest.fixture(scope="module")
def bar() -> DrillString:
    """Uniform 2200 m drill pipe, undamped."""
    return DrillString.uniform(2200.0, 0.127, 0.1086, elements=400)


@pytest.fixture(scope="module")
def field_check_20hz(field):
    return check(field, CheckConfig(excitation_hz=20.0, frequency_range_hz=(0.0, 40.0), min_window=0.0))


def tm_dynamic_stiffness(sections, f, eta, top_fixed=True, k_top=0.0):
    """D = N/u at the bit of a damped string, bit held, integrated top to bottom (oracle)."""
    w = 2 * math.pi * np.atleast_1d(f)
    u = np.zeros(w.size, complex) if top_fixed else np.ones(w.size, complex)
    n = np.ones(w.size, complex) if top_fixed else np.full(w.size, k_top, complex)
    for s in sections:
        ea = s.axial_stiffness * (1 + 1j * eta)
        k = np.sqrt((w * w * s.mass_per_length - 1j * w * s.viscous_damping) / ea)
        c, sn = np.cos(k * s.length), np.sin(k * s.length)
        u, n = c * u + sn / (ea * k) * n, -ea * k * sn * u + c * n
    return n / u


# ------------------------------------------------------------------ receptance and damping
def test_fe_receptance_matches_dense_solve(field):
    """The pivot recursion equals a dense solve of K(1 + i eta) - w^2 M + i w C."""
    secs = tuple(Section(s.name, s.length, s.od, s.id, viscous_damping=40.0) for s in field.sections)
    s = field.replace(sections=secs, modal_damping_ratio=0.03).with_elements((20, 4))
    f = np.array([0.2, 0.9, 3.3, 7.7, 15.1])
    for bottom in ("spring:5e8:3e5:500", "free", "free:2000"):
        asm = assemble(s, "fixed", bottom)
        ref = []
        for x in f:
            w = 2 * math.pi * x
            K = asm.K.copy()
            kb = asm.bottom.ground_stiffness
            K[-1, -1] -= kb
            Z = K * (1 + 0.06j) - w * w * asm.M + 1j * w * asm.C_viscous
            Z[-1, -1] += kb
            e = np.zeros(asm.n_dof)
            e[-1] = 1.0
            ref.append(np.linalg.solve(Z, e)[-1])
        h = bit_receptance(s, f, "fixed", bottom, correct=False)
        assert np.allclose(h, ref, rtol=1e-9, atol=0)


def test_receptance_analytic_uniform_bar(bar):
    sec = bar.sections[0]
    ea, L, c = sec.axial_stiffness, sec.length, sec.wave_speed
    f = np.array([0.05, 0.2, 0.9, 2.0, 3.1, 4.4])
    k = 2 * math.pi * f / c
    h = bit_receptance(bar, f, "fixed", "free")
    assert np.allclose(h.real, np.tan(k * L) / (ea * k), rtol=1e-7)
    assert np.allclose(h.imag, 0.0, atol=1e-14)
    d_ref = ea * k / np.tan(k * L)
    assert np.allclose(bit_dynamic_stiffness(bar, f, "fixed").real, d_ref, rtol=1e-7)
    assert np.allclose(exact_dynamic_stiffness(bar, f, "fixed").real, d_ref, rtol=1e-12)
    assert np.isclose(bit_receptance(bar, [1e-6], "fixed", "free")[0].real, static_compliance(bar, "fixed", "free"),
                      rtol=1e-9)
    assert np.all(bit_receptance(bar, f, "fixed", "fixed") == 0)


@pytest.mark.parametrize("bottom_k", [None, 5e8])   # fixed bit; bit on a rock spring
def test_damped_receptance_converges_under_mesh_refinement(field, bottom_k):
    """Hysteretic loss factor: the FE dynamic stiffness at the bit converges to
    the continuous string at fourth order, fixed bit and bit on bottom alike."""
    s = field.replace(modal_damping_ratio=0.02)
    f = np.array([6.0, 13.0, 19.84, 31.0])
    d_ref = tm_dynamic_stiffness(s.sections, f, eta=0.04)
    if bottom_k is not None:
        d_ref = d_ref + bottom_k
    errs = []
    for n in (110, 220, 440):
        ss = s.with_elements((n, n // 10))
        d = bit_dynamic_stiffness(ss, f, "fixed")
        if bottom_k is not None:
            d = 1.0 / bit_receptance(ss, f, "fixed", Boundary.spring(bottom_k))
        errs.append(np.abs(d / d_ref - 1))
    errs = np.array(errs)
    assert errs[-1].max() < 1e-4
    p = np.log2(errs[:-1] / errs[1:])
    assert np.all(p > 3.5), p
    assert np.allclose(exact_dynamic_stiffness(s, f, "fixed"), tm_dynamic_stiffness(s.sections, f, eta=0.04),
                       rtol=1e-12)


def test_modal_damping_on_every_fe_mode_does_not_converge_at_a_fixed_bit():
    """Why the check does not use a damping ratio per discrete mode: at a fixed
    bit the damping of the bit node grows with the number of modes."""
    s = DrillString.uniform(400.0, 0.127, 0.1086).replace(modal_damping_ratio=0.02)
    f = 19.84
    w = 2 * math.pi * f
    imag = []
    for n in (25, 50, 100, 200):
        asm = assemble(s.with_elements(n), "fixed", "fixed")
        c = asm.C        # M Phi diag(2 zeta w) Phi^T M over every mode of this mesh
        z = asm.K - w * w * asm.M + 1j * w * c
        full = assemble(s.with_elements(n), "fixed", "free")
        a_bb = full.kd_full[-1] - w * w * full.md_full[-1]
        b = full.ke_full[-1] - w * w * full.me_full[-1]
        e = np.zeros(asm.n_dof)
        e[-1] = 1.0
        d = a_bb - b * b * np.linalg.solve(z, e)[-1]
        imag.append(d.imag)
    steps = np.diff(imag)
    assert np.all(steps > 0.005 * imag[0])             # grows like log n: about the same step per doubling
    assert steps[-1] > 0.4 * steps[0]
    conv = [bit_dynamic_stiffness(s.with_elements(n), [f], "fixed")[0] for n in (25, 50, 100, 200)]
    exact = exact_dynamic_stiffness(s, [f], "fixed")[0]
    assert abs(conv[-1] / exact - 1) < 1e-6            # the hysteretic model converges


def test_resonance_factor_analytic_uniform_bar(bar):
    sec = bar.sections[0]
    ea, L, c, Z = sec.axial_stiffness, sec.length, sec.wave_speed, sec.impedance
    f = np.array([0.3, 0.7, 1.3, 2.6, 4.1])
    w = 2 * math.pi * f
    k = w / c
    assert np.allclose(resonance_factor(bar, f, "fixed", "free"), np.maximum(np.abs(np.tan(k * L)), 1.0), rtol=1e-9)
    assert np.allclose(resonance_factor(bar, f, "fixed", "fixed"), np.abs(1 / np.tan(k * L)), rtol=1e-9)
    kb = 3e7
    D = ea * k / np.tan(k * L)
    H, Hinf = 1 / (D + kb), 1 / (1j * w * Z + kb)
    r_ref = np.maximum(np.abs(H / Hinf), np.abs(1 - kb * H) / np.abs(1 - kb * Hinf))
    assert np.allclose(resonance_factor(bar, f, "fixed", Boundary.spring(kb)), r_ref, rtol=1e-9)


def test_stiff_rock_tends_to_fixed_bit(field):
    f = np.array([6.0, 11.0, 20.0])
    r_fixed = np.maximum(resonance_factor(field, f, "fixed", "fixed"), 1.0)
    err = [np.max(np.abs(resonance_factor(field, f, "fixed", Boundary.spring(k)) / r_fixed - 1))
           for k in (1e9, 1e10)]
    assert err[1] < 0.02 and err[1] < 0.2 * err[0]


# ------------------------------------------------------------------ verdicts against oracles
def test_lab_hammer_passes_on_margin(lab):
    r = check(lab, CheckConfig(excitation_hz=1.47, frequency_range_hz=(0.0, 10.0)))
    assert r.verdict == "pass" and r.robust and r.rule == "margin" and r.verdict_label == "robust pass"
    off = {c.name: c for c in r.configurations}["off_bottom"]
    rod, holder = lab.sections
    bounce = lab_closed_form(rod.length, rod, holder.length, holder, 2e4, 0.0, 0.0, 1)[0]
    assert off.nearest.frequency_hz == pytest.approx(bounce, rel=1e-5)
    assert off.nearest.separation_pct == pytest.approx(100 * (1.47 - bounce) / bounce, rel=1e-4)
    assert r.windows[0].lo_hz == 0.0 and r.windows[0].rule == "margin"
    assert r.windows[0].hi_hz == pytest.approx(bounce * 0.85, rel=1e-6)   # the first band edge


def test_field_at_lab_frequency_fails_on_margin(field):
    r = check(field, CheckConfig(excitation_hz=1.47))
    assert r.verdict == "fail" and r.rule == "margin"
    off = {c.name: c for c in r.configurations}["off_bottom"]
    f2 = two_section_closed_form(field, "fixed", "free", 2)[1]
    assert off.nearest.frequency_hz == pytest.approx(f2, rel=1e-5)
    assert off.nearest.isolated and off.regime == "isolated" and off.verdict == "fail"
    assert f"mode {off.nearest.index}" in r.reason and "off_bottom" in r.reason


def test_tricone_resonance_factor_against_independent_transfer_matrix(field):
    """120 rpm x 3 on bottom (rock spring 5e8 N/m): R from an independent
    damped transfer matrix, at the three damping levels."""
    r = check(field, CheckConfig(rpm=120.0, factor=3.0))
    on = r.configurations[0]
    assert on.name == "on_bottom" and on.rule == "receptance"
    kb, f = 5e8, 6.0
    w = 2 * math.pi * f
    dc = field.sections[-1]
    for lev, scale in enumerate((0.5, 1.0, 2.0)):
        eta = 0.04 * scale
        D = tm_dynamic_stiffness(field.sections, f, eta)[0]
        ea = dc.axial_stiffness * (1 + 1j * eta)
        zw = 1j * ea * np.sqrt(w * w * dc.mass_per_length / ea)      # i w Z*
        H, Hinf = 1 / (D + kb), 1 / (zw + kb)
        R = max(abs(H / Hinf), abs(1 - kb * H) / abs(1 - kb * Hinf))
        assert on.resonance_factor_by_damping[lev] == pytest.approx(R, rel=1e-9)
    assert r.verdict == "fail" and on.resonance_factor > r.config.resonance_limit
    assert math.isclose(r.excitation_hz, 6.0)


def test_rpm_excitation_and_windows_in_rpm(field):
    r3 = check(field, CheckConfig(rpm=120.0, factor=3.0, rpm_range=(0.0, 200.0)))
    assert math.isclose(r3.range_hz[1], 10.0)
    assert np.allclose(np.array(r3.safe_windows_rpm), np.array(r3.safe_windows_hz) * 20.0)


# ------------------------------------------------------------------ continuity
def _flip_explained(res, f1, f2):
    """A band edge or an R-limit crossing lies between f1 and f2."""
    m, lim = res.config.margin, res.config.resonance_limit
    for c in res.configurations:
        fe = c.frequencies_hz[c.frequencies_hz > 0]
        edges = np.concatenate((fe * (1 - m), fe * (1 + m)))
        if np.any((edges >= min(f1, f2)) & (edges <= max(f1, f2))):
            return True
    ev = res._evaluator
    for cfg in ev.cfgs:
        for lev in range(3):
            r1, r2 = (cfg.factors_at(np.array([x]), lev)[0][0] for x in (f1, f2))
            if (r1 - lim) * (r2 - lim) <= 0:
                return True
    return False


@pytest.mark.parametrize("name", ["field", "well", "lab"])
def test_verdict_is_continuous_across_every_mode(name, field, well, lab):
    """Sweep the excitation across each natural frequency in steps of 1e-7
    relative: no flip unless a band edge or an R-limit crossing lies between."""
    s = {"field": field, "well": well, "lab": lab}[name]
    hi = {"field": 40.0, "well": 60.0, "lab": 900.0}[name]
    res = check(s, CheckConfig(excitation_hz=hi / 2, frequency_range_hz=(0.0, hi)))
    flips = checked = 0
    for c in res.configurations:
        for fn in c.frequencies_hz[(c.frequencies_hz > 0) & (c.frequencies_hz < hi)]:
            f = fn * (1.0 + 1e-7 * np.arange(-5, 6))
            lab_ = res.label_at(f)
            verdict = lab_ != FAIL
            checked += 1
            for i in np.nonzero(verdict[1:] != verdict[:-1])[0]:
                flips += 1
                assert _flip_explained(res, f[i], f[i + 1]), (name, c.name, fn)
    assert checked > 3
    assert flips <= 1   # a crossing within 1e-6 of a mode is possible, not expected


def test_water_well_off_bottom_mode_no_flip_at_the_mode(well):
    res = check(well, CheckConfig(excitation_hz=20.0, frequency_range_hz=(10.0, 30.0)))
    off = {c.name: c for c in res.configurations}["off_bottom"]
    fn = off.frequencies_hz[np.argmin(np.abs(off.frequencies_hz - 19.33))]
    below = check(well, CheckConfig(excitation_hz=fn * (1 - 5e-6), frequency_range_hz=(10.0, 30.0)))
    above = check(well, CheckConfig(excitation_hz=fn * (1 + 5e-6), frequency_range_hz=(10.0, 30.0)))
    assert below.verdict_label == above.verdict_label
    assert below.verdict == ("fail" if res.label_at([fn])[0] == FAIL else "pass")
    # windows never start at a mode: every edge is a range end, a band edge or an R crossing
    for w in res.windows:
        for e in (w.lo_hz, w.hi_hz):
            if e in res.range_hz:
                continue
            assert _flip_explained(res, e * (1 - 1e-7), e * (1 + 1e-7)), e


# ------------------------------------------------------------------ damping range and labels
def test_robust_and_nominal_only_passes_are_labelled(field, field_check_20hz, capsys):
    r = field_check_20hz
    sweep = r.sweep_hz
    robust_f = sweep[(r.sweep_label == RECEPTANCE)][len(sweep[r.sweep_label == RECEPTANCE]) // 2]
    nominal_f = sweep[(r.sweep_label == NOMINAL_ONLY)][0]
    rob = check(field, CheckConfig(excitation_hz=float(robust_f)))
    assert rob.verdict == "pass" and rob.robust and rob.verdict_label == "robust pass"
    for c in rob.configurations:
        assert c.verdict_by_damping == ("pass", "pass", "pass")
        if c.rule == "receptance":
            assert max(c.resonance_factor_by_damping) <= rob.config.resonance_limit
    nom = check(field, CheckConfig(excitation_hz=float(nominal_f)))
    assert nom.verdict == "pass" and not nom.robust
    assert nom.verdict_label == "pass at nominal damping only"
    assert "pass at nominal damping only" in nom.reason
    d = json.loads(json.dumps(nom.to_dict(), allow_nan=False))
    assert d["robust"] is False and d["verdict_label"] == "pass at nominal damping only"
    assert any("fail" in c["verdict_by_damping"] for c in d["configurations"])
    # with no damping uncertainty the same point is a plain pass
    assert check(field, CheckConfig(excitation_hz=float(nominal_f), damping_range=(1.0, 1.0))).robust


def test_windows_carry_rule_and_damping_range(field_check_20hz):
    r = field_check_20hz
    z = r.damping_ratio_range
    assert z == pytest.approx((0.01, 0.02, 0.04))
    kinds = {w.label for w in r.windows}
    assert {"margin", "receptance", "receptance (nominal damping only)"} <= kinds
    for w in r.windows:
        assert w.hi_hz > w.lo_hz
        mid = 0.5 * (w.lo_hz + w.hi_hz)
        lab = r.label_at([mid])[0]
        assert lab == {"margin": MARGIN, "receptance": RECEPTANCE,
                       "receptance (nominal damping only)": NOMINAL_ONLY}[w.label]
        if w.rule == "margin":
            assert w.damping_ratio_range is None
        elif w.robust:
            assert w.damping_ratio_range == pytest.approx((z[0], z[2]))
        else:
            assert w.damping_ratio_range == pytest.approx((z[1], z[1]))
    gaps = [0.5 * (a.hi_hz + b.lo_hz) for a, b in zip(r.windows[:-1], r.windows[1:]) if b.lo_hz > a.hi_hz]
    assert np.all(r.label_at(gaps) == FAIL)
    d = r.to_dict()
    assert {"lo_hz", "hi_hz", "rule", "robust", "damping_ratio_range", "label"} <= set(d["windows"][0])


# ------------------------------------------------------------------ boundaries honoured everywhere
def test_bit_mass_in_the_file_applies_to_modes_check_and_state_space(field):
    s = field.replace(bottom=Boundary.free(3000.0), off_bottom=Boundary.free(), on_bottom=Boundary.spring(5e8))
    r = check(s, CheckConfig(excitation_hz=2.0, frequency_range_hz=(0.0, 4.0)))
    on, off = r.configurations
    assert off.bottom.mass == 3000.0 and on.bottom.mass == 3000.0
    m = modes(s, f_max=4.0)
    assert np.allclose(off.frequencies_hz[: len(m)], m.frequencies_hz, rtol=1e-9)
    tip = modes(field, "fixed", "free:3000", f_max=4.0)
    assert np.allclose(m.frequencies_hz, tip.frequencies_hz, rtol=1e-12)
    ss = state_space(s, "fixed", "hammer:1e9:2e4")
    plain = state_space(field, "fixed", "hammer:1e9:2e4")
    assert ss.mass_matrix[-1, -1] - plain.mass_matrix[-1, -1] == pytest.approx(3000.0)


# ------------------------------------------------------------------ config errors
@pytest.mark.parametrize("kw,name", [
    (dict(excitation_hz=-1.0), "excitation_hz"), (dict(excitation_hz=math.inf), "excitation_hz"),
    (dict(excitation_hz=math.nan), "excitation_hz"), (dict(excitation_hz=1.0, margin=1.5), "margin"),
    (dict(rpm=60.0, factor=0.0), "factor"), (dict(excitation_hz=1.0, damping_range=(2.0, 3.0)), "damping_range"),
    (dict(excitation_hz=1.0, frequency_range_hz=(3.0, 1.0)), "frequency_range_hz"),
])
def test_config_validation_names_the_parameter(kw, name):
    with pytest.raises(ParameterError) as ei:
        CheckConfig(**kw)
    assert ei.value.name == name


def test_config_needs_exactly_one_excitation():
    for kw in (dict(), dict(excitation_hz=1.0, rpm=30.0)):
        with pytest.raises(ValueError):
            CheckConfig(**kw)


# ------------------------------------------------------------------ plots
def test_plots(tmp_path, field_check_20hz, lab):
    p = plot_check(field_check_20hz, tmp_path / "check.png")
    assert p.stat().st_size > 20_000 and p.read_bytes()[:4] == b"\x89PNG"
    r = check(lab, CheckConfig(excitation_hz=1.47, frequency_range_hz=(0, 10)))
    ax = plot_campbell(r, path=tmp_path / "campbell.png")
    axes = plot_receptance(r, path=tmp_path / "rec.png")
    assert ax is not None and len(axes) == 2
    assert (tmp_path / "campbell.png").exists() and (tmp_path / "rec.png").exists()


def test_campbell_and_receptance_draw_in_si_without_saving(lab):
    """The drawing of the Campbell and receptance plots, without the PNG encoding that makes
    test_plots (slow set) slow: curves on SI axes (the check's own figure: the CLI test's --plot)."""
    import matplotlib.pyplot as plt
    r = check(lab, CheckConfig(excitation_hz=1.47, frequency_range_hz=(0, 10)))
    ax = plot_campbell(r)
    rec, factor = plot_receptance(r)
    try:
        assert ax.lines and rec.lines and factor.lines
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("rotary speed [rpm]", "frequency [Hz]")
        assert rec.get_ylabel() == "bit receptance [m/N]" and factor.get_xlabel() == "excitation frequency [Hz]"
    finally:
        plt.close("all")


# ------------------------------------------------------------------ CLI
def _cli(argv, capsys):
    code = cli.main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("value", ["inf", "nan", "-3", "0"])
def test_cli_bad_frequency_exits_2_with_a_clear_message(capsys, value):
    code, out, err = _cli(["check", "--string", "field-2200m", "--frequency", value], capsys)
    assert code == 2 and "--frequency" in err and "Traceback" not in err and out == ""


def test_cli_modes_json_and_csv(capsys, field, tmp_path):
    path = tmp_path / "modes.csv"
    code, out, _ = _cli(["modes", "--string", "field-2200m", "--top", "fixed", "--bottom", "free",
                         "--count", "4", "--json", "--exact", "--csv", str(path)], capsys)
    d = json.loads(out)
    ref = two_section_closed_form(field, "fixed", "free", 4)
    assert code == 0 and np.allclose(d["frequencies_hz"], ref, rtol=1e-5)
    assert max(abs(e) for e in d["relative_error"]) < 1e-5 and max(d["error_estimate"]) <= 1e-5
    rows = list(csv.DictReader(path.open()))
    assert [int(r["mode"]) for r in rows] == [1, 2, 3, 4]
    assert np.allclose([float(r["frequency_hz"]) for r in rows], d["frequencies_hz"], rtol=1e-12)
    assert {"period_s", "error_estimate", "exact_hz", "relative_error"} <= set(rows[0])
    code, out, _ = _cli(["modes", "--string", "lab", "--count", "3"], capsys)
    assert code == 0 and len(out.strip().splitlines()) == 5


def test_cli_check_json_plot_strict(capsys, tmp_path):
    png = tmp_path / "c.png"
    code, out, _ = _cli(["check", "--string", "field-2200m", "--rpm", "120", "--factor", "3",
                         "--json", "--plot", str(png)], capsys)
    d = json.loads(out)
    assert code == 0 and d["verdict"] == "fail" and d["windows"] and d["safe_windows_rpm"] and png.exists()
    code, out, _ = _cli(["check", "--string", "lab", "--frequency", "1.47", "--margin", "0.2"], capsys)
    assert code == 0 and "VERDICT: ROBUST PASS (margin rule)" in out
    code, _, _ = _cli(["check", "--string", "field-2200m", "--frequency", "1.47", "--strict"], capsys)
    assert code == 4


def test_cli_file_path_and_errors(capsys, tmp_path):
    good = tmp_path / "s.toml"
    good.write_text('[[section]]\nname = "rod"\nlength = 3.0\nod = 0.02\nid = 0.0\n')
    code, out, _ = _cli(["modes", "--string", str(good), "--count", "2", "--json"], capsys)
    assert code == 0 and json.loads(out)["string"] == "s"
    bad = tmp_path / "bad.toml"
    bad.write_text('[[section]]\nname = "rod"\nlength = 3.0\nod = 0.02\nid = 0.05\n')
    code, _, err = _cli(["modes", "--string", str(bad)], capsys)
    assert code == 2 and "bad.toml" in err and "section #1 'rod'" in err and "key 'id' = 0.05" in err
    code, _, err = _cli(["check", "--string", "field-2200m", "--frequency", "3", "--factor", "3"], capsys)
    assert code == 2 and "--factor needs --rpm" in err
    code, _, err = _cli(["check", "--string", "field-2200m", "--frequency", "3", "--on-bottom", "spring"], capsys)
    assert code == 2 and "--on-bottom" in err
    code, _, err = _cli(["check", "--string", "field-2200m", "--frequency", "3", "--damping-range", "2", "3"],
                        capsys)
    assert code == 2 and "--damping-range" in err
    code, _, err = _cli(["check", "--string", "field-2200m", "--frequency", "3", "--plot", str(tmp_path / "x.xyz")],
                        capsys)
    assert code == 2 and "--plot" in err
