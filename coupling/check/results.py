"""The data of a hammer-frequency check: its configuration and its results.

:class:`CheckConfig` holds the inputs (excitation, margin, damping range,
ranges, accuracy target); :class:`CheckResult` the verdict, the per
configuration results (:class:`ConfigurationResult` with :class:`ModeRow`
lines) and the labelled safe windows (:class:`Window`).  The rule itself is
in :mod:`hammerbit.check.frequency`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hammerbit.drillstring import DEFAULT_MASS, DEFAULT_RTOL, Boundary
from hammerbit.model.validation import ParameterError, check as _check_value

__all__ = ["FAIL", "MARGIN", "RECEPTANCE", "NOMINAL_ONLY", "LABELS", "CheckConfig", "ModeRow",
           "ConfigurationResult", "Window", "CheckResult"]

#: Window / point labels: 0 fail, 1 cleared by the margin rule, 2 cleared by
#: the receptance rule over the whole damping range, 3 by the receptance rule
#: at nominal damping only.
FAIL, MARGIN, RECEPTANCE, NOMINAL_ONLY = 0, 1, 2, 3
LABELS = {FAIL: "fail", MARGIN: "margin", RECEPTANCE: "receptance",
          NOMINAL_ONLY: "receptance (nominal damping only)"}


# --------------------------------------------------------------------------
# configuration
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class CheckConfig:
    """Inputs of the avoidance check (frequencies in Hz, speeds in rpm)."""

    excitation_hz: float | None = None
    """Hammer (or any) excitation frequency [Hz]; exclusive with ``rpm``."""
    rpm: float | None = None
    """Rotary speed [rev/min]; the excitation is ``factor * rpm / 60`` Hz."""
    factor: float = 1.0
    """Excitation multiplier [-]: 3 for a tricone bit, the blade count for a PDC bit."""
    margin: float = 0.15
    """Half-width of the band around each natural frequency [-] (0.15 = +-15 %)."""
    top: Boundary | str | None = None
    """Top boundary (default ``string.top``, normally the fixed hook)."""
    on_bottom: Boundary | str | None = None
    """Bit-on-bottom boundary (default ``string.on_bottom``; the bit mass applies)."""
    off_bottom: Boundary | str | None = None
    """Bit-off-bottom boundary (default ``string.off_bottom``; the bit mass applies)."""
    frequency_range_hz: tuple[float, float] | None = None
    """Range [Hz] for the safe windows and plots (default 0 .. 2 f)."""
    rpm_range: tuple[float, float] | None = None
    """Range [rpm] for the safe windows (with ``rpm``; overrides the Hz range)."""
    resonance_limit: float = math.sqrt(2.0)
    """Largest acceptable resonance factor R [-] where only crowded modes are in band."""
    damping_range: tuple[float, float] = (0.5, 2.0)
    """Low and high factor on the string's damping [-] (the nominal is 1)."""
    min_window: float = 0.02
    """Drop safe runs narrower than this fraction of their centre frequency [-]."""
    mass: str = DEFAULT_MASS
    """Mass-matrix scheme."""
    rtol: float = DEFAULT_RTOL
    """Target relative accuracy of the natural frequencies whose bands touch the range [-]."""
    n_grid: int | None = None
    """Frequency points of the sweep (default: 40 per mean mode spacing, at least 2001)."""

    def __post_init__(self) -> None:
        if (self.excitation_hz is None) == (self.rpm is None):
            raise ValueError("give exactly one of excitation_hz or rpm")
        if self.excitation_hz is not None:
            _check_value("check.frequency", self.excitation_hz, label="excitation_hz")
        if self.rpm is not None:
            _check_value("check.rpm", self.rpm, label="rpm")
        _check_value("check.factor", self.factor, label="factor")
        _check_value("check.margin", self.margin, label="margin")
        _check_value("check.resonance_limit", self.resonance_limit, label="resonance_limit")
        _check_value("check.min_window", self.min_window, label="min_window")
        _check_value("check.rtol", self.rtol, label="rtol")
        lo, hi = self.damping_range
        _check_value("check.damping_factor", lo, label="damping_range low")
        _check_value("check.damping_factor", hi, label="damping_range high")
        if not lo <= 1.0 <= hi:
            raise ParameterError("damping_range", self.damping_range, "low <= 1 <= high (factors on the nominal)")
        if self.n_grid is not None:
            _check_value("check.n_grid", self.n_grid, label="n_grid")
        for name in ("frequency_range_hz", "rpm_range"):
            r = getattr(self, name)
            if r is not None:
                if len(r) != 2:
                    raise ParameterError(name, r, "two values LO HI")
                _check_value("check.range", r[0], label=f"{name} low")
                _check_value("check.range", r[1], label=f"{name} high")
                if not r[0] < r[1]:
                    raise ParameterError(name, r, "LO < HI")

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

    @property
    def damping_factors(self) -> tuple[float, float, float]:
        """(low, nominal, high) factors on the string's damping."""
        return (float(self.damping_range[0]), 1.0, float(self.damping_range[1]))


# --------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------
def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


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
    isolated: bool
    """The band touches neither neighbour's band (margin rule applies inside it)."""
    bit_receptance: float
    """Modulus of the mode's contribution to the bit response at the
    excitation [m/N] (force-driven bit) or [N/m] (fixed, displacement-driven)."""
    share: float
    """Contribution / sum of contributions [-]."""
    rank: int
    """Rank by contribution (1 = largest)."""
    error_estimate: float | None = None
    """Estimated relative error of the frequency [-]."""

    def to_dict(self) -> dict:
        return {"configuration": self.configuration, "index": self.index,
                "frequency_hz": self.frequency_hz, "separation_pct": _finite(self.separation_pct),
                "in_band": self.in_band, "isolated": self.isolated, "bit_receptance": _finite(self.bit_receptance),
                "share": _finite(self.share), "rank": self.rank, "error_estimate": self.error_estimate}


@dataclass(frozen=True)
class ConfigurationResult:
    """Check of one end configuration (bit on bottom or off bottom) at the excitation."""

    name: str
    top: Boundary
    bottom: Boundary
    excitation: str
    """``force`` (bit free/spring) or ``displacement`` (bit fixed)."""
    modes: tuple[ModeRow, ...]
    frequencies_hz: np.ndarray
    """Computed natural frequencies (n,) [Hz] (bands touching the range, one more)."""
    regime: str
    """``isolated`` (in the band of an isolated mode), ``crowded`` (in bands of
    crowded modes only) or ``clear`` (in no band)."""
    rule: str
    """Rule that decided: ``margin`` or ``receptance``."""
    verdict: str
    """``pass`` or ``fail`` at nominal damping."""
    robust: bool
    """The verdict is ``pass`` at every damping of the range."""
    reason: str
    receptance: complex
    """Bit receptance H at the excitation, nominal damping [m/N] (0 for a fixed bit)."""
    dynamic_stiffness: complex | None
    """Bit dynamic stiffness D at the excitation [N/m] (fixed bit only)."""
    static_compliance: float
    """Static bit compliance [m/N] (fixed bit: inverse static stiffness)."""
    dynamic_amplification: float
    """``|H(f)|/H(0)`` (force) or ``|D(f)|/D(0)`` (displacement) [-]."""
    resonance_factor: float
    """R at the excitation, nominal damping [-]."""
    motion_factor: float
    """``|H/H_inf|`` at the excitation [-] (fixed bit: ``|D/D_inf|``)."""
    force_factor: float
    """``|1 - Z_bc H| / |1 - Z_bc H_inf|`` [-] (fixed bit: ``|D/D_inf|``)."""
    resonance_factor_by_damping: tuple[float, float, float]
    """R at the (low, nominal, high) damping [-]."""
    verdict_by_damping: tuple[str, str, str]
    """Verdict at the (low, nominal, high) damping."""
    nearest: ModeRow | None
    """Elastic mode with the smallest |separation|."""
    dominant: ModeRow | None
    """Mode with the largest contribution at the excitation."""
    n_elements: int = 0
    """Elements of the mesh the modes come from."""
    max_error_estimate: float | None = None
    """Largest estimated relative error of the natural frequencies in range [-]."""

    def to_dict(self) -> dict:
        return {
            "name": self.name, "top": self.top.spec(), "bottom": self.bottom.spec(),
            "excitation": self.excitation, "regime": self.regime, "rule": self.rule,
            "verdict": self.verdict, "robust": self.robust, "reason": self.reason,
            "receptance_m_per_n": _finite(abs(self.receptance)),
            "dynamic_stiffness_n_per_m": None if self.dynamic_stiffness is None
            else _finite(abs(self.dynamic_stiffness)),
            "static_compliance_m_per_n": _finite(self.static_compliance),
            "dynamic_amplification": _finite(self.dynamic_amplification),
            "resonance_factor": _finite(self.resonance_factor),
            "motion_factor": _finite(self.motion_factor),
            "force_factor": _finite(self.force_factor),
            "resonance_factor_by_damping": [_finite(x) for x in self.resonance_factor_by_damping],
            "verdict_by_damping": list(self.verdict_by_damping),
            "nearest_mode": None if self.nearest is None else self.nearest.to_dict(),
            "dominant_mode": None if self.dominant is None else self.dominant.to_dict(),
            "elements": self.n_elements,
            "max_error_estimate": self.max_error_estimate,
        }


@dataclass(frozen=True)
class Window:
    """A safe frequency interval and what cleared it."""

    lo_hz: float
    hi_hz: float
    rule: str
    """``margin`` or ``receptance``."""
    robust: bool
    """Clear over the whole damping range (always True for ``margin``)."""
    damping_ratio_range: tuple[float, float] | None
    """Damping ratios [-] over which the window is clear (receptance rule);
    None for the margin rule, which does not depend on damping."""

    @property
    def label(self) -> str:
        if self.rule == "margin":
            return "margin"
        return "receptance" if self.robust else "receptance (nominal damping only)"

    def to_dict(self) -> dict:
        return {"lo_hz": self.lo_hz, "hi_hz": self.hi_hz, "rule": self.rule, "robust": self.robust,
                "label": self.label,
                "damping_ratio_range": None if self.damping_ratio_range is None
                else list(self.damping_ratio_range)}


@dataclass(frozen=True)
class CheckResult:
    """Outcome of :func:`check`; :meth:`to_dict` gives the JSON form."""

    string_name: str
    config: CheckConfig
    excitation_hz: float
    verdict: str
    """``pass`` or ``fail`` at nominal damping (fail if any configuration fails)."""
    robust: bool
    """``pass`` at every damping of the range (False for a fail)."""
    rule: str
    """Rule(s) that decided: ``margin``, ``receptance`` or ``margin+receptance``
    (for a fail, the rules of the failing configurations only)."""
    reason: str
    configurations: tuple[ConfigurationResult, ...]
    windows: tuple[Window, ...]
    """Safe windows within the range, each with its rule and damping range."""
    range_hz: tuple[float, float]
    n_elements: int
    damping_ratio_range: tuple[float, float, float]
    """(low, nominal, high) damping ratios [-] assumed (loss factor / 2)."""
    sweep_hz: np.ndarray
    """Sweep frequencies (n_grid,) [Hz] (plots)."""
    sweep_receptance: dict[str, np.ndarray]
    """Per configuration: |H| [m/N] (force) or |D| [N/m] (displacement), nominal damping."""
    sweep_reference: dict[str, np.ndarray]
    """Per configuration: reflection-free |H_inf| or |D_inf|."""
    sweep_factor: dict[str, np.ndarray]
    """Per configuration: R (3, n_grid) at the (low, nominal, high) damping."""
    sweep_crowded: dict[str, np.ndarray]
    """Per configuration: True where the receptance rule applies."""
    sweep_label: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    """Combined label on the sweep (n_grid,): see :data:`LABELS`."""
    _evaluator: Any = None

    @property
    def verdict_label(self) -> str:
        """``robust pass``, ``pass at nominal damping only`` or ``fail``."""
        if self.verdict == "fail":
            return "fail"
        return "robust pass" if self.robust else "pass at nominal damping only"

    @property
    def safe_windows_hz(self) -> tuple[tuple[float, float], ...]:
        """Safe intervals at nominal damping [Hz] (touching windows merged)."""
        out: list[list[float]] = []
        for w in self.windows:
            if out and abs(out[-1][1] - w.lo_hz) <= 1e-12 * max(1.0, w.lo_hz):
                out[-1][1] = w.hi_hz
            else:
                out.append([w.lo_hz, w.hi_hz])
        return tuple((a, b) for a, b in out)

    @property
    def sweep_safe(self) -> np.ndarray:
        return self.sweep_label != FAIL

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

    def label_at(self, freqs_hz: Any) -> np.ndarray:
        """Combined label (:data:`LABELS`) at arbitrary frequencies [Hz] (F,) int."""
        return self._evaluator.label(np.atleast_1d(np.asarray(freqs_hz, dtype=float)))[0]

    def to_dict(self) -> dict:
        c = self.config
        return {
            "string": self.string_name,
            "verdict": self.verdict,
            "robust": self.robust,
            "verdict_label": self.verdict_label,
            "rule": self.rule,
            "reason": self.reason,
            "excitation_hz": self.excitation_hz,
            "rpm": c.rpm,
            "factor": c.factor if c.rpm is not None else None,
            "margin": c.margin,
            "resonance_limit": c.resonance_limit,
            "damping_factors": list(c.damping_factors),
            "damping_ratio_range": list(self.damping_ratio_range),
            "mass": c.mass,
            "rtol": c.rtol,
            "elements": self.n_elements,
            "configurations": [x.to_dict() for x in self.configurations],
            "modes": [m.to_dict() for m in self.modes],
            "frequency_range_hz": list(self.range_hz),
            "windows": [w.to_dict() for w in self.windows],
            "safe_windows_hz": [[lo, hi] for lo, hi in self.safe_windows_hz],
            "safe_windows_rpm": None if self.safe_windows_rpm is None
            else [[lo, hi] for lo, hi in self.safe_windows_rpm],
        }
