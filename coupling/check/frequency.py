"""Hammer / bit excitation frequency avoidance check for the axial string modes.

The check answers: *is it safe to run the hammer (or the bit) at this
excitation frequency, with the bit on bottom and off bottom, for any damping
in the assumed range?*

Excitation
    A hammer frequency ``f`` [Hz], or a rotary speed ``N`` [rpm] with an
    excitation multiplier ``K`` (3 for a tricone bit, the blade count for a
    PDC bit): ``f = K N / 60``.

Each mode is classified by its own band
    Every elastic mode ``f_n`` has the band ``|f/f_n - 1| <= margin`` (default
    15 %).  A mode is **isolated** when its band touches neither neighbour's
    band, **crowded** when it touches one: ``f_n (1 + m) >= f_{n+1} (1 - m)``.
    The classification belongs to the mode, not to the excitation.

The rule at an excitation ``f``, per end configuration
    1. ``f`` inside the band of an isolated mode -> **fail** (margin rule, the
       classic avoidance band);
    2. ``f`` inside the bands of crowded modes only -> the damped response
       decides (receptance rule): pass when the resonance factor ``R <=
       resonance_limit`` (default ``sqrt 2``, 3 dB) at every damping of the
       range;
    3. ``f`` outside every band -> **pass** (margin rule).

    The verdict changes only where ``f`` crosses a band edge or where ``R``
    crosses the limit: it is continuous in ``f`` everywhere else, also at the
    natural frequencies themselves.

Resonance factor
    The damped driving-point receptance at the bit ``H = x_bit/F_bit``
    compared with the same bit on a reflection-free string (bottom section
    continued to infinity): ``H_inf = 1/(i w Z* + Z_bc)``,
    ``R = max(|H/H_inf|, |1 - Z_bc H| / |1 - Z_bc H_inf|)`` with ``Z_bc = k + i
    w c - w^2 m`` of the bit boundary (bit motion and force passed into the
    string).  A fixed bit is displacement-driven: ``R = |D/(i w Z*)|`` with
    ``D`` the dynamic stiffness at the bit.  ``H`` and ``D`` are those of the
    continuous string (:func:`hammerbit.drillstring.exact_dynamic_stiffness`:
    transfer matrices, exact for piecewise-uniform sections, the same damping
    model as the finite elements, whose receptance converges to it).

Damping range
    The string's damping (hysteretic loss factor ``eta = 2 zeta`` of the
    file's ``modal_damping_ratio``, viscous damping per unit length) is
    uncertain.  The receptance rule is evaluated at the low end, the nominal
    value and the high end of a range of factors (default x0.5 .. x2).  A
    **robust pass** holds at all three; a **pass at nominal damping only**
    fails at one end and is labelled so (text and JSON).  The margin rule does
    not depend on damping.

Safe windows
    Maximal frequency intervals with the same label (``margin``, ``receptance``
    robust, ``receptance`` at nominal damping only), edges refined by
    bisection, intersected over both configurations.  Each window carries the
    rule that cleared it and the damping range assumed.  Safe runs narrower
    than ``min_window`` times their centre frequency are dropped.

Inputs and results: :mod:`hammerbit.check.results`; plots:
:mod:`hammerbit.check.plots` (both re-exported here).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hammerbit.check.results import (
    FAIL,
    LABELS,
    MARGIN,
    NOMINAL_ONLY,
    RECEPTANCE,
    CheckConfig,
    CheckResult,
    ConfigurationResult,
    ModeRow,
    Window,
)
from hammerbit.drillstring import Boundary, DampingModel, DrillString, exact_dynamic_stiffness, modes, reference_impedance, resolve_ends, static_compliance
from hammerbit.drillstring.validation import check_number
from hammerbit.drillstring.damping import boundary_impedance
from hammerbit.drillstring.eigen import has_rigid_mode
from hammerbit.drillstring.modes import solve_modes

__all__ = [
    "CheckConfig", "ModeRow", "ConfigurationResult", "Window", "CheckResult", "resonance_factor", "check",
    "plot_campbell", "plot_receptance", "plot_check", "bit_receptance", "bit_dynamic_stiffness",
    "hammer_on_bottom_frequencies", "LABELS", "FAIL", "MARGIN", "RECEPTANCE", "NOMINAL_ONLY",
]


# --------------------------------------------------------------------------
# damped response of the continuous string
# --------------------------------------------------------------------------
def _response(string, top, bottom, bit_mass, damping, f):
    """H [m/N] (force-driven bit) or D [N/m] (fixed bit) of the continuous string (F,)."""
    d = exact_dynamic_stiffness(string, f, top, damping)
    if bottom.is_fixed:
        return d
    w = 2.0 * math.pi * f
    with np.errstate(divide="ignore", invalid="ignore"):
        return 1.0 / (d + boundary_impedance(bottom, w, bit_mass))


def _reference(string, bottom, bit_mass, damping, f):
    """Reflection-free response: ``1/(i w Z* + Z_bc)`` (force) or ``i w Z*`` (fixed bit)."""
    dinf = reference_impedance(string, f, damping)
    if bottom.is_fixed:
        return dinf
    w = 2.0 * math.pi * f
    return 1.0 / (dinf + boundary_impedance(bottom, w, bit_mass))


def _factors(string, top, bottom, bit_mass, damping, f, resp=None):
    """``(R, R_motion, R_force)`` (F,) each."""
    resp = _response(string, top, bottom, bit_mass, damping, f) if resp is None else resp
    ref = _reference(string, bottom, bit_mass, damping, f)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if bottom.is_fixed:
            r = np.abs(resp / ref)
            return r, r, r
        zbc = boundary_impedance(bottom, 2.0 * math.pi * f, bit_mass)
        rm = np.abs(resp / ref)
        rf = np.abs((1.0 - zbc * resp) / (1.0 - zbc * ref))
        return np.maximum(rm, rf), rm, rf


# --------------------------------------------------------------------------
# one end configuration
# --------------------------------------------------------------------------
class _Config:
    """Modes, classification and damped response of one end configuration."""

    def __init__(self, name: str, string: DrillString, top: Boundary, bottom: Boundary, config: CheckConfig,
                 f_band: float):
        self.name = name
        self.string = string
        self.top = top
        self.bottom = bottom
        self.margin = config.margin
        m = modes(string, top, bottom, f_max=f_band, rtol=config.rtol, mass=config.mass)
        fine = string.with_elements(m.elements_per_section)
        # one mode above the band range classifies the last one
        asm, _, lam_x, phi_x = solve_modes(fine, top, bottom, None, len(m) + 1, config.mass, True, first=len(m))
        phi = m.shapes[asm.start:asm.stop]
        lam_c = (2.0 * math.pi * m.frequencies_hz) ** 2
        self.asm = asm
        self.lam = np.concatenate((lam_c, lam_x))
        self.phi = np.concatenate((phi, phi_x), axis=1)
        self.freqs = np.sqrt(self.lam) / (2.0 * math.pi)
        self.error_estimate = np.full(self.freqs.size, np.nan)
        if m.error_estimate is not None:
            self.error_estimate[:len(m)] = m.error_estimate
        self.n_elements = fine.n_elements
        self.rigid = has_rigid_mode(asm.top, asm.bottom)
        self.elastic = self.freqs > 0.0
        if self.rigid:
            self.elastic[0] = False
        fe = self.freqs[self.elastic]
        mm = self.margin
        touch = fe[:-1] * (1.0 + mm) >= fe[1:] * (1.0 - mm)      # band j touches band j+1
        crowded = np.zeros(fe.size, dtype=bool)
        crowded[:-1] |= touch
        crowded[1:] |= touch
        crowded[-1] = True  # its upper neighbour is not computed; it never reaches the range
        self.fe, self.crowded_modes = fe, crowded
        self.displacement = bottom.is_fixed
        self.bit_mass = 0.0 if bottom.is_fixed else (string.bit_mass if bottom.kind == "hammer" else bottom.mass)
        self.factors = config.damping_factors
        self.dampings = [DampingModel.of(string, s) for s in self.factors]

    # frequency response ---------------------------------------------------
    def response(self, f: np.ndarray, level: int = 1) -> np.ndarray:
        """H [m/N] (force) or D [N/m] (displacement) of the continuous string."""
        return _response(self.string, self.top, self.bottom, self.bit_mass, self.dampings[level], f)

    def reference(self, f: np.ndarray, level: int = 1) -> np.ndarray:
        return _reference(self.string, self.bottom, self.bit_mass, self.dampings[level], f)

    def factors_at(self, f: np.ndarray, level: int = 1, resp: np.ndarray | None = None):
        """``(R, R_motion, R_force)`` (F,) each."""
        f = np.atleast_1d(np.asarray(f, dtype=float))
        return _factors(self.string, self.top, self.bottom, self.bit_mass, self.dampings[level], f, resp)

    # classification --------------------------------------------------------
    def bands(self, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(in an isolated band, in a crowded band)`` (F,) bool each."""
        inb = np.abs(f[:, None] / self.fe[None, :] - 1.0) <= self.margin
        return np.any(inb & ~self.crowded_modes, axis=1), np.any(inb & self.crowded_modes, axis=1)

    def label(self, f: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(label (F,), crowded (F,), R (3, F))`` of this configuration."""
        iso, crowd = self.bands(f)
        only = crowd & ~iso
        r = np.full((3, f.size), np.nan)
        if np.any(only):
            for lev in range(3):
                r[lev, only] = self.factors_at(f[only], lev)[0]
        lab = np.full(f.size, MARGIN)
        lab[iso] = FAIL
        ok = r <= limit
        lab[only] = np.where(~ok[1, only], FAIL, np.where(ok[0, only] & ok[2, only], RECEPTANCE, NOMINAL_ONLY))
        return lab, only, r

    def contributions(self, f: float) -> np.ndarray:
        """|modal contribution| to the bit response at f (n,) (ranking only)."""
        w = 2.0 * math.pi * f
        eta = self.dampings[1].loss_factor
        den = self.lam * (1.0 + 1j * eta) - w * w
        if self.displacement:
            a = self.asm
            b = a.ke_full[-1] - w * w * a.me_full[-1]
            num = (b * self.phi[-1]) ** 2
        else:
            num = self.phi[-1] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.abs(num / den)


def _combine(labels: list[np.ndarray]) -> np.ndarray:
    """Combined label over configurations: fail if any fails; margin if all
    margin; nominal-only if any needs nominal damping; else receptance."""
    stack = np.vstack(labels)
    out = np.full(stack.shape[1], RECEPTANCE)
    out[np.all(stack == MARGIN, axis=0)] = MARGIN
    out[np.any(stack == NOMINAL_ONLY, axis=0)] = NOMINAL_ONLY
    out[np.any(stack == FAIL, axis=0)] = FAIL
    return out


class _Evaluator:
    """Combined label at any frequency (used for the verdict, the sweep and the window edges)."""

    def __init__(self, cfgs: list[_Config], limit: float):
        self.cfgs, self.limit = cfgs, limit

    def label(self, f: np.ndarray):
        parts = [c.label(f, self.limit) for c in self.cfgs]
        return _combine([p[0] for p in parts]), parts


# --------------------------------------------------------------------------
# the check
# --------------------------------------------------------------------------
def _mean_spacing_hz(string: DrillString) -> float:
    return 1.0 / (2.0 * sum(s.length / s.wave_speed for s in string.sections))


def check(string: DrillString, config: CheckConfig) -> CheckResult:
    """Run the hammer/bit frequency avoidance check (see the module docstring).

    Parameters
    ----------
    string : DrillString
    config : CheckConfig

    Returns
    -------
    CheckResult
    """
    fx = config.frequency_hz
    m = config.margin
    f_lo, f_hi = config.range_hz
    f_hi = max(f_hi, fx)
    f_lo = min(f_lo, fx)
    f_band = f_hi / (1.0 - m)               # every mode whose band reaches the range
    top, _ = resolve_ends(string, config.top, "free")
    ends = {"on_bottom": string.resolve_bottom(string.on_bottom if config.on_bottom is None
                                               else config.on_bottom, where="on_bottom"),
            "off_bottom": string.resolve_bottom(string.off_bottom if config.off_bottom is None
                                                else config.off_bottom, where="off_bottom")}
    for name, b in ends.items():
        if b.kind == "hammer":
            ends[name] = Boundary.free(string.bit_mass)   # the hammer is not part of this check
    cfgs = [_Config(name, string, top, b, config, f_band) for name, b in ends.items()]
    ev = _Evaluator(cfgs, config.resonance_limit)
    zeta = string.modal_damping_ratio
    zetas = tuple(zeta * s for s in config.damping_factors)

    results = [_evaluate(c, fx, config, zetas) for c in cfgs]
    failing = [r for r in results if r.verdict == "fail"]
    verdict = "fail" if failing else "pass"
    robust = not failing and all(r.robust for r in results)
    decisive = failing if failing else results
    rule = "+".join(sorted({r.rule for r in decisive}))
    label = "fail" if failing else ("robust pass" if robust else "pass at nominal damping only")
    reason = f"{label}: " + "; ".join(f"{r.name}: {r.reason}" for r in decisive)

    # sweep and windows
    n_grid = config.n_grid or max(2001, int(40 * (f_hi - f_lo) / _mean_spacing_hz(string)) + 1)
    start = f_lo if f_lo > 0 else f_hi / n_grid
    grid = np.linspace(start, f_hi, int(n_grid))
    labels, parts = ev.label(grid)
    windows = _windows(grid, labels, ev, config, f_lo, zetas)
    sweep_h, sweep_ref, sweep_r, sweep_c = {}, {}, {}, {}
    for c, (lab, only, r) in zip(cfgs, parts):
        resp = c.response(grid)
        sweep_h[c.name] = np.abs(resp)
        sweep_ref[c.name] = np.abs(c.reference(grid))
        full = np.vstack([c.factors_at(grid, lev)[0] for lev in range(3)])
        sweep_r[c.name] = full
        sweep_c[c.name] = only
    n_el = max(c.n_elements for c in cfgs)
    return CheckResult(string.name, config, fx, verdict, robust, rule, reason, tuple(results), windows,
                       (f_lo, f_hi), n_el, zetas, grid, sweep_h, sweep_ref, sweep_r, sweep_c, labels, ev)


def _evaluate(c: _Config, fx: float, config: CheckConfig, zetas) -> ConfigurationResult:
    m = config.margin
    limit = config.resonance_limit
    f = np.array([fx])
    contrib = c.contributions(fx)
    total = float(np.sum(contrib[np.isfinite(contrib)])) or 1.0
    order = np.argsort(-np.where(np.isfinite(contrib), contrib, np.inf))
    rank = np.empty(order.size, dtype=int)
    rank[order] = np.arange(1, order.size + 1)
    rows = []
    n_rigid = int(np.sum(~c.elastic))
    iso_of = np.zeros(c.freqs.size, dtype=bool)
    iso_of[c.elastic] = ~c.crowded_modes
    list_up_to = max(fx / (1.0 - m), c.freqs[min(3 + n_rigid, c.freqs.size - 1)])
    for j, fn in enumerate(c.freqs):
        if fn > list_up_to * (1 + 1e-12):
            continue
        el = bool(c.elastic[j])
        sep = 100.0 * (fx - fn) / fn if el else math.inf
        est = c.error_estimate[j]
        rows.append(ModeRow(c.name, j - n_rigid + 1 if el else 0, float(fn), sep,
                            bool(el and abs(sep) <= 100.0 * m), bool(iso_of[j]), float(contrib[j]),
                            float(contrib[j] / total), int(rank[j]), None if not np.isfinite(est) else float(est)))
    elastic_rows = [r for r in rows if r.index > 0]
    nearest = min(elastic_rows, key=lambda r: abs(r.separation_pct)) if elastic_rows else None
    dominant = min(rows, key=lambda r: r.rank) if rows else None

    lab, only, r_lev = c.label(f, limit)
    lab, only = int(lab[0]), bool(only[0])
    resp_arr = c.response(f)
    resp = complex(resp_arr[0])
    rf, r_motion, r_force = (float(x[0]) for x in c.factors_at(f, 1, resp_arr))
    r_by = tuple(float(c.factors_at(f, lev)[0][0]) for lev in range(3))
    if c.displacement:
        d0 = abs(complex(c.response(np.array([1e-6]))[0]))
        amp = abs(resp) / d0 if d0 > 0 else math.inf
        comp = 1.0 / d0 if d0 > 0 else math.inf
        h, dyn = 0j, resp
    else:
        comp = static_compliance(c.string, c.top, c.bottom)
        amp = abs(resp) / comp if 0 < comp < math.inf else math.inf
        h, dyn = resp, None

    inband = [r for r in elastic_rows if r.in_band]
    iso_in = [r for r in inband if r.isolated]
    fac = config.damping_factors
    if iso_in:
        worst = min(iso_in, key=lambda r: abs(r.separation_pct))
        regime, rule, verdict, robust = "isolated", "margin", "fail", False
        by = ("fail",) * 3
        reason = (f"margin rule: mode {worst.index} at {worst.frequency_hz:.4g} Hz (isolated band) is "
                  f"{worst.separation_pct:+.2f} % from the excitation, inside +-{100 * m:.0f} %")
    elif only:
        regime, rule = "crowded", "receptance"
        by = tuple("pass" if x <= limit else "fail" for x in r_by)
        verdict = by[1]
        robust = all(v == "pass" for v in by)
        names = ", ".join(str(r.index) for r in inband)
        dom = f"; dominant mode {dominant.index} at {dominant.frequency_hz:.4g} Hz " \
              f"({100 * dominant.share:.0f} % of the bit response)" if dominant else ""
        rs = " / ".join(f"{x:.3g}" for x in r_by)
        if verdict == "fail":
            tail = f"R = {rf:.3g} > {limit:.3g} at nominal damping"
        elif robust:
            tail = f"R <= {limit:.3g} at damping x{fac[0]:g} .. x{fac[2]:g}"
        else:
            bad = " and ".join(f"x{fac[i]:g}" for i in (0, 2) if by[i] == "fail")
            tail = f"pass at nominal damping only (R > {limit:.3g} at damping {bad})"
        reason = (f"receptance rule (only crowded modes {names} within +-{100 * m:.0f} %): "
                  f"{tail}; R at damping x{fac[0]:g}/x1/x{fac[2]:g} = {rs}{dom}")
    else:
        regime, rule, verdict, robust = "clear", "margin", "pass", True
        by = ("pass",) * 3
        sep = f"nearest mode {nearest.index} at {nearest.frequency_hz:.4g} Hz is " \
              f"{nearest.separation_pct:+.1f} % away" if nearest else "no elastic mode"
        reason = f"margin rule: {sep}, outside +-{100 * m:.0f} %"
    assert (lab == FAIL) == (verdict == "fail")
    est = c.error_estimate[np.isfinite(c.error_estimate)]
    return ConfigurationResult(c.name, c.top, c.bottom, "displacement" if c.displacement else "force",
                               tuple(rows), c.freqs, regime, rule, verdict, robust, reason, h, dyn, comp, amp, rf,
                               r_motion, r_force, r_by, by, nearest, dominant, c.n_elements,
                               float(est.max()) if est.size else None)


def _windows(grid: np.ndarray, labels: np.ndarray, ev: _Evaluator, config: CheckConfig, f_lo: float,
             zetas) -> tuple[Window, ...]:
    """Runs of equal non-fail label, edges refined by bisection on the label."""
    change = np.nonzero(labels[1:] != labels[:-1])[0]
    a, b = grid[change].copy(), grid[change + 1].copy()
    la, lb = labels[change].copy(), labels[change + 1].copy()
    for _ in range(44):
        if a.size == 0:
            break
        mid = 0.5 * (a + b)
        lm = ev.label(mid)[0]
        left = lm == la
        a = np.where(left, mid, a)
        b = np.where(left, b, mid)
    edges = 0.5 * (a + b)
    bounds = np.concatenate(([f_lo if f_lo < grid[0] else grid[0]], edges, [grid[-1]]))
    seg_labels = np.concatenate(([labels[0]], labels[change + 1]))
    pieces = [(float(bounds[i]), float(bounds[i + 1]), int(seg_labels[i])) for i in range(seg_labels.size)]
    # drop safe runs (consecutive non-fail pieces) narrower than min_window x centre
    out: list[Window] = []
    i = 0
    while i < len(pieces):
        if pieces[i][2] == FAIL:
            i += 1
            continue
        j = i
        while j + 1 < len(pieces) and pieces[j + 1][2] != FAIL:
            j += 1
        lo, hi = pieces[i][0], pieces[j][1]
        if hi > lo and hi - lo >= config.min_window * 0.5 * (lo + hi):
            for p in pieces[i:j + 1]:
                if p[1] <= p[0]:
                    continue
                rule = "margin" if p[2] == MARGIN else "receptance"
                robust = p[2] != NOMINAL_ONLY
                rng = None if rule == "margin" else ((zetas[0], zetas[2]) if robust else (zetas[1], zetas[1]))
                out.append(Window(p[0], p[1], rule, robust, rng))
        i = j + 1
    return tuple(out)


def resonance_factor(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                     bottom: "Boundary | str | None" = None, *, damping_scale: float = 1.0) -> np.ndarray:
    """Resonance factor ``R(f)`` (F,) [-] at the bit (see the module docstring),
    from the continuous string with its own damping times ``damping_scale``;
    the bit mass applies, a ``hammer`` bottom counts as free."""
    t, b = resolve_ends(string, top, bottom)
    bit_mass = 0.0 if b.is_fixed else (string.bit_mass if b.kind == "hammer" else b.mass)
    if b.kind == "hammer":
        b = Boundary.free(bit_mass)
    f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    return _factors(string, t, b, bit_mass, DampingModel.of(string, damping_scale), f)[0]


from hammerbit.drillstring import bit_dynamic_stiffness, bit_receptance  # noqa: E402  (re-exported)
from hammerbit.check.plots import plot_campbell, plot_check, plot_receptance  # noqa: E402  (re-exported)


# --------------------------------------------------------------------------
# the hammer as the bottom boundary (bit on bottom)
# --------------------------------------------------------------------------
def hammer_on_bottom_frequencies(string: DrillString, *, interface_stiffness: float,
                                 hammer_mass: float, hammer_stiffness: float,
                                 top: "Boundary | str | None" = None, f_max: float = 100.0,
                                 mass: str = "mixed", exact: bool = False) -> np.ndarray:
    """Undamped natural frequencies [Hz] with the hammer as the string's bottom boundary.

    The string's bottom node carries the interface spring ``k_i`` to the hammer
    body (mass ``m1``), and the hammer's spring ``K`` holds it to the bit, which
    the rock holds (bit on bottom, stuck).  The chain stays tridiagonal: the
    hammer is one more node below the bit node.

    Parameters
    ----------
    string : DrillString
    interface_stiffness : float
        k_i, string-to-hammer interface [N/m].
    hammer_mass : float
        m1 [kg].
    hammer_stiffness : float
        K, hammer-to-bit spring [N/m].
    top : Boundary or str, optional
        Top end (default the string's).
    f_max : float
        Highest frequency returned [Hz].
    mass : {'mixed', 'lumped', 'consistent'}
    exact : bool
        The continuous bar instead of the finite elements: roots of the
        transfer-matrix frequency function with the bottom's dynamic stiffness
        ``k_i (K - m1 w^2) / (k_i + K - m1 w^2)`` (multiplied through by the
        denominator, so the hammer's own resonance is no pole).

    Returns
    -------
    ndarray, shape (m,)
        Natural frequencies up to ``f_max`` [Hz], ascending.
    """
    import scipy.linalg as sla
    from hammerbit.drillstring import assemble
    for name, v in (("interface_stiffness", interface_stiffness), ("hammer_mass", hammer_mass),
                    ("hammer_stiffness", hammer_stiffness)):
        check_number("hammer boundary", name, v, 0.0, None, lo_open=True)
    if exact:
        return _hammer_on_bottom_exact(string, interface_stiffness, hammer_mass, hammer_stiffness, top, f_max)
    asm = assemble(string, top, "free", mass=mass)
    n = asm.n_dof
    K = np.zeros((n + 1, n + 1))
    M = np.zeros((n + 1, n + 1))
    K[:n, :n] = asm.K
    M[:n, :n] = asm.M
    K[n - 1, n - 1] += interface_stiffness
    K[n - 1, n] = K[n, n - 1] = -interface_stiffness
    K[n, n] = interface_stiffness + hammer_stiffness
    M[n, n] = hammer_mass
    hi = (2.0 * math.pi * f_max) ** 2
    lam = sla.eigh(K, M, eigvals_only=True, subset_by_value=(-1.0, hi))
    return np.sqrt(np.maximum(lam, 0.0)) / (2.0 * math.pi)


def _hammer_on_bottom_exact(string, ki, m1, K, top, f_max, points: int = 4000) -> np.ndarray:
    """Exact frequencies of the continuous string with the hammer at the bottom (see above)."""
    from scipy.optimize import brentq
    from hammerbit.drillstring import parse_boundary
    from hammerbit.drillstring.modes import bottom_state
    topb = parse_boundary(string.top if top is None else top)

    def g(w):
        w = np.atleast_1d(np.asarray(w, dtype=float))
        u, nn = bottom_state(string, topb, w)
        # bottom: N = -k_b(w) u with k_b the interface in series with the hammer on K
        return ki * (K - m1 * w ** 2) * u + (ki + K - m1 * w ** 2) * nn

    wmax = 2.0 * math.pi * f_max
    grid = np.linspace(1e-6, wmax, points)
    val = g(grid)
    roots = [brentq(lambda x: float(g(x)[0]), grid[i], grid[i + 1], xtol=1e-12, rtol=1e-14)
             for i in np.nonzero(np.sign(val[:-1]) * np.sign(val[1:]) < 0)[0]]
    return np.array(roots) / (2.0 * math.pi)
