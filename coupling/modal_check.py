"""Hammer / bit excitation frequency avoidance check for the axial string modes.

The check answers: *is it safe to run the hammer (or the bit) at this
excitation frequency, with the bit on bottom and off bottom?*

Excitation
    A hammer frequency ``f`` [Hz], or a rotary speed ``N`` [rpm] with an
    excitation multiplier ``K`` (3 for a tricone bit, the blade count for a
    PDC bit): ``f = K N / 60``.

Two rules, and the result says which one decided
    1. **Margin rule** (classic, where modes are *separated*): fail when a
       natural frequency lies within ``+-margin`` of the excitation,
       ``|f/f_n - 1| <= margin`` (default 15 %).
    2. **Receptance rule** (where modes are *crowded*): the modes ``f_a <=
       f <= f_b`` around the excitation are crowded when their bands touch,
       ``f_a (1 + margin) >= f_b (1 - margin)``; then every frequency between
       them is inside some band and the margin rule fails whatever the
       speed.  There the verdict comes from the damped driving-point
       receptance at the bit ``H = x_bit/F_bit``, compared with the same bit
       on a *reflection-free* string (bottom section continued to infinity,
       same bottom boundary): ``H_inf = 1/(i w Z + Z_bc)``, ``Z`` the axial
       impedance ``sqrt(EA m')`` of the bottom section and ``Z_bc = k + i w c
       - w^2 m`` the bottom boundary.  The *resonance factor*

           R = max(R_motion, R_force),
           R_motion = |H / H_inf|                    (bit motion),
           R_force  = |1 - Z_bc H| / |1 - Z_bc H_inf|  (force passed into the string),

       is above 1 where standing waves amplify the response and below 1 at
       anti-resonances.  Both parts are needed: off bottom (free bit) the
       force entering the string is the applied force and only the motion
       can resonate; on a stiff rock the bit hardly moves and the resonance
       shows in the force the string carries.  Pass when ``R <=
       resonance_limit`` (default ``sqrt(2)``, within 3 dB of the
       reflection-free response).  Modes are ranked by their contribution
       ``|phi_b^2 / (w_n^2 - w^2 + i w c_n)|`` to the bit receptance at the
       excitation; the dominant one is named in the reason.

    ``R`` is only used where modes are crowded: below the first few modes
    the string is shorter than a wavelength, responds quasi-statically and
    ``R`` (relative to a wave-carrying reference) is not a resonance
    measure.  The static dynamic amplification ``|H(f)|/H(0)`` is reported
    too but cannot rank high-frequency behaviour either: the receptance falls
    like ``1/(w Z)`` above the first modes, so a static criterion passes
    everything there, just as the pure margin criterion fails everything.

Bit on bottom / off bottom
    Both configurations are checked; the verdict is ``fail`` if either
    fails.  With a ``spring`` (bit-rock contact) or ``free`` bit the
    excitation is a force at the bit.  With a ``fixed`` bit the bit cannot
    move under a force, so the excitation is a prescribed bit displacement
    and ``R = |D(f)| / (w Z)`` with ``D`` the dynamic stiffness of the
    string at the bit (the limit of ``R_force`` for a very stiff rock).  A
    ``hammer`` bottom is treated as free (the hammer model is not part of
    this check).

Safe windows
    The rule above applied on a frequency grid over the requested range
    (edges refined by bisection), intersected over both configurations and
    reported in Hz (and rpm when a factor is given).  Windows narrower than
    ``min_window`` times their centre frequency are dropped.

Plots: :func:`plot_campbell`, :func:`plot_receptance`, :func:`plot_check`
(matplotlib, Agg backend, imported lazily).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import scipy.linalg as sla

from .drillstring import (
    DEFAULT_MASS,
    DrillStringError,
    _check_number,
    Assembly,
    Boundary,
    DrillString,
    _eigen,
    assemble,
    parse_boundary,
    static_compliance,
)

__all__ = [
    "CheckConfig",
    "ModeRow",
    "ConfigurationResult",
    "CheckResult",
    "bit_receptance",
    "bit_dynamic_stiffness",
    "resonance_factor",
    "check",
    "plot_campbell",
    "plot_receptance",
    "plot_check",
]

_CHUNK = 2048


# --------------------------------------------------------------------------
# receptance
# --------------------------------------------------------------------------
def _receptance_evaluator(asm: Assembly, eig: tuple[np.ndarray, np.ndarray] | None = None):
    """Return ``H(omega)``: damped driving-point receptance of the last DOF
    (F,) -> (F,) complex [m/N], with the expensive part pre-computed.

    * no modal damping: LDL^T pivots of the tridiagonal dynamic stiffness
      ``K - w^2 M + i w C`` (exact, O(n) per frequency, vectorised over w);
    * modal damping only: modal sum over all modes (exact);
    * modal + viscous damping: complex eigen-decomposition of the
      first-order system in modal coordinates (exact, non-proportional).

    ``eig`` optionally passes the complete ``(omega^2, Phi)`` of ``asm``.
    """
    if asm.modal_damping_ratio == 0.0:
        kd, ke = asm.tridiagonal("K")
        md, me = asm.tridiagonal("M")
        cd, ce = asm.tridiagonal("C")

        def pivots(w: np.ndarray) -> np.ndarray:
            w2 = w * w
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                piv = kd[0] - w2 * md[0] + 1j * w * cd[0]
                for i in range(1, kd.size):  # recursion along the chain (sequential by nature)
                    off = ke[i - 1] - w2 * me[i - 1] + 1j * w * ce[i - 1]
                    piv = (kd[i] - w2 * md[i] + 1j * w * cd[i]) - off * off / piv
                return 1.0 / piv
        return pivots
    lam, phi = _eigen(asm, None, None, all_modes=True) if eig is None else eig
    pb = phi[-1]
    zeta = asm.modal_damping_ratio
    if not asm.has_viscous:
        poles_c = 2.0 * zeta * np.sqrt(lam)
        num = pb * pb

        def modal_sum(w: np.ndarray) -> np.ndarray:
            out = np.empty(w.size, dtype=complex)
            for s in range(0, w.size, _CHUNK):
                ww = w[s:s + _CHUNK, None]
                out[s:s + _CHUNK] = np.sum(num / (lam - ww * ww + 1j * ww * poles_c), axis=1)
            return out
        return modal_sum
    n = lam.size
    chat = phi.T @ asm.C_viscous @ phi + np.diag(2.0 * zeta * np.sqrt(lam))
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(lam), -chat]])
    ev, V = sla.eig(A)
    res = (np.concatenate((pb, np.zeros(n))) @ V) * sla.solve(V, np.concatenate((np.zeros(n), pb)))

    def pole_sum(w: np.ndarray) -> np.ndarray:
        out = np.empty(w.size, dtype=complex)
        for s in range(0, w.size, _CHUNK):
            ww = w[s:s + _CHUNK, None]
            out[s:s + _CHUNK] = np.sum(res / (1j * ww - ev), axis=1)
        return out
    return pole_sum


def _dynamic_stiffness_evaluator(asm_fixed: Assembly, eig: tuple[np.ndarray, np.ndarray] | None = None):
    """Return ``D(omega)`` [N/m] of the bit node of a fixed-bit assembly."""
    h_adj = _receptance_evaluator(asm_fixed, eig)

    def dyn(w: np.ndarray) -> np.ndarray:
        a_bb = asm_fixed.kd_full[-1] - w * w * asm_fixed.md_full[-1] + 1j * w * asm_fixed.cd_full[-1]
        b = asm_fixed.ke_full[-1] - w * w * asm_fixed.me_full[-1] + 1j * w * asm_fixed.ce_full[-1]
        return a_bb - b * b * h_adj(w)
    return dyn


def _last_dof_receptance(asm: Assembly, omega: np.ndarray) -> np.ndarray:
    """Receptance of the last DOF at ``omega`` (F,) [rad/s] -> (F,) [m/N]."""
    return _receptance_evaluator(asm)(np.asarray(omega, dtype=float))


def _as_omega(freqs_hz: Any) -> np.ndarray:
    return 2.0 * math.pi * np.atleast_1d(np.asarray(freqs_hz, dtype=float))


def bit_receptance(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                   bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS) -> np.ndarray:
    """Damped driving-point receptance at the bit ``x_bit/F_bit`` [m/N].

    Parameters
    ----------
    string : DrillString
    freqs_hz : array_like (F,)
        Frequencies [Hz].
    top, bottom : Boundary or str, optional
        Ends (defaults from ``string``); the bottom spring/dashpot/mass act
        at the bit, ``hammer`` counts as free.  A fixed bit gives zeros.
    mass : {"mixed", "lumped", "consistent"}

    Returns
    -------
    ndarray (F,) complex
        Receptance [m/N]; ``|H|`` is the dynamic compliance, ``angle(H)`` the
        phase of displacement relative to force.
    """
    w = _as_omega(freqs_hz)
    asm = assemble(string, top, bottom, mass=mass)
    if asm.bottom.is_fixed:
        return np.zeros(w.size, dtype=complex)
    return _last_dof_receptance(asm, w)


def bit_dynamic_stiffness(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                          *, mass: str = DEFAULT_MASS) -> np.ndarray:
    """Reaction force at a bit whose displacement is prescribed, per metre
    ``D(f) = F_bit/x_bit`` [N/m] (F,) complex.

    Computed as ``a_bb - b^2 H_adj`` where ``a_bb``, ``b`` are the bit
    diagonal and coupling entries of ``K - w^2 M + i w C`` and ``H_adj`` the
    receptance of the node above the bit with the bit fixed; the modal
    damping is that of the fixed-bit modes.  ``D(0)`` is the static axial
    stiffness of the string at the bit.
    """
    asm = assemble(string, top, Boundary.fixed(), mass=mass)
    return _dynamic_stiffness_evaluator(asm)(_as_omega(freqs_hz))


def _boundary_impedance(bottom: Boundary, w: np.ndarray) -> np.ndarray:
    """Dynamic stiffness of the bottom boundary ``k + i w c - w^2 m`` [N/m]."""
    return bottom.ground_stiffness + 1j * w * bottom.ground_damping - w * w * bottom.mass


def _reference(bottom: Boundary, z_bottom: float, w: np.ndarray) -> np.ndarray:
    """Reflection-free response: ``H_inf = 1/(i w Z + k + i w c - w^2 m)``
    for a force-driven bit, ``D_inf = i w Z`` for a displacement-driven bit."""
    if bottom.is_fixed:
        return 1j * w * z_bottom
    return 1.0 / (1j * w * z_bottom + _boundary_impedance(bottom, w))


def _factors(bottom: Boundary, z_bottom: float, w: np.ndarray,
             resp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(R, R_motion, R_force)`` from the bit response ``resp`` (H or D).

    Force-driven bit: ``R_motion = |H/H_inf|`` (bit motion) and
    ``R_force = |1 - Z_bc H| / |1 - Z_bc H_inf|`` (force passed into the
    string, ``F_s/F = D H = 1 - Z_bc H``); fixed bit: both ``|D/D_inf|``.
    ``R = max(R_motion, R_force)``.
    """
    ref = _reference(bottom, z_bottom, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        if bottom.is_fixed:
            r = np.abs(resp / ref)
            return r, r, r
        zbc = _boundary_impedance(bottom, w)
        rm = np.abs(resp / ref)
        rf = np.abs((1.0 - zbc * resp) / (1.0 - zbc * ref))
        return np.maximum(rm, rf), rm, rf


def resonance_factor(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                     bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS) -> np.ndarray:
    """Resonance factor ``R(f)`` (F,) [-] at the bit (see module docstring).

    Force-driven bit (free, spring, hammer = free): the larger of the bit
    motion ratio ``|H/H_inf|`` and the string-force ratio
    ``|1 - Z_bc H| / |1 - Z_bc H_inf|``; fixed (displacement-driven) bit:
    ``|D/D_inf|``.  ``H_inf``, ``D_inf``: same bit on a reflection-free
    (semi-infinite) bottom section; ``Z_bc = k + i w c - w^2 m`` of the
    bottom boundary.
    """
    w = _as_omega(freqs_hz)
    bot = parse_boundary(string.bottom if bottom is None else bottom)
    if bot.kind == "hammer":
        bot = Boundary.free()
    z = string.sections[-1].impedance
    if bot.is_fixed:
        resp = bit_dynamic_stiffness(string, freqs_hz, top, mass=mass)
    else:
        resp = bit_receptance(string, freqs_hz, top, bot, mass=mass)
    return _factors(bot, z, w, resp)[0]


# --------------------------------------------------------------------------
# configuration and results
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class CheckConfig:
    """Inputs of the avoidance check (all frequencies in Hz, speeds in rpm)."""

    excitation_hz: float | None = None
    """Hammer (or any) excitation frequency [Hz]; exclusive with ``rpm``."""
    rpm: float | None = None
    """Rotary speed [rev/min]; the excitation is ``factor * rpm / 60`` Hz."""
    factor: float = 1.0
    """Excitation multiplier [-]: 3 for a tricone bit, the blade count for a PDC bit."""
    margin: float = 0.15
    """Half-width of the avoidance band around each natural frequency [-] (0.15 = +-15 %)."""
    top: Boundary | str | None = None
    """Top boundary (default ``string.top``, normally the fixed hook)."""
    on_bottom: Boundary | str | None = None
    """Bit-on-bottom boundary (default ``string.on_bottom``)."""
    off_bottom: Boundary | str | None = None
    """Bit-off-bottom boundary (default ``string.off_bottom``)."""
    frequency_range_hz: tuple[float, float] | None = None
    """Range [Hz] for the safe windows and plots (default 0 .. 2 f)."""
    rpm_range: tuple[float, float] | None = None
    """Range [rpm] for the safe windows (with ``rpm``; overrides the Hz range)."""
    resonance_limit: float = math.sqrt(2.0)
    """Largest acceptable resonance factor R [-] in the crowded regime."""
    min_window: float = 0.02
    """Drop safe windows narrower than this fraction of their centre frequency [-]."""
    mass: str = DEFAULT_MASS
    """Mass-matrix scheme."""
    rel_tol: float = 1e-3
    """Target discretisation error at the top of the range [-]; the mesh is refined to meet it."""
    n_grid: int = 8001
    """Frequency points of the sweep over the range (edges then refined by bisection)."""

    def __post_init__(self) -> None:
        if (self.excitation_hz is None) == (self.rpm is None):
            raise ValueError("give exactly one of excitation_hz or rpm")
        if self.excitation_hz is not None and not self.excitation_hz > 0:
            raise ValueError(f"excitation_hz = {self.excitation_hz!r}: must be > 0 Hz")
        if self.rpm is not None and not self.rpm > 0:
            raise ValueError(f"rpm = {self.rpm!r}: must be > 0 rpm")
        if not self.factor > 0:
            raise ValueError(f"factor = {self.factor!r}: must be > 0")
        if not 0.0 < self.margin < 1.0:
            raise ValueError(f"margin = {self.margin!r}: allowed range 0 < margin < 1")
        if not self.resonance_limit > 0:
            raise ValueError(f"resonance_limit = {self.resonance_limit!r}: must be > 0")
        for name in ("frequency_range_hz", "rpm_range"):
            r = getattr(self, name)
            if r is not None and not (len(r) == 2 and 0 <= r[0] < r[1]):
                raise ValueError(f"{name} = {r!r}: need 0 <= low < high")

    @property
    def frequency_hz(self) -> float:
        """Excitation frequency [Hz]."""
        if self.excitation_hz is not None:
            return float(self.excitation_hz)
        return self.factor * float(self.rpm) / 60.0

    @property
    def range_hz(self) -> tuple[float, float]:
        """Frequency range of the sweep [Hz]."""
        if self.rpm is not None and self.rpm_range is not None:
            return (self.factor * self.rpm_range[0] / 60.0, self.factor * self.rpm_range[1] / 60.0)
        if self.frequency_range_hz is not None:
            return (float(self.frequency_range_hz[0]), float(self.frequency_range_hz[1]))
        return (0.0, 2.0 * self.frequency_hz)


@dataclass(frozen=True)
class ModeRow:
    """One natural frequency seen from the excitation."""

    configuration: str
    """``on_bottom`` or ``off_bottom``."""
    index: int
    """Mode number (1 = lowest elastic mode; 0 = rigid-body mode)."""
    frequency_hz: float
    """Natural frequency [Hz]."""
    separation_pct: float
    """``100 (f_exc - f_n)/f_n`` [%] (positive: excitation above the mode)."""
    in_band: bool
    """``|separation| <= 100 margin``."""
    bit_receptance: float
    """Modulus of the mode's contribution to the bit response at the
    excitation [m/N] (force-driven bit) or [N/m] (fixed, displacement-driven)."""
    share: float
    """Contribution / sum of contributions [-]."""
    rank: int
    """Rank by contribution (1 = largest)."""

    def to_dict(self) -> dict:
        return {"configuration": self.configuration, "index": self.index,
                "frequency_hz": self.frequency_hz, "separation_pct": _finite(self.separation_pct),
                "in_band": self.in_band, "bit_receptance": self.bit_receptance,
                "share": self.share, "rank": self.rank}


@dataclass(frozen=True)
class ConfigurationResult:
    """Check of one end configuration (bit on bottom or off bottom)."""

    name: str
    top: Boundary
    bottom: Boundary
    excitation: str
    """``force`` (bit free/spring) or ``displacement`` (bit fixed)."""
    modes: tuple[ModeRow, ...]
    frequencies_hz: np.ndarray
    """All computed natural frequencies (n,) [Hz] (up to the top of the range)."""
    regime: str
    """``separated`` or ``crowded`` at the excitation."""
    rule: str
    """Rule that decided: ``margin`` or ``receptance``."""
    verdict: str
    """``pass`` or ``fail``."""
    reason: str
    receptance: complex
    """Bit receptance H at the excitation [m/N] (0 for a fixed bit)."""
    dynamic_stiffness: complex | None
    """Bit dynamic stiffness D at the excitation [N/m] (fixed bit only)."""
    static_compliance: float
    """Static bit compliance H(0) [m/N] (fixed bit: static stiffness inverse of the string)."""
    dynamic_amplification: float
    """``|H(f)|/H(0)`` (force) or ``|D(f)|/D(0)`` (displacement) [-]."""
    resonance_factor: float
    """R = max(R_motion, R_force) at the excitation [-]."""
    motion_factor: float
    """Bit-motion ratio ``|H/H_inf|`` at the excitation [-] (fixed bit: ``|D/D_inf|``)."""
    force_factor: float
    """String-force ratio ``|D H| / |D_inf H_inf|`` at the excitation [-] (fixed bit: ``|D/D_inf|``)."""
    nearest: ModeRow | None
    """Mode with the smallest |separation|."""
    dominant: ModeRow | None
    """Mode with the largest contribution at the excitation."""

    def to_dict(self) -> dict:
        return {
            "name": self.name, "top": self.top.spec(), "bottom": self.bottom.spec(),
            "excitation": self.excitation, "regime": self.regime, "rule": self.rule,
            "verdict": self.verdict, "reason": self.reason,
            "receptance_m_per_n": _finite(abs(self.receptance)),
            "receptance_phase_deg": _finite(math.degrees(np.angle(self.receptance)))
            if self.receptance != 0 else None,
            "dynamic_stiffness_n_per_m": None if self.dynamic_stiffness is None
            else _finite(abs(self.dynamic_stiffness)),
            "static_compliance_m_per_n": _finite(self.static_compliance),
            "dynamic_amplification": _finite(self.dynamic_amplification),
            "resonance_factor": _finite(self.resonance_factor),
            "motion_factor": _finite(self.motion_factor),
            "force_factor": _finite(self.force_factor),
            "nearest_mode": None if self.nearest is None else self.nearest.to_dict(),
            "dominant_mode": None if self.dominant is None else self.dominant.to_dict(),
        }


@dataclass(frozen=True)
class CheckResult:
    """Outcome of :func:`check`; :meth:`to_dict` gives the JSON form."""

    string_name: str
    config: CheckConfig
    excitation_hz: float
    verdict: str
    """``pass`` or ``fail`` (fail if any configuration fails)."""
    rule: str
    """Rule(s) that decided: ``margin``, ``receptance`` or ``margin+receptance``
    (for a fail, the rules of the failing configurations only)."""
    reason: str
    configurations: tuple[ConfigurationResult, ...]
    safe_windows_hz: tuple[tuple[float, float], ...]
    """Safe excitation frequency intervals within the range [Hz]."""
    range_hz: tuple[float, float]
    n_elements: int
    sweep_hz: np.ndarray
    """Sweep frequencies (n_grid,) [Hz] (plots)."""
    sweep_receptance: dict[str, np.ndarray]
    """Per configuration: |H| [m/N] (force) or |D| [N/m] (displacement) on the sweep."""
    sweep_reference: dict[str, np.ndarray]
    """Per configuration: reflection-free |H_inf| or |D_inf| on the sweep."""
    sweep_factor: dict[str, np.ndarray]
    """Per configuration: resonance factor R on the sweep."""
    sweep_crowded: dict[str, np.ndarray]
    """Per configuration: True where modes are crowded (receptance rule applies)."""
    sweep_safe: np.ndarray
    """Combined safe flag on the sweep (n_grid,) bool."""

    @property
    def modes(self) -> list[ModeRow]:
        return [m for c in self.configurations for m in c.modes]

    @property
    def safe_windows_rpm(self) -> tuple[tuple[float, float], ...] | None:
        """Safe windows as rotary speeds [rpm] (when the excitation is rpm based)."""
        if self.config.rpm is None:
            return None
        k = 60.0 / self.config.factor
        return tuple((lo * k, hi * k) for lo, hi in self.safe_windows_hz)

    def to_dict(self) -> dict:
        c = self.config
        return {
            "string": self.string_name,
            "verdict": self.verdict,
            "rule": self.rule,
            "reason": self.reason,
            "excitation_hz": self.excitation_hz,
            "rpm": c.rpm,
            "factor": c.factor if c.rpm is not None else None,
            "margin": c.margin,
            "resonance_limit": c.resonance_limit,
            "mass": c.mass,
            "elements": self.n_elements,
            "configurations": [x.to_dict() for x in self.configurations],
            "modes": [m.to_dict() for m in self.modes],
            "frequency_range_hz": list(self.range_hz),
            "safe_windows_hz": [[lo, hi] for lo, hi in self.safe_windows_hz],
            "safe_windows_rpm": None if self.safe_windows_rpm is None
            else [[lo, hi] for lo, hi in self.safe_windows_rpm],
        }


def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


# --------------------------------------------------------------------------
# the check
# --------------------------------------------------------------------------
class _Config:
    """Pre-computed data of one end configuration (internal)."""

    def __init__(self, name: str, string: DrillString, top: Boundary, bottom: Boundary, mass: str,
                 f_top: float):
        self.name = name
        self.string = string
        self.top = top
        self.bottom = Boundary.free() if bottom.kind == "hammer" else bottom
        self.mass = mass
        self.asm = assemble(string, top, self.bottom, mass=mass)
        eig_all = None
        if string.modal_damping_ratio > 0.0:  # the receptance needs every mode anyway
            eig_all = _eigen(self.asm, None, None, all_modes=True)
            lam, phi = eig_all
            keep = min(lam.size, int(np.searchsorted(lam, (2.0 * math.pi * f_top) ** 2, side="right")) + 1)
            lam, phi = lam[:keep], phi[:, :keep]
        else:
            lam, phi = _eigen(self.asm, f_top, None)
            if lam.size < self.asm.n_dof:  # one mode beyond the range closes the last interval
                lam, phi = _eigen(self.asm, None, lam.size + 1)
        self.lam, self.phi = lam, phi
        self.freqs = np.sqrt(lam) / (2.0 * math.pi)
        self.elastic = self.freqs > 1e-9 * max(1.0, float(self.freqs.max(initial=1.0)))
        self.zb = string.sections[-1].impedance
        self.displacement = self.bottom.is_fixed
        cv = self.asm.C_viscous
        self.cdiag = np.einsum("ij,ij->j", phi, cv @ phi) + \
            2.0 * string.modal_damping_ratio * np.sqrt(lam)
        self._resp = (_dynamic_stiffness_evaluator(self.asm, eig_all) if self.displacement
                      else _receptance_evaluator(self.asm, eig_all))

    def response(self, f: np.ndarray) -> np.ndarray:
        """H [m/N] (force) or D [N/m] (displacement) on frequencies f [Hz]."""
        return self._resp(2.0 * math.pi * np.atleast_1d(np.asarray(f, dtype=float)))

    def reference(self, f: np.ndarray) -> np.ndarray:
        return _reference(self.bottom, self.zb, 2.0 * math.pi * np.atleast_1d(np.asarray(f, dtype=float)))

    def factors(self, f: np.ndarray, resp: np.ndarray | None = None):
        """``(R, R_motion, R_force)`` on frequencies f [Hz]."""
        f = np.atleast_1d(np.asarray(f, dtype=float))
        resp = self.response(f) if resp is None else resp
        return _factors(self.bottom, self.zb, 2.0 * math.pi * f, resp)

    def factor(self, f: np.ndarray) -> np.ndarray:
        return self.factors(f)[0]

    def crowded(self, f: np.ndarray, margin: float) -> np.ndarray:
        """True where the modes bracketing f have overlapping bands."""
        fe = self.freqs[self.elastic]
        f = np.asarray(f, dtype=float)
        i = np.searchsorted(fe, f)
        has_both = (i > 0) & (i < fe.size)
        lo = fe[np.clip(i - 1, 0, fe.size - 1)]
        hi = fe[np.clip(i, 0, fe.size - 1)]
        return has_both & (lo * (1.0 + margin) >= hi * (1.0 - margin))

    def in_band(self, f: np.ndarray, margin: float) -> np.ndarray:
        fe = self.freqs[self.elastic]
        f = np.asarray(f, dtype=float)
        return np.any(np.abs(f[..., None] / fe - 1.0) <= margin, axis=-1)

    def safe(self, f: np.ndarray, margin: float, limit: float) -> np.ndarray:
        f = np.asarray(f, dtype=float)
        crowd = self.crowded(f, margin)
        ok = ~self.in_band(f, margin)
        if np.any(crowd):
            ok[crowd] = self.factor(f[crowd]) <= limit
        return ok

    def contributions(self, f: float) -> np.ndarray:
        """|modal contribution| to the bit response at f (n,)."""
        w = 2.0 * math.pi * f
        den = self.lam - w * w + 1j * w * self.cdiag
        if self.displacement:
            b = self.asm.ke_full[-1] - w * w * self.asm.me_full[-1] + 1j * w * self.asm.ce_full[-1]
            num = (b * self.phi[-1]) ** 2
        else:
            num = self.phi[-1] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.abs(num / den)


def check(string: DrillString, config: CheckConfig) -> CheckResult:
    """Run the hammer/bit frequency avoidance check.

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
    f_top = f_hi / (1.0 - m) * 1.05
    fine = string.refined(f_top, config.rel_tol, config.mass)
    top = parse_boundary(fine.top if config.top is None else config.top, where="top")
    ends = {"on_bottom": parse_boundary(fine.on_bottom if config.on_bottom is None else config.on_bottom,
                                        where="on_bottom"),
            "off_bottom": parse_boundary(fine.off_bottom if config.off_bottom is None else config.off_bottom,
                                         where="off_bottom")}
    cfgs = [_Config(name, fine, top, b, config.mass, f_top) for name, b in ends.items()]

    results = [_evaluate(c, fx, config) for c in cfgs]
    failing = [r for r in results if r.verdict == "fail"]
    verdict = "fail" if failing else "pass"
    decisive = failing if failing else results  # a fail is decided by the failing configuration(s)
    rule = "+".join(sorted({r.rule for r in decisive}))
    reason = f"{verdict}: " + "; ".join(f"{r.name}: {r.reason}" for r in decisive)

    # sweep and safe windows
    start = f_lo if f_lo > 0 else f_hi / config.n_grid
    grid = np.linspace(start, f_hi, config.n_grid)
    safe = np.ones(grid.size, dtype=bool)
    for c in cfgs:
        safe &= c.safe(grid, m, config.resonance_limit)

    def safe_at(f: np.ndarray) -> np.ndarray:
        ok = np.ones(np.shape(f), dtype=bool)
        for c in cfgs:
            ok &= c.safe(f, m, config.resonance_limit)
        return ok

    windows = _windows(grid, safe, safe_at, config.min_window, f_lo)
    sweep_h, sweep_ref, sweep_r, sweep_c = {}, {}, {}, {}
    for c in cfgs:
        resp = c.response(grid)
        sweep_h[c.name] = np.abs(resp)
        sweep_ref[c.name] = np.abs(c.reference(grid))
        sweep_r[c.name] = c.factors(grid, resp)[0]
        sweep_c[c.name] = c.crowded(grid, m)
    return CheckResult(string.name, config, fx, verdict, rule, reason, tuple(results), windows,
                       (f_lo, f_hi), fine.n_elements, grid, sweep_h, sweep_ref, sweep_r, sweep_c, safe)


def _evaluate(c: _Config, fx: float, config: CheckConfig) -> ConfigurationResult:
    m = config.margin
    limit = config.resonance_limit
    fe_mask = c.elastic
    contrib = c.contributions(fx)
    total = float(np.sum(contrib[np.isfinite(contrib)])) or 1.0
    order = np.argsort(-np.where(np.isfinite(contrib), contrib, np.inf))
    rank = np.empty(order.size, dtype=int)
    rank[order] = np.arange(1, order.size + 1)
    rows = []
    n_rigid = int(np.sum(~fe_mask))
    list_up_to = max(fx / (1.0 - m), c.freqs[min(3 + n_rigid, c.freqs.size - 1)])
    for j, fn in enumerate(c.freqs):
        if fn > list_up_to * (1 + 1e-12):
            continue
        sep = 100.0 * (fx - fn) / fn if fe_mask[j] else math.inf
        rows.append(ModeRow(c.name, j - n_rigid + 1 if fe_mask[j] else 0, float(fn), sep,
                            bool(fe_mask[j] and abs(sep) <= 100.0 * m), float(contrib[j]),
                            float(contrib[j] / total), int(rank[j])))
    elastic_rows = [r for r in rows if r.index > 0]
    nearest = min(elastic_rows, key=lambda r: abs(r.separation_pct)) if elastic_rows else None
    dominant = min(rows, key=lambda r: r.rank) if rows else None

    resp_arr = c.response(np.array([fx]))
    resp = complex(resp_arr[0])
    rf, r_motion, r_force = (float(x[0]) for x in c.factors(np.array([fx]), resp_arr))
    if c.displacement:
        d0 = abs(complex(c.response(np.array([0.0]))[0]))
        amp = abs(resp) / d0 if d0 > 0 else math.inf
        comp = 1.0 / d0 if d0 > 0 else math.inf
        h, dyn = 0j, resp
    else:
        comp = static_compliance(c.string, c.top, c.bottom)
        amp = abs(resp) / comp if 0 < comp < math.inf else math.inf
        h, dyn = resp, None

    crowded = bool(c.crowded(np.array([fx]), m)[0])
    inband = [r for r in elastic_rows if r.in_band]
    if not crowded:
        rule, regime = "margin", "separated"
        if inband:
            worst = min(inband, key=lambda r: abs(r.separation_pct))
            verdict = "fail"
            reason = (f"margin rule (modes separated): mode {worst.index} at {worst.frequency_hz:.4g} Hz is "
                      f"{worst.separation_pct:+.1f} % from the excitation, inside +-{100 * m:.0f} %")
        else:
            verdict = "pass"
            sep = f"nearest mode {nearest.index} at {nearest.frequency_hz:.4g} Hz is " \
                  f"{nearest.separation_pct:+.1f} % away" if nearest else "no elastic mode"
            reason = f"margin rule (modes separated): {sep}, outside +-{100 * m:.0f} %"
    else:
        rule, regime = "receptance", "crowded"
        verdict = "pass" if rf <= limit else "fail"
        dom = f"; dominant mode {dominant.index} at {dominant.frequency_hz:.4g} Hz " \
              f"({100 * dominant.share:.0f} % of the bit response)" if dominant else ""
        reason = (f"receptance rule ({len(inband)} modes within +-{100 * m:.0f} %, bands overlap): "
                  f"resonance factor {rf:.3g} {'<=' if verdict == 'pass' else '>'} {limit:.3g}{dom}")
    return ConfigurationResult(c.name, c.top, c.bottom, "displacement" if c.displacement else "force",
                               tuple(rows), c.freqs, regime, rule, verdict, reason, h, dyn, comp, amp, rf,
                               r_motion, r_force, nearest, dominant)


def _windows(grid: np.ndarray, safe: np.ndarray, safe_at, min_window: float,
             f_lo: float) -> tuple[tuple[float, float], ...]:
    """Intervals where ``safe`` holds, edges refined by bisection."""
    change = np.nonzero(safe[1:] != safe[:-1])[0]
    a, b = grid[change].copy(), grid[change + 1].copy()
    left_safe = safe[change]
    for _ in range(40):
        mid = 0.5 * (a + b)
        s = safe_at(mid)
        same = s == left_safe
        a = np.where(same, mid, a)
        b = np.where(same, b, mid)
    edges = 0.5 * (a + b)
    out = []
    lo = f_lo if safe[0] else None
    for e, ls in zip(edges, left_safe):
        if ls:
            out.append((lo, float(e)))
            lo = None
        else:
            lo = float(e)
    if lo is not None:
        out.append((lo, float(grid[-1])))
    return tuple((float(x), float(y)) for x, y in out
                 if y - x >= min_window * 0.5 * (x + y) and y > x)


# --------------------------------------------------------------------------
# plots
# --------------------------------------------------------------------------
_COLORS = {"on_bottom": "tab:blue", "off_bottom": "tab:orange"}
_LABELS = {"on_bottom": "bit on bottom", "off_bottom": "bit off bottom"}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_campbell(result: CheckResult, ax=None, path: "str | Path | None" = None,
                  rpm_max: float | None = None):
    """Campbell-type diagram: natural frequencies with their +-margin bands
    (horizontal) against rotary speed, the excitation line(s) ``f = K N/60``
    (or the hammer frequency, with 1x and 3x rotary lines for reference), the
    operating point, and the safe windows.

    Returns the matplotlib Axes.
    """
    plt = _pyplot()
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(7, 5))
    c = result.config
    f_lo, f_hi = result.range_hz
    if rpm_max is None:
        rpm_max = (c.rpm_range[1] if (c.rpm is not None and c.rpm_range) else
                   2.0 * c.rpm if c.rpm is not None else 200.0)
    rpm = np.array([0.0, rpm_max])
    for cfg in result.configurations:
        col = _COLORS.get(cfg.name, "k")
        ls = "-" if cfg.name == "on_bottom" else "--"
        for j, fn in enumerate(cfg.frequencies_hz):
            if fn <= 0 or fn * (1 - c.margin) > f_hi:
                continue
            ax.axhspan(fn * (1 - c.margin), fn * (1 + c.margin), color=col, alpha=0.07, lw=0)
            ax.axhline(fn, color=col, ls=ls, lw=0.8,
                       label=f"{_LABELS.get(cfg.name, cfg.name)} modes (+-{100 * c.margin:.0f} %)"
                       if j == int(np.argmax(cfg.frequencies_hz > 0)) else None)
    if c.rpm is not None:
        ax.plot(rpm, rpm / 60.0, color="0.4", lw=1, ls=":", label="1x rpm")
        ax.plot(rpm, c.factor * rpm / 60.0, color="k", lw=1.5, label=f"{c.factor:g}x rpm (excitation)")
        for lo, hi in result.safe_windows_rpm or ():
            ax.plot([lo, min(hi, rpm_max)], [c.factor * lo / 60.0, c.factor * min(hi, rpm_max) / 60.0],
                    color="tab:green", lw=5, alpha=0.6, solid_capstyle="butt")
        ax.plot([c.rpm], [result.excitation_hz], "o", ms=8,
                color="tab:red" if result.verdict == "fail" else "tab:green",
                label=f"operating point: {result.verdict}")
        ax.plot([], [], color="tab:green", lw=5, alpha=0.6, label="safe speed windows")
    else:
        for k, ls in ((1.0, ":"), (3.0, "-.")):
            ax.plot(rpm, k * rpm / 60.0, color="0.5", lw=0.8, ls=ls, label=f"{k:g}x rpm (bit, reference)")
        ax.axhline(result.excitation_hz, color="tab:red" if result.verdict == "fail" else "k", lw=1.8,
                   label=f"hammer {result.excitation_hz:g} Hz: {result.verdict}")
        for lo, hi in result.safe_windows_hz:
            ax.axhspan(lo, hi, xmin=0.96, xmax=1.0, color="tab:green", alpha=0.8, lw=0)
        ax.plot([], [], color="tab:green", lw=5, label="safe frequency windows (right edge)")
    ax.set_xlim(0, rpm_max)
    ax.set_ylim(0, f_hi)
    ax.set_xlabel("rotary speed [rpm]")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title(f"{result.string_name}: axial modes vs excitation")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    if own and path is not None:
        ax.figure.tight_layout()
        ax.figure.savefig(path, dpi=120)
        plt.close(ax.figure)
    return ax


def plot_receptance(result: CheckResult, axes: Sequence | None = None, path: "str | Path | None" = None):
    """Bit receptance ``|H(f)|`` (log scale, with the reflection-free
    reference) and the resonance factor ``R(f)`` with its limit (bold where
    modes are crowded and the receptance rule applies, faint where the margin
    rule decides); excitation marked, safe windows shaded.  Returns the two
    Axes."""
    plt = _pyplot()
    own = axes is None
    if own:
        fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    ax1, ax2 = axes
    f = result.sweep_hz
    c = result.config
    for cfg in result.configurations:
        col = _COLORS.get(cfg.name, "k")
        h = result.sweep_receptance[cfg.name]
        ref = result.sweep_reference[cfg.name]
        lab = _LABELS.get(cfg.name, cfg.name)
        if cfg.excitation == "force":
            ax1.semilogy(f, h, color=col, lw=1, label=f"|H| {lab}")
            ax1.semilogy(f, ref, color=col, lw=0.8, ls=":", label=f"reflection-free {lab}")
        else:
            ax1.semilogy(f, 1.0 / h, color=col, lw=1, label=f"1/|D| {lab} (fixed bit)")
        r = result.sweep_factor[cfg.name]
        crowd = result.sweep_crowded[cfg.name]
        ax2.semilogy(f, r, color=col, lw=0.6, alpha=0.35,
                     label=f"{lab} (faint: modes separated, margin rule decides)")
        if np.any(crowd):
            ax2.semilogy(f, np.where(crowd, r, np.nan), color=col, lw=1.2,
                         label=f"{lab} (bold: modes crowded, receptance rule)")
    ax2.axhline(c.resonance_limit, color="tab:red", lw=1, ls="--", label=f"limit {c.resonance_limit:.3g}")
    for ax in (ax1, ax2):
        for lo, hi in result.safe_windows_hz:
            ax.axvspan(lo, hi, color="tab:green", alpha=0.12, lw=0)
        ax.axvline(result.excitation_hz, color="k", lw=1.2)
    ax1.set_ylabel("bit receptance [m/N]")
    ax2.set_ylabel("resonance factor R [-]")
    ax2.set_xlabel("excitation frequency [Hz]")
    ax1.set_title(f"{result.string_name}: excitation {result.excitation_hz:.4g} Hz -> {result.verdict} "
                  f"({result.rule} rule); green = safe windows")
    ax1.legend(fontsize=7, loc="upper right")
    ax2.legend(fontsize=7, loc="upper right")
    ax2.set_xlim(f[0], f[-1])
    if own and path is not None:
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
    return axes


def plot_check(result: CheckResult, path: "str | Path", rpm_max: float | None = None) -> Path:
    """Campbell diagram and receptance plots side by side, saved to ``path`` (PNG/PDF/SVG)."""
    plt = _pyplot()
    fig = plt.figure(figsize=(13, 5.5))
    gs = fig.add_gridspec(2, 2, width_ratios=(1, 1.15))
    ax_c = fig.add_subplot(gs[:, 0])
    ax_h = fig.add_subplot(gs[0, 1])
    ax_r = fig.add_subplot(gs[1, 1], sharex=ax_h)
    plot_campbell(result, ax=ax_c, rpm_max=rpm_max)
    plot_receptance(result, axes=(ax_h, ax_r))
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


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
    from .drillstring import assemble
    for name, v in (("interface_stiffness", interface_stiffness), ("hammer_mass", hammer_mass),
                    ("hammer_stiffness", hammer_stiffness)):
        _check_number("hammer boundary", name, v, 0.0, None, lo_open=True)
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
    from .drillstring import parse_boundary
    topb = parse_boundary(string.top if top is None else top)

    def g(w):
        w = np.atleast_1d(np.asarray(w, dtype=float))
        if topb.is_fixed:
            u, nn = np.zeros_like(w), np.ones_like(w)
        else:
            u, nn = np.ones_like(w), topb.ground_stiffness - topb.mass * w ** 2
        for sec in string.sections:
            a = w * sec.length / sec.wave_speed
            zw = sec.impedance * w
            ca, sa = np.cos(a), np.sin(a)
            sz = np.where(zw > 0, sa / np.where(zw > 0, zw, 1.0), sec.length / sec.axial_stiffness)
            u, nn = ca * u + sz * nn, -zw * sa * u + ca * nn
        # bottom: N = -k_b(w) u with k_b the interface in series with the hammer on K
        return ki * (K - m1 * w ** 2) * u + (ki + K - m1 * w ** 2) * nn

    wmax = 2.0 * math.pi * f_max
    grid = np.linspace(1e-6, wmax, points)
    val = g(grid)
    roots = [brentq(lambda x: float(g(x)[0]), grid[i], grid[i + 1], xtol=1e-12, rtol=1e-14)
             for i in np.nonzero(np.sign(val[:-1]) * np.sign(val[1:]) < 0)[0]]
    return np.array(roots) / (2.0 * math.pi)
