"""Coupling error of a co-simulation: what a macro step can resolve, and how wrong a run is.

Two questions a co-simulation engineer asks of every run, answered here:

* **Can this macro step work at all?**  :func:`step_limits` lists the time
  scales the exchange must sample: the forcing period, the slip dynamics (the
  hammer–bit mode while the bit slips, which the interface sees during every
  slip) and the highest mode of the string that takes part in the exchange.
  :func:`check_step` refuses a step above half the shortest of them (the
  sampling limit: two communication points per period), naming the time scale
  and the largest step that resolves it, before the run starts.

* **How far is the answer from the coupled system's?**  A posteriori, by
  step doubling (Richardson extrapolation): the master runs a *companion*
  co-simulation that takes two half steps for every macro step of the run, in
  lock step.  If the coupling error of a quantity ``Q`` behaves as
  ``C H^p``, then ``Q_H - Q_{H/2} = C H^p (1 - 2^-p)`` and the error of the
  run is ``Q_H - Q_true ~ (Q_H - Q_{H/2}) 2^p / (2^p - 1)``.  The order ``p``
  is measured on the run itself, each macro step: the interface force defect
  ``F_held - mean F_i`` (the force the hammer held against the force the
  string transmitted over the step) of the run and of the companion give
  ``p = log2(rms defect_H / rms defect_{H/2})``, clipped to ``[1, 3]``.
  :func:`richardson` turns the two runs' WOB amplitudes and penetrations into
  :class:`CouplingErrorEstimate`.

  The coupling error of the WOB's first harmonic is mostly a phase lag (the
  exchange holds the force over a step), and step doubling estimates the
  harmonic's error ``|c_H - c_true|`` well.  The amplitude's error is only the
  part of it along ``c``: where that part is a small fraction of the whole
  (under ``1 / PHASE_DOMINATED``), its two-step estimate is the difference of
  two nearly equal errors and can miss by more than 3x either way (measured:
  0.18 to 5.3).  Two rules follow.  A run meets ``tol`` only when the
  harmonic's error does too (the amplitude's error is at most the harmonic's,
  so exit 0 stays sound; the adaptive run tightens its steps until it does).
  And a run whose harmonic misses the claim while its error is phase-dominated
  claims no estimate (:func:`phase_dominated`): step doubling cannot tell how
  far its amplitude is off.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np

__all__ = ["StepResolutionError", "StepLimit", "step_limits", "check_step", "CouplingErrorEstimate",
           "richardson", "measured_order", "ORDER_RANGE", "SAFETY_FACTOR", "unclaimed", "phase_dominated",
           "PHASE_DOMINATED"]

#: A run meets ``tol`` when its estimate is within ``tol / SAFETY_FACTOR``: the estimate is held to
#: a factor of 3 of the true error (it has been found up to 1.8 times optimistic), and exit 0 must
#: mean a true error within ``tol``.
SAFETY_FACTOR = 3.0
#: The harmonic's error is phase-dominated when it is above this many times the amplitude's: the part
#: along the harmonic is then under a fifth of the whole (within 11.5 degrees of a pure phase lag), and
#: step doubling cannot estimate it to a factor of 3.
PHASE_DOMINATED = 5.0
#: Range the measured order is clipped to (a defect ratio outside it is noise, not an order).
ORDER_RANGE = (1.0, 3.0)


class StepResolutionError(ValueError):
    """The macro step cannot resolve a time scale of the coupled system.

    Attributes
    ----------
    step : float
        The macro step [s].
    limit : StepLimit
        The time scale it cannot resolve.
    """

    def __init__(self, message: str, *, step: float, limit: "StepLimit"):
        self.step = step
        self.limit = limit
        super().__init__(message)


@dataclass(frozen=True)
class StepLimit:
    """One time scale the macro step must resolve.

    Attributes
    ----------
    name : str
        ``forcing``, ``slip`` or ``string``.
    frequency_hz : float
        Its frequency [Hz].
    max_step_s : float
        Largest macro step that resolves it, half its period [s].
    description : str
        What it is, for people.
    """

    name: str
    frequency_hz: float
    max_step_s: float
    description: str


def step_limits(side, config) -> list:
    """The time scales a macro step must resolve (:class:`StepLimit`, shortest first).

    Parameters
    ----------
    side : hammerbit.cosim.string_side.StringSide
        The string side of the run (its modes and interface).
    config : hammerbit.cosim.config.CosimConfig

    Notes
    -----
    * ``forcing``: the harmonic force at ``rig.frequency``.
    * ``slip``: while the bit slips, hammer and bit oscillate on the hammer
      spring at ``sqrt(K (1/m1 + 1/m2)) / 2 pi``; every slip excites it and the
      interface force carries it.
    * ``string``: the highest string mode the exchange sees.  The string
      itself is stepped exactly (any mode, any step), so the limit is the
      highest mode of the string side (string + interface, hammer held) that
      carries at least 1e-3 of the interface's static compliance
      (:meth:`StringSide.exchange_frequency`); with ``f_max`` only the
      retained modes count.
    """
    rig = config.rig
    out = []
    if rig.amplitude != 0.0 and rig.frequency > 0.0:
        out.append(StepLimit("forcing", float(rig.frequency), 0.5 / rig.frequency,
                             f"the forcing period ({rig.frequency:g} Hz)"))
    m1, m2, K = rig.hammer_mass, rig.bit_mass, rig.stiffness
    f_slip = math.sqrt(K * (1.0 / m1 + 1.0 / m2)) / (2.0 * math.pi)
    out.append(StepLimit("slip", f_slip, 0.5 / f_slip,
                         f"the slip dynamics (hammer-bit mode while the bit slips, {f_slip:.4g} Hz)"))
    f_str = side.exchange_frequency()
    if f_str > 0.0:
        out.append(StepLimit("string", f_str, 0.5 / f_str,
                             f"the highest string mode in the exchange ({f_str:.4g} Hz)"))
    return sorted(out, key=lambda s: s.max_step_s)


def check_step(side, config, step: Optional[float] = None) -> None:
    """Raise :class:`StepResolutionError` if ``step`` (default ``config.step``) is above
    half the period of a time scale of :func:`step_limits`."""
    H = config.step if step is None else step
    for lim in step_limits(side, config):
        if H > lim.max_step_s * (1.0 + 1e-12):
            raise StepResolutionError(
                f"macro step {H:g} s cannot resolve {lim.description}: at most {lim.max_step_s:.4g} s "
                f"(two communication points per period); choose a smaller step",
                step=H, limit=lim)


def measured_order(defect_coarse: np.ndarray, defect_fine: np.ndarray, *, fallback: float = 2.0) -> float:
    """Order p of the coupling error from the force defects of a run (step H) and its
    companion (step H/2): ``log2(rms_H / rms_{H/2})``, clipped to :data:`ORDER_RANGE`."""
    a = float(np.sqrt(np.mean(np.square(defect_coarse)))) if len(defect_coarse) else 0.0
    b = float(np.sqrt(np.mean(np.square(defect_fine)))) if len(defect_fine) else 0.0
    if not (a > 0.0 and b > 0.0 and math.isfinite(a) and math.isfinite(b)):
        return fallback
    return float(min(max(math.log2(a / b), ORDER_RANGE[0]), ORDER_RANGE[1]))


@dataclass(frozen=True)
class CouplingErrorEstimate:
    """A posteriori estimate of a run's coupling error (step doubling, measured order).

    Attributes
    ----------
    order : float
        Measured order p of the coupling error (:func:`measured_order`).
    factor : float
        ``2^p / (2^p - 1)``: the run's error is this times its difference to the companion.
    wob_amplitude_rel : float
        Estimated relative error of the dynamic WOB amplitude over the steady window [-].
    wob_amplitude_n : float
        The same in newtons [N].
    penetration_rel : float
        Estimated relative error of the penetration [-] (relative to
        ``max(|penetration|, penetration_floor_m)``).
    penetration_m : float
        Estimated error of the penetration [m].
    penetration_floor_m : float
        Smallest penetration the relative error is taken against [m] (1 % of the
        rig's length scale x0: below it the bit has not drilled).
    tol : float
        Tolerance the estimate is held against [-].
    meets_tolerance : bool
        Both relative estimates are at most ``tol / SAFETY_FACTOR``.
    """

    order: float
    factor: float
    wob_amplitude_rel: float
    wob_amplitude_n: float
    penetration_rel: float
    penetration_m: float
    penetration_floor_m: float
    tol: float
    meets_tolerance: bool
    claimed: bool = True
    """False when the estimate is not trusted for this run (impacts: the gap's contact
    spikes are not resolved by step doubling); ``meets_tolerance`` is then False too."""
    note: str = ""
    """Why the estimate is not claimed (empty when it is)."""
    wob_harmonic_rel: float = 0.0
    """Estimated relative error of the WOB's first harmonic as a phasor (amplitude and phase) [-]:
    at least the amplitude's (``meets_tolerance`` requires both)."""

    @property
    def worst(self) -> float:
        """The largest relative estimate (harmonic, amplitude, penetration) [-]."""
        return max(self.wob_harmonic_rel, self.wob_amplitude_rel, self.penetration_rel)

    def to_dict(self) -> dict:
        return asdict(self)

    def text(self) -> str:
        """One line for people (SI)."""
        if not self.claimed:
            return f"coupling error not claimed: {self.note}"
        return (f"estimated coupling error: WOB amplitude {self.wob_amplitude_rel:.2e} "
                f"({self.wob_amplitude_n:.4g} N), penetration {self.penetration_rel:.2e} "
                f"({self.penetration_m * 1e3:.4g} mm); tolerance {self.tol:g}, measured order "
                f"{self.order:.2f}")


def richardson(*, amplitude: float, amplitude_fine: float, penetration: float, penetration_fine: float,
               order: float, tol: float, length_scale: float, harmonic: complex = complex(math.nan),
               harmonic_fine: complex = complex(math.nan)) -> CouplingErrorEstimate:
    """The estimate of a run from itself and its half-step companion.

    Parameters
    ----------
    amplitude, amplitude_fine : float
        Dynamic WOB amplitude of the run and of the companion [N].
    penetration, penetration_fine : float
        Penetration of the run and of the companion [m].
    order : float
        Order p of the coupling error.
    tol : float
        Relative tolerance [-].
    length_scale : float
        The rig's x0 [m] (sets the penetration floor, 1 % of it).
    harmonic, harmonic_fine : complex
        First harmonic of the WOB of the run and of the companion, ``a + i b`` [N] (NaN: none;
        the harmonic's estimate is then the amplitude's).
    """
    k = 2.0 ** order / (2.0 ** order - 1.0)
    e_amp = k * abs(amplitude - amplitude_fine)
    e_pen = k * abs(penetration - penetration_fine)
    floor = 1e-2 * length_scale
    rel_amp = e_amp / max(abs(amplitude_fine), 1e-300) if e_amp > 0 else 0.0
    rel_pen = e_pen / max(abs(penetration_fine), floor)
    e_har = k * abs(harmonic - harmonic_fine)
    rel_har = e_har / max(abs(harmonic_fine), 1e-300) if e_har > 0 else 0.0
    if not math.isfinite(rel_har):
        rel_har = rel_amp
    rel_har = max(rel_har, rel_amp)
    if not (math.isfinite(rel_amp) and math.isfinite(rel_pen)):
        rel_amp = rel_pen = rel_har = math.inf
    claim = tol / SAFETY_FACTOR
    return CouplingErrorEstimate(order=float(order), factor=float(k), wob_amplitude_rel=float(rel_amp),
                                 wob_amplitude_n=float(e_amp), penetration_rel=float(rel_pen),
                                 penetration_m=float(e_pen), penetration_floor_m=float(floor), tol=float(tol),
                                 meets_tolerance=bool(rel_har <= claim and rel_pen <= claim),
                                 wob_harmonic_rel=float(rel_har))


def phase_dominated(est: CouplingErrorEstimate) -> str:
    """Why ``est`` cannot be claimed for the amplitude (empty when it can): the harmonic's estimated
    error misses the claim and is over :data:`PHASE_DOMINATED` times the amplitude's."""
    if not est.claimed or est.meets_tolerance or not math.isfinite(est.wob_harmonic_rel):
        return ""
    if est.wob_harmonic_rel <= est.tol / SAFETY_FACTOR or est.wob_harmonic_rel <= PHASE_DOMINATED * est.wob_amplitude_rel:
        return ""
    return (f"the WOB's first harmonic is off by about {est.wob_harmonic_rel:.2e} (relative), mostly in phase: "
            f"its effect on the amplitude ({est.wob_amplitude_rel:.2e} by step doubling) is below what two step "
            f"sizes can resolve; halve the step or run adaptively")


def unclaimed(est: CouplingErrorEstimate, note: str) -> CouplingErrorEstimate:
    """``est`` marked as not claimed (``meets_tolerance`` False), with the reason."""
    from dataclasses import replace
    return replace(est, claimed=False, meets_tolerance=False, note=note)
