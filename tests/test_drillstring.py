"""Lumped axial drillstring model: closed forms, convergence, statics, state space, input files.

Closed forms used here (derived in the docstrings, coded independently of
``hammerbit.drillstring``):

Uniform bar, ``u_tt = c^2 u_zz``, ``c = sqrt(EA/m')``, length L:
    fixed-free / free-fixed ``f_n = (2n-1) c / 4L``;
    fixed-fixed ``f_n = n c / 2L``; free-free ``f_0 = 0, f_n = n c / 2L``.
Tip mass M at the free end of a fixed-free bar: ``u = sin(beta z)``, end
condition ``EA u'(L) = M w^2 u(L)`` gives ``EA beta cos(beta L) = M c^2
beta^2 sin(beta L)``, i.e. ``beta L tan(beta L) = m' L / M``.
Spring k at the end of a fixed-"spring" bar: ``EA u'(L) = -k u(L)``:
``EA beta cos(beta L) + k sin(beta L) = 0``.
Two sections (1 on top of 2), ``a = k1 l1``, ``b = k2 l2``, ``Z = sqrt(EA m')``:
continuity of displacement and force ``EA u'`` at the joint, e.g. fixed-free
with ``u1 = sin(k1 z)``, ``u2 = B cos(k2 (L - z))``:
``sin a = B cos b`` and ``Z1 cos a = Z2 B sin b`` ->
``Z1 cos a cos b - Z2 sin a sin b = 0``.  Likewise
fixed-fixed ``Z1 cos a sin b + Z2 sin a cos b = 0``,
free-free ``Z1 sin a cos b + Z2 cos a sin b = 0`` (+ rigid mode),
free-fixed ``Z1 sin a sin b - Z2 cos a cos b = 0``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from hammerbit.drillstring import (
    G,
    Boundary,
    DrillString,
    DrillStringError,
    Section,
    assemble,
    dispersion_error,
    example_names,
    exact_frequencies,
    load_string,
    loads_string,
    modes,
    parse_boundary,
    state_space,
    static_compliance,
    static_equilibrium,
    string_from_dict,
)

E, RHO = 2.07e11, 7850.0
C = math.sqrt(E / RHO)


@pytest.fixture(scope="module")
def field() -> DrillString:
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def pipe() -> DrillString:
    """Uniform 2200 m of 5 in drill pipe."""
    return DrillString.uniform(2200.0, 0.127, 0.1086, name="dp")


# ---------------------------------------------------------------- closed forms
def _roots(fun, f_hi: float, step: float) -> np.ndarray:
    """All sign-change roots of fun on (0, f_hi] [Hz]."""
    grid = np.arange(step * 1e-3, f_hi + step, step)
    val = np.array([fun(f) for f in grid])
    idx = np.nonzero(np.sign(val[:-1]) * np.sign(val[1:]) < 0)[0]
    return np.array([brentq(fun, grid[i], grid[i + 1], xtol=1e-14) for i in idx])


def uniform_closed_form(top: str, bottom: str, L: float, n: int) -> np.ndarray:
    k = np.arange(1, n + 1)
    if (top, bottom) in (("fixed", "free"), ("free", "fixed")):
        return (2 * k - 1) * C / (4 * L)
    if (top, bottom) == ("fixed", "fixed"):
        return k * C / (2 * L)
    if (top, bottom) == ("free", "free"):
        return np.concatenate(([0.0], k[:-1] * C / (2 * L)))
    raise ValueError


def tip_mass_closed_form(sec: Section, M: float, n: int) -> np.ndarray:
    """beta L tan(beta L) = m' L / M, one root in each ((j-1) pi, (j-1) pi + pi/2)."""
    ratio = sec.mass_per_length * sec.length / M
    x = [brentq(lambda t: t * math.tan(t) - ratio, (j - 1) * math.pi + 1e-12, (j - 0.5) * math.pi - 1e-12)
         for j in range(1, n + 1)]
    return np.array(x) * sec.wave_speed / (2 * math.pi * sec.length)


def spring_closed_form(sec: Section, kb: float, n: int) -> np.ndarray:
    """EA beta cos(beta L) + k sin(beta L) = 0, root j in ((j - 1/2) pi, j pi)."""
    L, EA = sec.length, sec.axial_stiffness
    x = [brentq(lambda t: EA * t / L * math.cos(t) + kb * math.sin(t), (j - 0.5) * math.pi, j * math.pi)
         for j in range(1, n + 1)]
    return np.array(x) * sec.wave_speed / (2 * math.pi * L)


def two_section_closed_form(s: DrillString, top: str, bottom: str, n: int) -> np.ndarray:
    s1, s2 = s.sections
    z1, z2 = s1.impedance, s2.impedance

    def ab(f):
        w = 2 * math.pi * f
        return w * s1.length / s1.wave_speed, w * s2.length / s2.wave_speed

    eqs = {
        ("fixed", "free"): lambda f: z1 * math.cos(ab(f)[0]) * math.cos(ab(f)[1])
        - z2 * math.sin(ab(f)[0]) * math.sin(ab(f)[1]),
        ("fixed", "fixed"): lambda f: z1 * math.cos(ab(f)[0]) * math.sin(ab(f)[1])
        + z2 * math.sin(ab(f)[0]) * math.cos(ab(f)[1]),
        ("free", "free"): lambda f: z1 * math.sin(ab(f)[0]) * math.cos(ab(f)[1])
        + z2 * math.cos(ab(f)[0]) * math.sin(ab(f)[1]),
        ("free", "fixed"): lambda f: z1 * math.sin(ab(f)[0]) * math.sin(ab(f)[1])
        - z2 * math.cos(ab(f)[0]) * math.cos(ab(f)[1]),
    }
    spacing = 1.0 / (2 * (s1.length / s1.wave_speed + s2.length / s2.wave_speed))
    r = _roots(eqs[(top, bottom)], (n + 2) * spacing * 1.5, spacing / 400)
    if (top, bottom) == ("free", "free"):
        r = np.concatenate(([0.0], r))
    return r[:n]


CLASSIC = [("fixed", "free"), ("fixed", "fixed"), ("free", "free"), ("free", "fixed")]


def _rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.where(b == 0, np.abs(a), np.abs(a - b) / np.where(b == 0, 1, b))


# --------------------------------------------------------- done-when criteria
def test_uniform_drill_pipe_fixed_free_matches_quarter_wave(pipe):
    f = modes(pipe, "fixed", "free", count=4).frequencies_hz
    ref = (2 * np.arange(1, 5) - 1) * C / (4 * 2200.0)
    assert abs(C - 5135.1) < 0.1 and abs(ref[0] - 0.5835) < 1e-3
    assert np.all(_rel(f, ref) < 1e-3)
    assert np.all(_rel(f, ref) < 1e-6)  # what the default mesh actually achieves


@pytest.mark.parametrize("top,bottom", CLASSIC)
def test_field_string_classic_pairs_match_closed_form(field, top, bottom):
    """Example 2200 m string, default mesh: first four within 0.1 % (here < 1e-6)."""
    ref = two_section_closed_form(field, top, bottom, 4)
    f = modes(field, top, bottom, count=4).frequencies_hz
    assert len(f) == 4
    assert np.all(_rel(f, ref) < 1e-3)
    assert np.all(_rel(f, ref) < 1e-6)
    # the library's transfer-matrix solution agrees with the explicit equations
    assert np.allclose(exact_frequencies(field, top, bottom, 4), ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("top", ["fixed", "free", "spring:2e7", "spring:5e6:0:30000"])
@pytest.mark.parametrize("bottom", ["free", "fixed", "spring:5e8", "mass:20000", "spring:5e8:0:3000"])
def test_field_string_all_end_pairs_match_transfer_matrix(field, top, bottom):
    ref = exact_frequencies(field, top, bottom, 4)
    f = modes(field, top, bottom, count=4).frequencies_hz
    assert np.all(_rel(f, ref) < 1e-3)


# ------------------------------------------------------------ uniform closed forms
@pytest.mark.parametrize("top,bottom", CLASSIC)
@pytest.mark.parametrize("mass", ["lumped", "consistent", "mixed"])
def test_uniform_bar_all_classic_pairs(pipe, top, bottom, mass):
    ref = uniform_closed_form(top, bottom, 2200.0, 5)
    f = modes(pipe.with_elements(400), top, bottom, count=5, mass=mass, rtol=None).frequencies_hz
    assert np.all(_rel(f, ref) < 2e-4)
    assert np.allclose(exact_frequencies(pipe, top, bottom, 5), ref, rtol=1e-11, atol=1e-9)


@pytest.mark.parametrize("tip", [2000.0, 27000.0, 2.0e5])
def test_tip_mass(pipe, tip):
    sec = pipe.sections[0]
    ref = tip_mass_closed_form(sec, tip, 4)
    f = modes(pipe, "fixed", Boundary.free(tip), count=4).frequencies_hz
    assert np.all(_rel(f, ref) < 1e-4)
    assert np.allclose(exact_frequencies(pipe, "fixed", f"mass:{tip}", 4), ref, rtol=1e-10)


@pytest.mark.parametrize("kb", [1e5, 3e6, 1e9])
def test_spring_bottom(pipe, kb):
    sec = pipe.sections[0]
    ref = spring_closed_form(sec, kb, 4)
    f = modes(pipe, "fixed", Boundary.spring(kb), count=4).frequencies_hz
    assert np.all(_rel(f, ref) < 1e-4)
    assert np.allclose(exact_frequencies(pipe, "fixed", Boundary.spring(kb), 4), ref, rtol=1e-10)


def test_rigid_mode_and_sorting(field):
    m = modes(field, "free", "free", count=3)
    assert m.frequencies_hz[0] == 0.0 and np.all(np.diff(m.frequencies_hz) > 0)


# ------------------------------------------------------------------ convergence
def _errors(string, top, bottom, counts, mass, nmodes=3):
    ref = exact_frequencies(string, top, bottom, nmodes + 1)
    ref = ref[ref > 0][:nmodes]
    out = []
    for n in counts:
        f = modes(string.with_elements(n), top, bottom, count=nmodes + 1, mass=mass, rtol=None).frequencies_hz
        f = f[f > 0][:nmodes]
        out.append((f - ref) / ref)
    return np.array(out)  # (levels, nmodes), signed


@pytest.mark.parametrize("top,bottom", [("fixed", "free"), ("fixed", "fixed"), ("free", "free")])
@pytest.mark.parametrize("mass,order", [("lumped", 2), ("consistent", 2), ("mixed", 4)])
def test_convergence_order_uniform(pipe, top, bottom, mass, order):
    e = _errors(pipe, top, bottom, [20, 40, 80], mass)
    ratio = np.abs(e[:-1] / e[1:])
    p = np.log2(ratio)
    assert np.all(np.abs(p - order) < 0.1), p
    # signs: lumped too low, consistent too high, mixed too low (-(kh)^4/480)
    assert np.all(np.sign(e) == {"lumped": -1, "consistent": 1, "mixed": -1}[mass])


@pytest.mark.parametrize("top,bottom", CLASSIC)
def test_convergence_order_two_sections(field, top, bottom):
    counts = [(20, 2), (40, 4), (80, 8)]
    for mass, order in (("lumped", 2), ("mixed", 4)):
        e = _errors(field, top, bottom, counts, mass)
        p = np.log2(np.abs(e[:-1] / e[1:]))
        assert np.all(np.abs(p - order) < 0.15), (mass, p)


def test_point_mass_plain_fe_is_second_order_corrected_is_fourth(pipe):
    """A lumped end mass meets the element's second-order impedance error: the
    plain eigenvalues of K, M converge at second order, the impedance-corrected
    frequencies at fourth."""
    ref = tip_mass_closed_form(pipe.sections[0], 20000.0, 3)
    raw, cor = [], []
    for n in (20, 40, 80):
        m = modes(pipe.with_elements(n), "fixed", "mass:20000", count=3, rtol=None)
        raw.append(np.abs(m.fe_frequencies_hz / ref - 1))
        cor.append(np.abs(m.frequencies_hz / ref - 1))
    p_raw = np.log2(np.array(raw[:-1]) / np.array(raw[1:]))
    p_cor = np.log2(np.array(cor[:-1]) / np.array(cor[1:]))
    assert np.all(np.abs(p_raw[-1] - 2) < 0.2), p_raw
    assert np.all(np.abs(p_cor[-1] - 4) < 0.25), p_cor


@pytest.mark.parametrize("mass", ["lumped", "consistent", "mixed"])
def test_dispersion_formula_is_exact_for_fixed_free_chain(pipe, mass):
    """Fixed-free chain of N elements: discrete modes sin(k z_j) with
    k h = (2n-1) pi / (2N); the frequency error is the dispersion error."""
    N = 12
    f = modes(pipe.with_elements(N), "fixed", "free", count=N, mass=mass, rtol=None).frequencies_hz
    n = np.arange(1, N + 1)
    theta = (2 * n - 1) * math.pi / (2 * N)
    exact = (2 * n - 1) * C / (4 * 2200.0)
    assert np.allclose(f, exact * (1 + dispersion_error(theta, mass)), rtol=1e-10)


def test_for_accuracy_meshes_by_equal_travel_time(field):
    fine = field.for_accuracy(60.0, rtol=1e-6)
    tau = fine.travel_times
    assert np.all(np.array(fine.elements_per_section) >= np.array(field.elements_per_section))
    assert np.max(tau) / np.min(tau) < 1.1          # equal h/c up to the rounding of the counts
    ex = exact_frequencies(field, "fixed", "free", f_max=60.0)
    f = modes(fine, "fixed", "free", f_max=60.5, rtol=None).frequencies_hz[: ex.size]
    assert np.max(_rel(f, ex)) < 1e-6
    lumped = field.for_accuracy(60.0, rtol=1e-6, mass="lumped")
    assert lumped.n_elements > fine.n_elements  # second order needs more elements


def test_default_mesh_has_no_forced_minimum(field):
    """No element count is forced on a short section: equal travel time decides."""
    s = DrillString((Section("pipe", 1000.0, 0.127, 0.1086), Section("sub", 0.5, 0.17, 0.07)))
    assert s.elements_per_section == (100, 1)


# ------------------------------------------------------------------ matrices
@pytest.mark.parametrize("mass", ["lumped", "consistent", "mixed"])
def test_matrices_mass_and_rigid_body(field, mass):
    s = field.replace(sections=tuple(
        Section(x.name, x.length, x.od, x.id, viscous_damping=3.0) for x in field.sections))
    asm = assemble(s, "free", "free", mass=mass)
    M, K, Cv = asm.M, asm.K, asm.C_viscous
    assert np.isclose(M.sum(), s.mass, rtol=1e-12)
    assert np.isclose(Cv.sum(), 3.0 * s.length, rtol=1e-12)
    assert np.allclose(K @ np.ones(asm.n_dof), 0.0, atol=1e-6 * np.abs(K).max())
    for A in (M, K, Cv):
        assert np.array_equal(A, A.T)
        assert np.count_nonzero(np.triu(A, 2)) == 0
    if mass == "lumped":
        assert np.count_nonzero(M - np.diag(np.diag(M))) == 0


def test_boundaries_enter_matrices(field):
    free = assemble(field, "free", "free", mass="lumped")
    sp = assemble(field, "spring:1e7:100:50", "spring:5e8:200:3000", mass="lumped")
    assert np.isclose(sp.K[0, 0] - free.K[0, 0], 1e7) and np.isclose(sp.K[-1, -1] - free.K[-1, -1], 5e8)
    assert np.isclose(sp.C_viscous[0, 0], 100) and np.isclose(sp.C_viscous[-1, -1], 200)
    assert np.isclose(sp.M[0, 0] - free.M[0, 0], 50) and np.isclose(sp.M[-1, -1] - free.M[-1, -1], 3000)
    fx = assemble(field, "fixed", "fixed")
    assert fx.n_dof == field.n_elements - 1 and fx.bottom_dof is None
    hm = assemble(field, "fixed", "hammer:1e9:1e4")
    assert np.allclose(hm.K, assemble(field, "fixed", "free").K)  # hammer leaves the bit free


def test_modes_are_mass_normalised_and_only_requested(field):
    asm = assemble(field, "fixed", "free")
    m = modes(field, "fixed", "free", f_max=5.0, rtol=None)
    assert np.all(m.frequencies_hz <= 5.0) and len(m) == 4
    phi = m.shapes[asm.start:asm.stop]
    assert np.allclose(phi.T @ asm.M @ phi, np.eye(len(m)), atol=1e-10)
    w_fe = 2 * math.pi * m.fe_frequencies_hz
    assert np.allclose(phi.T @ asm.K @ phi, np.diag(w_fe ** 2), rtol=1e-9, atol=1e-6)
    assert np.all(m.shapes[-1] > 0)  # sign convention
    assert len(modes(field, count=3)) == 3
    assert len(modes(field, f_max=5.0, count=2)) == 2
    fixed = modes(field, "fixed", "fixed", count=2)
    assert np.all(fixed.shapes[0] == 0) and np.all(fixed.shapes[-1] == 0)


def test_modal_damping_matrix(field):
    s = field.replace(modal_damping_ratio=0.05)
    asm = assemble(s, "fixed", "free")
    m = modes(s, "fixed", "free", count=5, rtol=None)
    phi = m.shapes[asm.start:asm.stop]
    cm = phi.T @ asm.C @ phi
    assert np.allclose(cm, np.diag(2 * 0.05 * 2 * math.pi * m.fe_frequencies_hz), atol=1e-8 * cm.max())


def test_long_meshes_and_selection_by_frequency(pipe):
    long = pipe.with_elements(2000)
    f = modes(long, "fixed", "free", count=4, rtol=None).frequencies_hz
    assert np.allclose(f, uniform_closed_form("fixed", "free", 2200.0, 4), rtol=1e-8)
    g = modes(long, "fixed", "free", f_max=3.0, rtol=None).frequencies_hz
    assert np.allclose(g, f[f <= 3.0], rtol=1e-10)


# ------------------------------------------------------------------ statics
def _hanging_displacement(string: DrillString, z: np.ndarray, wob: float) -> np.ndarray:
    """u(z) = int_0^z T/EA, T(s) = weight below s - wob, piecewise-uniform sections."""
    tops = np.concatenate(([0.0], np.cumsum([s.length for s in string.sections])))
    q = np.array([s.mass_per_length * G * s.buoyancy_factor(string.mud_density) for s in string.sections])
    ea = np.array([s.axial_stiffness for s in string.sections])
    below_top = np.array([np.sum(q[i:] * np.diff(tops)[i:]) for i in range(len(q))]) - wob
    u = np.zeros_like(z)
    for i, (a, b) in enumerate(zip(tops[:-1], tops[1:])):
        s_hi = np.clip(z, a, b) - a  # length of section i above z
        # T(a + s) = below_top[i] - q s
        u += (below_top[i] * s_hi - q[i] * s_hi ** 2 / 2) / ea[i]
    return u


@pytest.mark.parametrize("wob", [0.0, 5.0e4, 1.5e5])
def test_static_stretch_exact_at_nodes(field, wob):
    st = static_equilibrium(field, wob=wob)
    assert np.allclose(st.displacement, _hanging_displacement(field, st.z, wob), rtol=1e-10, atol=1e-12)
    zmid = 0.5 * (st.z[:-1] + st.z[1:])
    s_ = field
    tops = np.cumsum([x.length for x in s_.sections])
    # element tension equals the exact tension at the element mid-point
    t_exact = np.interp(zmid, st.z, st.tension_nodes)
    assert np.allclose(st.tension_elements, t_exact, rtol=1e-9, atol=1e-6)
    assert np.isclose(st.hook_load, st.buoyed_weight - wob)
    assert np.isclose(st.tension_nodes[0], st.hook_load) and np.isclose(st.tension_nodes[-1], -wob)
    if wob > 0:
        dc = field.sections[1]
        q_dc = dc.mass_per_length * G * dc.buoyancy_factor(field.mud_density)
        assert np.isclose(st.neutral_point_depth, tops[-1] - wob / q_dc)  # neutral point in the collars
    else:
        assert st.neutral_point_depth is None


def test_static_buoyancy_hook_load_and_top_spring(field):
    air = static_equilibrium(field.replace(mud_density=0.0))
    mud = static_equilibrium(field)
    assert np.isclose(air.hook_load, field.mass * G)
    assert np.isclose(mud.hook_load / air.hook_load, 1 - 1200.0 / 7850.0)
    by_hook = static_equilibrium(field, hook_load=mud.hook_load - 8e4)
    assert np.isclose(by_hook.wob, 8e4)
    spr = static_equilibrium(field, wob=8e4, top="spring:2e7")
    rigid = static_equilibrium(field, wob=8e4)
    assert np.isclose(spr.displacement[0], spr.hook_load / 2e7)
    assert np.allclose(spr.displacement - spr.displacement[0], rigid.displacement, atol=1e-12)
    with pytest.raises(ValueError, match="wob"):
        static_equilibrium(field, wob=2 * mud.buoyed_weight)
    with pytest.raises(ValueError, match="hook"):
        static_equilibrium(field, top="free")


def test_static_compliance(field, pipe):
    sec = pipe.sections[0]
    assert np.isclose(static_compliance(pipe, "fixed", "free"), sec.length / sec.axial_stiffness)
    flex = sum(s.length / s.axial_stiffness for s in field.sections)
    assert np.isclose(static_compliance(field, "spring:1e7", "spring:5e8"), 1 / (1 / (flex + 1e-7) + 5e8))
    assert static_compliance(field, "free", "free") == math.inf
    assert static_compliance(field, "fixed", "fixed") == 0.0


# ------------------------------------------------------------------ state space
@pytest.mark.parametrize("f_max", [None, 12.0])
@pytest.mark.parametrize("bottom", ["hammer:1e9:2e4", "spring:5e8:1e4", "free"])
def test_state_space_equilibrium(field, f_max, bottom):
    wob = 8.0e4
    ss = state_space(field.replace(modal_damping_ratio=0.02), "fixed", bottom, wob=wob, f_max=f_max)
    assert np.allclose(ss.rhs(ss.x0, ss.u0), 0.0, atol=1e-9 * np.abs(ss.d).max())
    assert ss.u0 == -wob and np.isclose(ss.hook_load, static_equilibrium(field, wob=wob).hook_load)
    st = static_equilibrium(field, wob=wob)
    if f_max is None:
        assert np.isclose(ss.output(ss.x0)[0], st.bit_displacement, rtol=1e-10)
        assert ss.basis is None and ss.residual_compliance == 0.0
    else:
        # modal states are deviations from the full equilibrium: exact at rest
        assert np.allclose(ss.x0, 0.0)
        assert np.isclose(ss.output(ss.x0)[0], st.bit_displacement, rtol=1e-10)
        assert np.isclose(ss.output(ss.x0)[2], st.tension_elements[0], rtol=1e-8)
        assert ss.residual_compliance > 0  # bit flexibility of the dropped modes
        assert ss.max_frequency_hz <= f_max
    assert np.allclose(ss.static_displacement, st.displacement, rtol=1e-10, atol=1e-12)
    assert ss.bottom_node == field.n_elements and ss.nodes[ss.bottom_dof] == ss.bottom_node


def test_state_space_eigenvalues_and_interface(field):
    coarse = field.with_elements((40, 4))  # eigen-solve of the 2n x 2n A stays cheap
    undamped = coarse.replace(modal_damping_ratio=0.0)
    ss = state_space(undamped, "fixed", "hammer:1e9:2e4", mass="lumped")
    assert ss.interface.kind == "hammer" and ss.interface.stiffness == 1e9 and ss.interface.damping == 2e4
    assert np.count_nonzero(ss.mass_matrix - np.diag(np.diag(ss.mass_matrix))) == 0
    ev = np.linalg.eigvals(ss.A)
    f_ss = np.sort(np.abs(ev.imag[ev.imag > 0]))[:4] / (2 * math.pi)
    f_m = modes(coarse, "fixed", "free", count=4, mass="lumped", rtol=None).fe_frequencies_hz
    assert np.allclose(f_ss, f_m, rtol=1e-8)
    assert np.allclose(ev.real, 0, atol=1e-8)  # undamped string
    # 2 % modal damping: poles -zeta w +- i w sqrt(1 - zeta^2)
    ev = np.linalg.eigvals(state_space(coarse, "fixed", "free", mass="lumped").A)
    ev = ev[ev.imag > 0]
    ev = ev[np.argsort(ev.imag)][:4]
    w = 2 * math.pi * f_m
    assert np.allclose(ev.imag, w * math.sqrt(1 - 0.02 ** 2), rtol=1e-8)
    assert np.allclose(ev.real, -0.02 * w, rtol=1e-6)
    # output row 2: tension in the top element at equilibrium (exact mid-element value)
    st = static_equilibrium(field, wob=0.0)
    ss0 = state_space(field, "fixed", "free", wob=0.0)
    assert np.isclose(ss0.output(ss0.x0)[2], st.tension_elements[0], rtol=1e-10)


def test_state_space_frequency_response_matches_modal_truncation(field):
    s = field.replace(modal_damping_ratio=0.03).with_elements((60, 6))
    full = state_space(s, "fixed", "free")
    trunc = state_space(s, "fixed", "free", f_max=30.0)
    for f in (0.3, 1.1, 2.0):
        w = 2 * math.pi * f
        h_full = (full.C[0] @ np.linalg.solve(1j * w * np.eye(full.n_states) - full.A, full.B))[0]
        h_tr = (trunc.C[0] @ np.linalg.solve(1j * w * np.eye(trunc.n_states) - trunc.A, trunc.B))[0]
        assert abs(h_tr + trunc.residual_compliance - h_full) < 2e-3 * abs(h_full)


def test_state_space_refuses_fixed_bit(field):
    with pytest.raises(ValueError, match="bottom"):
        state_space(field, "fixed", "fixed")


# ------------------------------------------------------------------ files
def test_examples_load_and_match_the_issue():
    assert {"field-2200m", "lab"} <= set(example_names())
    f = load_string("field-2200m")
    dp, dc = f.sections
    assert (dp.length, dp.od, dp.id) == (2000.0, 0.127, 0.1086)
    assert (dc.length, dc.od, dc.id) == (200.0, 0.1651, 0.0714375)
    assert dp.youngs_modulus == 2.07e11 and dp.density == 7850.0
    assert f.elements_per_section == (200, 20)
    lab = load_string("lab")
    assert lab.length < 5 and lab.top.kind == "spring"


def test_python_and_toml_descriptions_agree(field):
    py = DrillString((Section("drill pipe", 2000.0, 0.127, 0.1086),
                      Section("drill collars", 200.0, 0.1651, 0.0714375)),
                     name=field.name, description=field.description, modal_damping_ratio=0.02,
                     mud_density=1200.0, top=Boundary.fixed(), bottom=Boundary.free(),
                     on_bottom=Boundary.spring(5e8), off_bottom=Boundary.free())
    assert py == field
    assert string_from_dict(field.to_dict()) == field


def test_linear_mass_counts_tool_joints():
    toml = """
[[section]]
name = "dp"
length = 1000.0
od = 0.127
id = 0.1086
linear_mass = 33.6
"""
    s = loads_string(toml)
    sec = s.sections[0]
    assert sec.mass_per_length == 33.6 and sec.wave_speed < C
    f = modes(s, "fixed", "free", count=1).frequencies_hz[0]
    assert np.isclose(f, sec.wave_speed / 4000.0, rtol=1e-5)


BASE = """
name = "t"
[[section]]
name = "pipe"
length = 100.0
od = 0.127
id = 0.1086
"""


@pytest.mark.parametrize("edit,key,value_text,allowed", [
    (("length = 100.0", "length = -5.0"), "length", "-5.0", "0 < length <= 20000 m"),
    (("id = 0.1086", "id = 0.2"), "id", "0.2", "id < 0.127"),
    (("od = 0.127", "od = 3.0"), "od", "3.0", "0 < od <= 2 m"),
    (("length = 100.0", "lenght = 100.0"), "lenght", "100.0", "unknown key"),
    (("id = 0.1086", ""), "id", "None", "missing required key"),
    (("length = 100.0", 'length = "long"'), "length", "'long'", "finite number"),
    (("od = 0.127", "od = 0.127\nyoungs_modulus = 2.0e7"), "youngs_modulus", "20000000.0", "1e+09 <= youngs"),
    (("od = 0.127", "od = 0.127\nelements = 2.5"), "elements", "2.5", "integer"),
    (("od = 0.127", "od = 0.127\nelements = 4\nmax_element_length = 3.0"), "elements", "4", "not both"),
    (("od = 0.127", "od = 0.127\nlinear_mass = 1.0"), "linear_mass", "1.0", "kg/m"),
    (("od = 0.127", "od = 0.127\nviscous_damping = -1.0"), "viscous_damping", "-1.0", "0 <= viscous"),
])
def test_bad_section_errors_name_section_key_value_range(edit, key, value_text, allowed):
    text = BASE.replace(*edit)
    with pytest.raises(DrillStringError) as ei:
        loads_string(text, source="bad.toml")
    msg = str(ei.value)
    assert "bad.toml" in msg and "section #1 'pipe'" in msg
    assert f"key '{key}'" in msg and value_text in msg and allowed in msg
    assert ei.value.key == key


@pytest.mark.parametrize("extra,key,allowed", [
    ('mud_density = 9000.0\n', "mud_density", "0 <= mud_density <= 3000 kg/m3"),
    ('modal_damping_ratio = 1.5\n', "modal_damping_ratio", "0 <= modal_damping_ratio < 1"),
    ('colour = "red"\n', "colour", "unknown top-level key"),
    ('[boundaries]\ntop = "hinge"\n', "kind", "allowed values"),
    ('[boundaries]\nbottom = "spring"\n', "spec", "spring:K"),
    ('[boundaries]\nbottom = { kind = "spring", stiffness = -1.0 }\n', "stiffness", "0 <= stiffness"),
    ('[boundaries]\ntop = "hammer:1e9"\n', "kind", "at the top"),
    ('[boundaries]\nside = "free"\n', "side", "unknown key"),
])
def test_bad_string_level_errors(extra, key, allowed):
    head, sec = BASE.split("[[section]]")
    text = head + (extra if not extra.startswith("[") else "") + "[[section]]" + sec
    if extra.startswith("["):
        text = text + extra
    with pytest.raises(DrillStringError) as ei:
        loads_string(text, source="bad.toml")
    msg = str(ei.value)
    assert "bad.toml" in msg and f"key '{key}'" in msg and allowed in msg


def test_mud_heavier_than_section_material():
    text = BASE.replace("od = 0.127", "od = 0.127\ndensity = 1500.0").replace('name = "t"', 'name = "t"\nmud_density = 1600.0')
    with pytest.raises(DrillStringError) as ei:
        loads_string(text, source="bad.toml")
    assert "section 'pipe'" in str(ei.value) and "must be < section density 1500" in str(ei.value)


def test_toml_syntax_and_missing_sections():
    with pytest.raises(DrillStringError, match="TOML syntax"):
        loads_string("[[section]\nname=", source="x.toml")
    with pytest.raises(DrillStringError, match="at least one"):
        loads_string('name = "x"\n', source="x.toml")
    with pytest.raises(DrillStringError, match="no such file"):
        load_string("/nonexistent/file.toml")


def test_parse_boundary_forms():
    assert parse_boundary("fixed") == Boundary.fixed()
    assert parse_boundary("free:500") == Boundary.free(500.0)
    assert parse_boundary("mass:500") == Boundary.free(500.0)
    assert parse_boundary("spring:1e8:2e4:10") == Boundary.spring(1e8, 2e4, 10.0)
    assert parse_boundary("hammer:1e9:5e3") == Boundary.hammer(1e9, 5e3)
    assert parse_boundary({"kind": "spring", "stiffness": 3.0}) == Boundary.spring(3.0)
    for b in (Boundary.spring(1e8, 2e4, 10.0), Boundary.hammer(1e9, 5e3), Boundary.free(3.0)):
        assert parse_boundary(b.spec()) == b
    with pytest.raises(DrillStringError):
        parse_boundary("spring:abc")
    with pytest.raises(DrillStringError):
        Boundary("fixed", stiffness=1.0)
    with pytest.raises(DrillStringError):
        Boundary.hammer(0.0)


# ------------------------------------------------- lab strings, junctions, eigen-solver
def lab_closed_form(l1, sec1: Section, l2, sec2: Section, k_top, k_bot, tip_mass, n, fixed_top=False):
    """Rod (1) over holder (2), top spring k_top (or fixed), bottom spring k_bot
    with the tip mass M.  Derived here, not with the library's transfer matrix:

    u1 = cos k1 z + B sin k1 z with EA1 k1 B = k_top (top: EA u'(0) = k_top u(0));
    fixed top: u1 = sin k1 z.  u2 = cos k2 (L - z) + D sin k2 (L - z) with
    bottom EA2 u2'(L) = (w^2 M - k_bot) u2(L), i.e. D = (k_bot - w^2 M)/(EA2 k2).
    Junction z = l1: u and EA u' continuous, so
    g(w) = EA1 u1'(l1) u2(l1) - EA2 u2'(l1) u1(l1) = 0.
    """
    ea1, ea2 = sec1.axial_stiffness, sec2.axial_stiffness

    def g(f):
        w = 2 * math.pi * f
        k1, k2 = w / sec1.wave_speed, w / sec2.wave_speed
        a, b = k1 * l1, k2 * l2
        if fixed_top:
            u1, du1 = math.sin(a), k1 * math.cos(a)
        else:
            B = k_top / (ea1 * k1)
            u1, du1 = math.cos(a) + B * math.sin(a), k1 * (-math.sin(a) + B * math.cos(a))
        D = (k_bot - w * w * tip_mass) / (ea2 * k2)
        u2 = math.cos(b) + D * math.sin(b)
        du2 = k2 * math.sin(b) - D * k2 * math.cos(b)
        return ea1 * du1 * u2 - ea2 * du2 * u1

    spacing = 1.0 / (2 * (l1 / sec1.wave_speed + l2 / sec2.wave_speed))
    return _roots(g, (n + 1.5) * spacing, spacing / 2000)[:n]


LAB_ROD = Section("rod", 3.0, 0.025, 0.0)
LAB_HOLDER = Section("holder", 0.25, 0.08, 0.02)


@pytest.mark.parametrize("top,bottom,fixed_top,k_top,k_bot", [
    ("spring:2e4", None, False, 2e4, 0.0),             # off bottom, the file's bit mass
    ("spring:2e4", "spring:5e6", False, 2e4, 5e6),     # on the rock sample, bit mass inherited
    ("fixed", None, True, 0.0, 0.0),
    ("fixed", "spring:5e6", True, 0.0, 5e6),
])
def test_lab_string_with_tip_mass_meets_the_target_at_default_settings(top, bottom, fixed_top, k_top, k_bot):
    """3 m rod, 0.25 m holder, 2.5 kg bit: the default mesh meets rtol = 1e-5
    on the first eight modes against the derived frequency equation."""
    lab = DrillString((LAB_ROD, LAB_HOLDER), name="lab3", top=Boundary.spring(2e4), bottom=Boundary.free(2.5))
    ref = lab_closed_form(3.0, LAB_ROD, 0.25, LAB_HOLDER, k_top, k_bot, 2.5, 8, fixed_top)
    m = modes(lab, top, bottom, count=8)
    assert m.bottom.mass == 2.5
    err = np.abs(m.frequencies_hz / ref - 1)
    assert np.all(err <= 1e-5), err
    assert np.all(m.error_estimate <= 1e-5)
    assert np.all(err <= 5 * m.error_estimate + 1e-9)     # the estimate is not optimistic
    # the library's transfer matrix agrees with the derived equation
    assert np.allclose(exact_frequencies(lab, top, bottom, 8), ref, rtol=1e-10)


def test_fourth_order_through_a_junction_of_unequal_sections():
    """Pipe over a heavier sub (tool-joint mass: other wave speed), meshed with
    unequal travel times on purpose: the corrected frequencies converge at
    fourth order; the plain FE eigenvalues drop to second order, and regain
    fourth order on a mesh of equal travel time."""
    s1 = Section("pipe", 300.0, 0.127, 0.1086)
    s2 = Section("sub", 60.0, 0.1651, 0.0714375, linear_mass=200.0)
    s = DrillString((s1, s2))
    ref = two_section_closed_form(s, "fixed", "free", 5)[1:]
    tau1, tau2 = 300.0 / s1.wave_speed, 60.0 / s2.wave_speed

    def orders(base):
        cor, raw = [], []
        for k in (1, 2, 4):
            m = modes(s.with_elements(tuple(k * b for b in base)), "fixed", "free", count=5, rtol=None)
            cor.append(np.abs(m.frequencies_hz[1:] / ref - 1))
            raw.append(np.abs(m.fe_frequencies_hz[1:] / ref - 1))
        return (np.log2(np.array(cor[1]) / cor[2]), np.log2(np.array(raw[1]) / raw[2]))

    unequal = (30, 3)                       # h/c differ by a factor ~2.4
    assert abs(math.log((300 / 30 / s1.wave_speed) / (60 / 3 / s2.wave_speed))) > math.log(2)
    p_cor, p_raw = orders(unequal)
    assert np.all(np.abs(p_cor - 4) < 0.3), p_cor
    assert np.all(np.abs(p_raw - 2) < 0.3), p_raw
    # equal travel time, exactly: the pipe length is a whole number of sub elements' travel time
    n2 = 6
    tau = 60.0 / n2 / s2.wave_speed
    n1 = round(300.0 / (s1.wave_speed * tau))
    s_eq = s.replace(sections=(dataclasses.replace(s1, length=n1 * s1.wave_speed * tau), s2))
    assert np.allclose(s_eq.with_elements((n1, n2)).travel_times, tau, rtol=1e-12)
    ref_eq = two_section_closed_form(s_eq, "fixed", "free", 5)[1:]
    raw = []
    for k in (1, 2, 4):
        m = modes(s_eq.with_elements((k * n1, k * n2)), "fixed", "free", count=5, rtol=None, correct=False)
        raw.append(np.abs(m.frequencies_hz[1:] / ref_eq - 1))
    p_eq = np.log2(np.array(raw[1]) / raw[2])
    assert np.all(np.abs(p_eq - 4) < 0.3), p_eq


def test_pencil_solver_matches_dense_eigh():
    from hammerbit.drillstring.eigen import pencil_eigenpairs, sturm_count
    import scipy.linalg as sla
    rng = np.random.default_rng(3)
    n = 60
    k = rng.uniform(1.0, 5.0, n + 1)
    mm = rng.uniform(0.5, 2.0, n + 1)
    kd = k[:-1] + k[1:]
    ke = -k[1:-1]
    md = (mm[:-1] + mm[1:]) * 5 / 12
    me = mm[1:-1] / 12
    K = np.diag(kd) + np.diag(ke, 1) + np.diag(ke, -1)
    M = np.diag(md) + np.diag(me, 1) + np.diag(me, -1)
    ref, vec = sla.eigh(K, M)
    lam, phi = pencil_eigenpairs(kd, ke, md, me, count=12)
    assert np.allclose(lam, ref[:12], rtol=1e-12)
    assert np.allclose(np.abs(phi.T @ M @ vec[:, :12]), np.eye(12), atol=1e-9)
    lam2, _ = pencil_eigenpairs(kd, ke, md, me, upper=0.5 * (ref[20] + ref[21]))
    assert lam2.size == 21 and np.allclose(lam2, ref[:21], rtol=1e-12)
    lam3, _ = pencil_eigenpairs(kd, ke, md, me, count=8, first=5)
    assert np.allclose(lam3, ref[5:8], rtol=1e-12)
    assert sturm_count(kd, ke, md, me, 0.5 * (ref[9] + ref[10])) == 10


def test_tighter_rtol_refines_the_mesh_and_meets_it():
    lab = DrillString((LAB_ROD, LAB_HOLDER), name="lab3", top=Boundary.spring(2e4), bottom=Boundary.free(2.5))
    ref = lab_closed_form(3.0, LAB_ROD, 0.25, LAB_HOLDER, 2e4, 0.0, 2.5, 4)
    loose = modes(lab, count=4, rtol=1e-4)
    tight = modes(lab, count=4, rtol=1e-8)
    assert tight.n_elements > loose.n_elements
    assert np.all(np.abs(loose.frequencies_hz / ref - 1) <= 1e-4)
    assert np.all(np.abs(tight.frequencies_hz / ref - 1) <= 1e-8)


def test_a_bottom_with_its_own_mass_keeps_it():
    s = DrillString((LAB_ROD,), bottom=Boundary.free(2.5))
    assert s.resolve_bottom("free") == Boundary.free(2.5)
    assert s.resolve_bottom("free:10") == Boundary.free(10.0)
    assert s.resolve_bottom("spring:5e6") == Boundary.spring(5e6, 0.0, 2.5)
    assert s.resolve_bottom("fixed") == Boundary.fixed()
    assert s.resolve_bottom("hammer:1e9") == Boundary.hammer(1e9)
    assert assemble(s, "fixed", "hammer:1e9").md_full[-1] - assemble(s, "fixed", "free:0.0001").md_full[-1] \
        == pytest.approx(2.5 - 1e-4)
