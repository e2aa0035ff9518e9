"""Options and results of a co-simulation run: :class:`CosimConfig`, :class:`CosimResult`.

Also the regime verdict of a run (:func:`cosim_regime`, :func:`capacity_warning`), the field hammer
(:func:`field_hammer`), the recordable variables
(:data:`RECORDABLE`) and :class:`CouplingInstabilityError`.  All re-exported by
:mod:`hammerbit.cosim.master`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from hammerbit.model.params import RigParameters
from hammerbit.model.regime import STALL_PERIODS, STALL_WOB_FRACTION, friction_floor, sliding_capacity
from hammerbit.model.regime_codes import REGIME_BITS, REGIME_BOUNCE, regime_json
from hammerbit.model.presets import RIG
from hammerbit.model.scales import Scales
from hammerbit.model.validation import check as _check

from hammerbit.cosim.error import CouplingErrorEstimate
from hammerbit.drillstring.top import TopCondition

__all__ = ["SCHEMES", "EXCHANGES", "HAMMER_INPUTS", "RECORDABLE", "CouplingInstabilityError", "field_hammer",
           "default_hammer", "CosimConfig", "CosimResult", "steady_start", "event_counts", "record_dtype",
           "capacity_warning", "cosim_regime", "cosim_warnings", "COSIM_SETTLE_TOL"]

SCHEMES = ("jacobi", "gauss-seidel")
#: How the string side computes the interface force at a communication point (``CosimConfig.exchange``).
EXCHANGES = ("master", "fmi")
#: Where an FMU hammer gets the held interface force (``CosimConfig.hammer_input``).
HAMMER_INPUTS = ("preload", "harmonic_force")

#: Variables a run can record (all SI), in output order after ``time``.
RECORDABLE = {
    "wob": "weight on bit: drive of the hammer assembly on the bit K(x_h-x_b)+C(v_h-v_b)+F_c [N]",
    "interface_force": "force of the string (interface spring-dashpot) on the hammer [N]",
    "hammer_force": "force held on the hammer's preload input over the step [N]",
    "hammer_position": "hammer position [m] (downward)",
    "hammer_velocity": "hammer velocity [m/s]",
    "bit_position": "bit position = penetration [m]",
    "bit_velocity": "bit velocity [m/s]",
    "stick": "1 while the bit sticks to the rock, 0 while it slips [-]",
    "contact": "1 while the hammer is in contact with the bit (gap closed), else 0 [-]",
    "string_bit_displacement": "displacement of the string's bottom node from equilibrium [m]",
    "string_bit_velocity": "velocity of the string's bottom node [m/s]",
    "hook_load": "hook load [N]: static hook load plus the dynamic tension of the top element",
    "energy_residual": "coupling energy residual of the step (power-bond residual x H) [J]",
    "step_size": "macro step that ended at this time [s]",
    "force_defect": "interface force defect of the step, F_held - mean F_i [N]",
    "wob_error_estimate": "estimated coupling error of the WOB at this time, factor x (run - companion) [N]",
}


class CouplingInstabilityError(RuntimeError):
    """The co-simulation coupling became unstable (energy growth at the interface).

    Attributes
    ----------
    time : float
        Communication time [s] where it was detected.
    step : int
        Macro-step index.
    residual : float
        Absolute energy residual of the last window [J].
    reference : float
        Reference energy [J] it was compared with.
    """

    def __init__(self, message: str, *, time: float, step: int, residual: float, reference: float):
        self.time = time
        self.step = step
        self.residual = residual
        self.reference = reference
        super().__init__(message)


# ---------------------------------------------------------------------------
# field hammer
# ---------------------------------------------------------------------------
def field_hammer(*, hammer_mass: float = 400.0, natural_frequency: float = 20.0,
                 friction_force: float = 100e3, groups=None) -> RigParameters:
    """A field-size resonance hammer with the dimensionless groups of the rig.

    The rig of Franca & Weber (``RigParameters()``: m1 = 25.3 kg,
    K = 2170 N/m, F0 = 54 N, natural frequency 1.47 Hz) is scaled by choosing
    the three scales the nondimensional form loses:

    * hammer mass ``m1 = 400 kg`` -- a downhole hammer body of a few hundred
      kilograms (an 8 in percussion hammer piston and housing);
    * natural frequency ``Omega/2pi = 20 Hz`` -- the middle of the 10-30 Hz
      band of downhole resonance/percussion tools, so ``K = m1 Omega^2 =
      6.32e6 N/m``;
    * friction force ``F0 = 100 kN`` -- so the rig's preload group
      ``b = 0.55`` is a weight on bit of 55 kN (5.6 t), a usual WOB for an
      8.5 in hard-rock bit, and ``a = 0.15`` is a 15 kN harmonic force.

    Every group (rho, xi, eta, a, b, r, mu, gamma_hat, kc, n, lam_hat, phi)
    is that of ``RigParameters().to_groups()`` (or ``groups`` if given), so
    the nondimensional dynamics are the rig's; the length scale becomes
    ``x0 = F0/K = 15.8 mm``.  ``preload`` is the WOB of the static
    equilibrium, ``frequency`` = 20 Hz (eta = 1).
    """
    g = RIG.to_groups() if groups is None else groups
    K = hammer_mass * (2.0 * math.pi * natural_frequency) ** 2
    return g.to_rig(Scales(hammer_mass, K, friction_force), mu_static=RIG.mu_static)


#: A string carries the field hammer by default when its buoyed weight is at least this many times
#: the field hammer's WOB (the rest hangs from the hook, as on a rig).
FIELD_WEIGHT_RATIO = 2.0


def default_hammer(string) -> RigParameters:
    """The hammer a string gets unless told otherwise: the field hammer (:func:`field_hammer`, a
    55 kN WOB) on a string whose buoyed weight is at least twice that, else the rig of the paper
    (``RigParameters()``: m1 = 25.3 kg, 1.47 Hz, a 29.7 N WOB), the hammer of the lab string."""
    from hammerbit.drillstring.statics import static_equilibrium
    field = field_hammer()
    weight = static_equilibrium(string).buoyed_weight
    return field if weight >= FIELD_WEIGHT_RATIO * field.preload else RIG


# ---------------------------------------------------------------------------
# configuration
# ---------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class CosimConfig:
    """Options of a co-simulation run (SI units; keyword-only).

    Attributes
    ----------
    stop : float
        End time [s] (start at ``start``); reached exactly (a shorter last step).
    step : float
        Macro step H [s]; with ``adaptive`` the first step.
    start : float
        Start time t0 [s].
    scheme : {'jacobi', 'gauss-seidel'}
    extrapolation : {0, 1, 2}
        Polynomial order of the exchanged signals over a step.
    rig : RigParameters
        Hammer; its ``preload`` is replaced by the interface force and its
        amplitude/frequency/phase drive the internal harmonic source.
    wob : float, optional
        Weight on bit of the static equilibrium [N] (default ``rig.preload``).
    interface_stiffness, interface_damping : float
        k_i [N/m], c_i [N s/m] between the string's bottom node and the hammer.
        Default 2e6 N/m and 2e3 N s/m: a shock sub.  With the 400 kg field
        hammer it puts the hammer-on-interface mode at 11 Hz, below the
        20 Hz drive, so the string is isolated and the hammer resonates and
        drills.  A stiff interface (>= 1e7 N/m) clamps the hammer to the
        collars (impedance ~ 7e5 N s/m against ``omega m1`` = 5e4 N s/m), the
        hammer cannot resonate and the bit does not progress.
    mass : str
        Mass scheme of the string (``mixed``, ``lumped``, ``consistent``).
    f_max : float, optional
        Modal truncation of the string at f_max [Hz] (None: all nodal DOFs).
    ramp : float
        Duration [s] over which the harmonic force rises linearly from 0 to its
        amplitude (0: on at full amplitude).  The ramp factor is held per macro
        step at its value at the step's midpoint; with the FMU the master then
        feeds the harmonic force (``harmonic_source='master'``).
    adaptive : bool
        Adaptive macro step with rollback (see :func:`cosimulate`).
    tol : float
        Relative tolerance [-] of the coupling error on the WOB amplitude and
        the penetration: the estimate is held against it; with ``adaptive`` it
        also drives the step.
    estimate : bool
        Run the half-step companion and estimate the coupling error
        (:mod:`hammerbit.cosim.error`); costs about twice the run itself.
    check_step : bool
        Refuse a step that cannot resolve the forcing, the slip dynamics or the
        string modes in the exchange (:func:`hammerbit.cosim.error.check_step`).
    h_min, h_max : float, optional
        Adaptive step limits [s] (default ``step / 64`` and ``step * 8``).
    record : tuple of str
        Variables to record (keys of :data:`RECORDABLE`); ``time`` is always first.
    record_every : int
        Record every n-th communication point.
    check_stability : bool
        Watch the power-bond residual (see module docstring).
    energy_tol, growth, growth_windows, stability_window, blowup : float/int
        Thresholds of the instability detector.
    progress : bool, optional
        Progress bar on stderr (tqdm; None: only for runs above 20000 steps on a terminal).
    rtol : float
        Tolerance of the in-process hammer / the monolithic reference.
    top : TopCondition
        How the hook moves (:mod:`hammerbit.drillstring.top`): ``fixed`` (default),
        a constant ``feed`` or the ``auto-driller`` (a PI controller on the hook
        load holding the static WOB ``wob``).
    """

    stop: float = 1.0
    step: float = 1e-3
    start: float = 0.0
    scheme: str = "jacobi"
    extrapolation: int = 2
    rig: RigParameters = field(default_factory=field_hammer)
    wob: Optional[float] = None
    interface_stiffness: float = 2.0e6
    interface_damping: float = 2.0e3
    mass: str = "mixed"
    f_max: Optional[float] = None
    ramp: float = 0.0
    adaptive: bool = False
    tol: float = 1e-3
    estimate: bool = True
    check_step: bool = True
    h_min: Optional[float] = None
    h_max: Optional[float] = None
    string_step: str = "auto"
    """``auto``: the modal form of the exact string step when the eigenbasis
    reproduces it, else dense; ``dense``: always the dense mat-vec."""
    record: tuple = ("wob", "interface_force", "hammer_position", "hammer_velocity",
                     "bit_position", "bit_velocity")
    record_every: int = 1
    check_stability: bool = True
    energy_tol: float = 0.05
    growth: float = 1.2
    growth_windows: int = 3
    stability_window: int = 10
    blowup: float = 50.0
    progress: Optional[bool] = None
    rtol: float = 1e-10
    exchange: str = "master"
    """``master``: the interface force at ``t_{n+1}`` takes the hammer's new position and
    velocity; ``fmi``: it takes the hammer motion the string extrapolated over the step,
    as the Drillstring FMU computes it in any fixed-step master (which sets the FMU's
    inputs only before its next step); the held force is extrapolated the same way."""
    hammer_input: str = "preload"
    """Where the FMU hammer gets the held interface force: ``preload``, or ``harmonic_force``
    (its change from the WOB, with ``preload`` held at the WOB: the SSP package's wiring)."""
    top: TopCondition = field(default_factory=TopCondition)
    output_derivatives: bool = False
    """Jacobi with an FMU hammer that gives output derivatives (the native flavour): the string
    takes the hammer motion over a step as the Taylor polynomial of its first and second
    derivatives at the step's start (after its new input is set) instead of extrapolating it."""
    harmonic_source: str = "fmu"
    """``fmu``: the FMU's internal harmonic source (continuous in time);
    ``master``: the master computes the harmonic force and feeds its mean over
    each macro step to the FMU's ``harmonic_force`` input (zero-order hold),
    with the FMU's internal source switched off."""

    def __post_init__(self):
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme = {self.scheme!r}: allowed {', '.join(SCHEMES)}")
        if self.extrapolation not in (0, 1, 2):
            raise ValueError(f"extrapolation = {self.extrapolation!r}: allowed 0, 1, 2")
        if self.output_derivatives and self.scheme != "jacobi":
            raise ValueError(f"output_derivatives with scheme = {self.scheme!r}: allowed only with 'jacobi'")
        if self.string_step not in ("auto", "dense"):
            raise ValueError(f"string_step = {self.string_step!r}: allowed 'auto', 'dense'")
        if self.exchange not in EXCHANGES:
            raise ValueError(f"exchange = {self.exchange!r}: allowed {', '.join(EXCHANGES)}")
        if self.hammer_input not in HAMMER_INPUTS:
            raise ValueError(f"hammer_input = {self.hammer_input!r}: allowed {', '.join(HAMMER_INPUTS)}")
        if self.hammer_input == "harmonic_force" and (self.harmonic_source == "master" or self.ramp > 0.0):
            raise ValueError("hammer_input = 'harmonic_force' takes the hammer's harmonic_force input: "
                             "allowed only with harmonic_source = 'fmu' and ramp = 0")
        if not isinstance(self.top, TopCondition):
            raise ValueError(f"top = {self.top!r}: a hammerbit.drillstring.top.TopCondition "
                             f"(TopCondition.parse('auto-driller'), ...)")
        if self.harmonic_source not in ("fmu", "master"):
            raise ValueError(f"harmonic_source = {self.harmonic_source!r}: allowed 'fmu', 'master'")
        for key, name in (("cosim.step", "step"), ("cosim.start", "start"), ("cosim.stop", "stop"),
                          ("cosim.interface_stiffness", "interface_stiffness"),
                          ("cosim.interface_damping", "interface_damping"), ("cosim.ramp", "ramp"),
                          ("cosim.tol", "tol")):
            _check(key, getattr(self, name), label=name)
        if not self.stop > self.start:
            raise ValueError(f"stop = {self.stop!r}: must be > start = {self.start!r}")
        if self.step > self.stop - self.start:
            raise ValueError(f"step = {self.step!r} s is longer than the run ({self.stop - self.start:g} s "
                             f"from start = {self.start!r} to stop = {self.stop!r})")
        if self.f_max is not None:
            _check("cosim.f_max", self.f_max, label="f_max")
        if self.wob is not None:
            _check("cosim.wob", self.wob, label="wob")
        bad = [r for r in self.record if r not in RECORDABLE]
        if bad:
            raise ValueError(f"record: unknown variable(s) {bad}; allowed {', '.join(RECORDABLE)}")
        if self.record_every < 1:
            raise ValueError("record_every must be >= 1")
        if self.adaptive:
            lo, hi = self.step_range
            if not (0 < lo <= self.step <= hi):
                raise ValueError(f"need 0 < h_min <= step <= h_max; got h_min={lo!r}, step={self.step!r}, "
                                 f"h_max={hi!r}")

    @property
    def weight_on_bit(self) -> float:
        """WOB of the static equilibrium [N]."""
        return float(self.rig.preload if self.wob is None else self.wob)

    @property
    def macro_steps(self) -> int:
        """Number of fixed macro steps: whole steps, plus one shorter last step if needed."""
        n, rem = self.whole_steps
        return n + (1 if rem > 0.0 else 0)

    @property
    def whole_steps(self) -> tuple:
        """``(n, rem)``: whole steps of ``step`` in the run and the remaining time [s] (0 if none)."""
        span = self.stop - self.start
        n = int(math.floor(span / self.step * (1.0 + 1e-12)))
        rem = span - n * self.step
        if rem <= 1e-9 * self.step:
            rem = 0.0
        return n, rem

    @property
    def step_range(self) -> tuple:
        """``(h_min, h_max)`` of the adaptive step [s]."""
        return (self.step / 64 if self.h_min is None else self.h_min,
                self.step * 8 if self.h_max is None else self.h_max)

    def ramp_factor(self, t: float) -> float:
        """Factor of the harmonic amplitude at time t [s] (1 after the ramp)."""
        if self.ramp <= 0.0:
            return 1.0
        return min(1.0, max(0.0, (t - self.start) / self.ramp))

    def replace(self, **changes) -> "CosimConfig":
        return replace(self, **changes)


def record_dtype(record: Sequence[str]) -> np.dtype:
    """The structured dtype of a run's recorded series: ``time`` first, then ``record``."""
    return np.dtype([("time", "f8")] + [(r, "f8") for r in record])


@dataclass
class CosimResult:
    """Result of :func:`cosimulate` or :func:`monolithic`.

    Attributes
    ----------
    data : structured ndarray
        ``time`` then the recorded variables (SI).
    config : CosimConfig
    macro_steps : int
    wall_time_s : float
        Time of the stepping loop (set-up excluded; with the companion).
    setup_time_s : float
    penetration_m : float
        Bit position at the end [m].
    stats : dict
        Energy residuals, rejected steps, ...
    method : str
        ``cosim``, ``cosim-adaptive`` or ``monolithic``.
    counts : dict
        Events of the hammer side by kind: ``slips``, ``sticks``, ``impacts``,
        ``bounce_violations``.
    estimate : CouplingErrorEstimate, optional
        A posteriori coupling-error estimate (None without the companion or for
        the monolithic reference).
    """

    data: np.ndarray
    config: CosimConfig
    macro_steps: int
    wall_time_s: float
    setup_time_s: float
    penetration_m: float
    stats: dict
    method: str = "cosim"
    counts: dict = field(default_factory=dict)
    estimate: Optional[CouplingErrorEstimate] = None
    dense: Optional[np.ndarray] = None
    """``time``, ``wob`` sampled finely (the monolithic reference's dense output); the WOB
    figures are taken from it when present."""
    steps: Optional[object] = None
    """The run's :class:`~hammerbit.cosim.amplitude.StepLog`: the WOB amplitude is taken from
    the WOB within each macro step when present."""

    @property
    def stop_s(self) -> float:
        """Time of the last communication point [s]."""
        return float(self.data["time"][-1]) if len(self.data) else self.config.start

    def window(self, t_from: Optional[float] = None) -> np.ndarray:
        """Rows with time >= t_from (default: the second half of the run, the steady window)."""
        if t_from is None:
            t_from = steady_start(self.config)
        return self.data[self.data["time"] >= t_from - 1e-12]

    def wob_amplitude(self, t_from: Optional[float] = None) -> float:
        """Dynamic WOB amplitude [N]: the fundamental harmonic at the forcing frequency over the
        last whole forcing periods of the window (:mod:`hammerbit.cosim.amplitude`), from the WOB
        within each macro step (:class:`~hammerbit.cosim.amplitude.StepLog`) for a co-simulation,
        from the dense output for the monolithic reference."""
        from hammerbit.cosim.amplitude import fundamental
        t0 = steady_start(self.config) if t_from is None else t_from
        if self.steps is not None:
            return self.steps.wob_harmonic(t0)[0]
        d = self.dense if self.dense is not None else self.data
        return fundamental(d["time"], d["wob"], self.config.rig.frequency, t0)[0]

    def wob_peaks(self, t_from: Optional[float] = None) -> tuple:
        """``(max, min)`` of the WOB over the window [N]: the contact peaks and the lowest WOB
        (sampled: a contact spike between two samples is missed)."""
        from hammerbit.cosim.amplitude import peak
        d = self.dense if self.dense is not None else self.data
        t0 = steady_start(self.config) if t_from is None else t_from
        return peak(d["time"], d["wob"], t0)

    def wob_mean(self, t_from: Optional[float] = None) -> float:
        """Mean WOB over the window [N]."""
        return float(np.mean(self.window(t_from)["wob"]))

    def summary(self, t_from: Optional[float] = None) -> dict:
        """JSON-ready figures."""
        out = {"method": self.method, "scheme": self.config.scheme,
               "extrapolation": self.config.extrapolation, "step_s": self.config.step,
               "output_derivatives": self.config.output_derivatives,
               "stop_s": self.stop_s, "macro_steps": self.macro_steps,
               "wall_time_s": self.wall_time_s, "setup_time_s": self.setup_time_s,
               "penetration_m": self.penetration_m, "ramp_s": self.config.ramp,
               "steady_window_start_s": steady_start(self.config) if t_from is None else t_from}
        if "wob" in self.data.dtype.names:
            out["wob_mean_n"] = self.wob_mean(t_from)
            out["wob_amplitude_n"] = self.wob_amplitude(t_from)
            out["wob_max_n"], out["wob_min_n"] = self.wob_peaks(t_from)
        out["top"] = self.config.top.to_dict()
        if "auto_driller" in self.stats:
            out["top"].update(self.stats["auto_driller"])
        out["counts"] = dict(self.counts)
        bounce = int(self.counts.get("bounce_violations", 0))
        out["bounce"] = {"violations": bounce, "flagged": bounce > 0}
        if self.estimate is not None:
            out["error_estimate"] = self.estimate.to_dict()
        out.update({k: v for k, v in self.stats.items() if isinstance(v, (int, float, str))})
        verdict = cosim_regime(self)
        out.update(regime_json(verdict["code"]))
        out["regime_detail"] = verdict
        return out

    def to_csv(self, path) -> Path:
        """Write the recorded array as CSV, with a header of ``name [unit]`` (:func:`record_unit`)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        names = self.data.dtype.names
        arr = np.column_stack([self.data[n] for n in names]) if len(self.data) else np.zeros((0, len(names)))
        header = ",".join(f"{n} [{record_unit(n)}]" for n in names)
        np.savetxt(path, arr, delimiter=",", header=header, comments="", fmt="%.17g")
        return path


def record_unit(name: str) -> str:
    """The SI unit of a recorded variable (``time``: s; the others: the bracket of :data:`RECORDABLE`)."""
    if name == "time":
        return "s"
    text = RECORDABLE[name]
    return text[text.index("[") + 1:text.index("]")]


def steady_start(config: CosimConfig) -> float:
    """Start of the steady window [s]: the later of the run's midpoint and the end of the ramp."""
    return max(0.5 * (config.start + config.stop), min(config.start + config.ramp, config.stop))


#: The co-simulation's ``transient``: the mean WOB of the last two quarters differs by more than this
#: fraction of the set point, or their rates of penetration by more than this fraction of the larger.
COSIM_SETTLE_TOL = 0.05


def capacity_warning(config: CosimConfig) -> Optional[str]:
    """A warning before the run when the held WOB (auto-driller set point or feed) exceeds what the rock carries.

    The rock holds at most ``mu_d F_N`` (:func:`hammerbit.model.regime.sliding_capacity`) against a
    sliding bit: a top condition that keeps more weight on the bit drives it faster and faster.
    """
    if config.top.kind not in ("auto-driller", "feed"):
        return None
    cap = sliding_capacity(config.rig.mu_kinetic, config.rig.normal_force)
    wob = config.weight_on_bit
    if not wob > cap:
        return None
    what = "set point" if config.top.kind == "auto-driller" else "(held by the feed)"
    return (f"the WOB {what} {wob:.6g} N is above the rock's sliding capacity mu_d F_N = {cap:.6g} N: "
            f"once the bit slides it cannot stick again (runaway)")


def _windows_grow(t: np.ndarray, x: np.ndarray, n: int) -> bool:
    """The mean velocity dx/dt over ``n`` equal windows of (t, x) grows strictly, the last growth >= half the first."""
    edges = np.linspace(t[0], t[-1], n + 1)
    xs = np.interp(edges, t, x)
    v = np.diff(xs) / np.diff(edges)
    growth = np.diff(v)
    return bool(np.all(growth > 0.0) and growth[-1] >= 0.5 * growth[0])


def cosim_regime(result: "CosimResult") -> dict:
    """The regime verdict of a co-simulation from its recorded series.

    The rules of ``docs/model.md`` ("Validity domain and the regime verdict").  The bit is stuck at
    a sample where the recorded ``stick`` is 1 (or, without it, its velocity is 0).  ``runaway``: no
    stuck sample over ``RUNAWAY_WINDOWS`` windows of at least ``MIN_WINDOW`` forcing periods at the
    end, the mean bit velocity growing over them (the fallback rule of the scenes), and the mean WOB above the friction
    floor; ``stall``: no slip for ``STALL_PERIODS`` forcing periods at the end while the mean WOB is at
    least ``STALL_WOB_FRACTION`` of its set point; ``bounce``: bounce violations counted; ``tension``:
    the WOB fell below zero; ``transient``: the last two quarters differ (:data:`COSIM_SETTLE_TOL`).
    Needs ``bit_position``, ``wob`` and ``stick`` or ``bit_velocity`` recorded; without them only ``bounce``.
    """
    from hammerbit.scene.flags import MIN_WINDOW, RUNAWAY_WINDOWS
    cfg = result.config
    d = result.data
    bounce = int(result.counts.get("bounce_violations", 0)) > 0
    out = {"runaway": False, "bounce": bounce, "tension": False, "stall": False, "transient": False,
           "sliding_capacity_n": sliding_capacity(cfg.rig.mu_kinetic, cfg.rig.normal_force),
           "wob_set_point_n": cfg.weight_on_bit}
    names = d.dtype.names
    if len(d) < 8 or not all(k in names for k in ("bit_position", "wob")) or \
            not ("stick" in names or "bit_velocity" in names):
        out["code"] = REGIME_BOUNCE if bounce else 0
        return out
    t, x, wob = d["time"], d["bit_position"], d["wob"]
    held = d["stick"] > 0.5 if "stick" in names else d["bit_velocity"] <= 0.0
    T = 1.0 / cfg.rig.frequency
    stuck = np.nonzero(held)[0]
    t_stuck = float(t[stuck[-1]]) if stuck.size else float(t[0])
    out["tension"] = bool(np.min(wob) < 0.0)
    out["last_stuck_s"] = float(t[stuck[-1]]) if stuck.size else None
    # runaway: the samples after the last stuck one
    after = t > t_stuck
    if np.count_nonzero(after) >= 2 and t[-1] - t_stuck >= RUNAWAY_WINDOWS * MIN_WINDOW * T:
        ta, xa = t[after], x[after]
        last = ta >= ta[-1] - (ta[-1] - ta[0]) / RUNAWAY_WINDOWS
        F0 = cfg.rig.mu_static * cfg.rig.normal_force
        g = cfg.rig.to_groups().replace(b=float(np.mean(wob[after][last])) / F0)
        out["runaway"] = bool(g.b > friction_floor(g) and _windows_grow(ta, xa, RUNAWAY_WINDOWS))
    # stall: no slip over the last STALL_PERIODS periods, the WOB held
    tail = t >= t[-1] - STALL_PERIODS * T
    if t[-1] - t[0] >= STALL_PERIODS * T and np.all(held[tail]):
        out["stall"] = bool(np.mean(wob[tail]) >= STALL_WOB_FRACTION * cfg.weight_on_bit)
    if not (out["runaway"] or out["stall"]):
        q = [(t >= t[0] + f * (t[-1] - t[0])) for f in (0.5, 0.75)]
        third, fourth = q[0] & ~q[1], q[1]
        if np.count_nonzero(third) >= 2 and np.count_nonzero(fourth) >= 2:
            dw = abs(np.mean(wob[fourth]) - np.mean(wob[third]))
            r3 = (x[third][-1] - x[third][0]) / (t[third][-1] - t[third][0])
            r4 = (x[fourth][-1] - x[fourth][0]) / (t[fourth][-1] - t[fourth][0])
            out["transient"] = bool(dw > COSIM_SETTLE_TOL * cfg.weight_on_bit
                                    or abs(r4 - r3) > COSIM_SETTLE_TOL * max(abs(r3), abs(r4)))
    out["code"] = sum(bit for name, bit in REGIME_BITS.items() if out[name])
    return out


def cosim_warnings(summary: dict) -> list:
    """Plain-language warnings of a co-simulation's regime verdict (its :meth:`CosimResult.summary`)."""
    r = summary["regime_detail"]
    msgs = []
    if r["runaway"]:
        since = "the start" if r["last_stuck_s"] is None else f"t = {r['last_stuck_s']:.4g} s"
        msgs.append(f"runaway: the bit has not stuck since {since} and its drift keeps accelerating (rock's "
                    f"sliding capacity {r['sliding_capacity_n']:.6g} N, WOB set point {r['wob_set_point_n']:.6g} N); "
                    f"the penetration is not a rate of penetration")
    if r["stall"]:
        msgs.append(f"stall: the bit has not slipped for the last {STALL_PERIODS} forcing periods while the WOB "
                    f"is held: it no longer drills")
    if r["tension"]:
        msgs.append(f"tension: the WOB fell below zero (lowest {summary.get('wob_min_n', float('nan')):.4g} N)")
    if r["transient"]:
        msgs.append("transient: the mean WOB or the rate of penetration has not settled within the run")
    return msgs


def event_counts(raw: dict) -> dict:
    """The hammer's event counts under the names the results use."""
    return {"slips": int(raw.get("slip_start", 0)), "sticks": int(raw.get("stick", 0)),
            "impacts": int(raw.get("impact", 0)), "bounce_violations": int(raw.get("bounce", 0))}
