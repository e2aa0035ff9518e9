"""One error type and one table of allowed ranges for every user-facing number.

Every number a user can give hammerbit (an SI parameter of the rig, a
nondimensional group, a solver option, an FMU parameter or input) has one
entry in :data:`RANGES`.  The dataclasses of :mod:`params`, the solver
options, the FMU's ``modelDescription.xml`` (``min``/``max``) and the FMU's
run-time checks all read this table, so a range is written once.

A failed check raises :class:`ParameterError`, which names the parameter *as
the caller typed it*, its value, the allowed range and, where known, the unit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ParameterError", "Range", "RANGES", "check", "check_range"]


class ParameterError(ValueError):
    """A parameter is out of range or not finite.

    Attributes
    ----------
    name : str
        Parameter name as the caller spelled it.
    value : object
        The offending value.
    allowed : str
        The allowed range, human-readable (with the unit where one applies).
    """

    def __init__(self, name: str, value, allowed: str):
        self.name = name
        self.value = value
        self.allowed = allowed
        super().__init__(f"parameter {name!r} = {value!r} is out of range: allowed {allowed}")

    def renamed(self, name: str) -> "ParameterError":
        """The same error, naming the parameter as ``name`` (the user's spelling)."""
        return type(self)(name, self.value, self.allowed)


@dataclass(frozen=True)
class Range:
    """Allowed values of one real parameter.

    Attributes
    ----------
    lo, hi : float
        Bounds.
    lo_open, hi_open : bool
        Whether a bound itself is excluded.
    allow_inf : bool
        ``+inf`` is allowed (e.g. a gap of ``inf``: no impact device).
    unit : str
        SI unit ("" for nondimensional).
    """

    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False
    allow_inf: bool = False
    unit: str = ""

    def text(self) -> str:
        """``[lo, hi]`` with open ends as ``(``/``)`` and the unit."""
        s = f"{'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}{')' if self.hi_open else ']'}"
        if self.allow_inf:
            s += " or inf"
        return f"{s} {self.unit}" if self.unit and self.unit != "1" else s

    def contains(self, v: float) -> bool:
        """True if the float ``v`` is allowed."""
        if math.isnan(v):
            return False
        if math.isinf(v):
            return self.allow_inf and v > 0
        if v < self.lo or v > self.hi:
            return False
        return not ((self.lo_open and v == self.lo) or (self.hi_open and v == self.hi))


def check_range(name: str, value, rng: Range) -> float:
    """``float(value)`` if ``rng`` allows it, else :class:`ParameterError` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, value, f"a real number in {rng.text()}") from None
    if isinstance(value, bool):
        raise ParameterError(name, value, f"a real number in {rng.text()}")
    if not rng.contains(v):
        if math.isnan(v) or (math.isinf(v) and not rng.allow_inf):
            raise ParameterError(name, value, f"a finite number in {rng.text()}")
        raise ParameterError(name, value, rng.text())
    return v


def check(key: str, value, *, label: str | None = None) -> float:
    """Check ``value`` against ``RANGES[key]``; errors name ``label`` (default ``key``)."""
    return check_range(label or key, value, RANGES[key])


_INF = math.inf

#: key -> Range.  Keys are RigParameters fields (SI), the nondimensional
#: groups (prefixed ``group.``), solver options (``solver.``), the options of
#: the hammer-frequency check (``check.``) and the FMU's own parameters and
#: inputs (``fmu.``).
RANGES: dict[str, Range] = {
    # -- SI parameters of the rig (RigParameters fields) --------------------
    "hammer_mass": Range(1e-6, 1e9, unit="kg"),
    "bit_mass": Range(1e-6, 1e9, unit="kg"),
    "stiffness": Range(1e-6, 1e15, unit="N/m"),
    "damping": Range(0.0, 1e12, unit="N.s/m"),
    "mu_static": Range(1e-6, 10.0, unit="1"),
    "mu_kinetic": Range(1e-6, 10.0, unit="1"),      # and <= mu_static (checked by RigParameters)
    "friction_decay": Range(0.0, 1e9, unit="s/m"),
    "normal_force": Range(1e-9, 1e12, unit="N"),
    "contact_stiffness": Range(0.0, 1e20, unit="N/m^n"),
    "contact_exponent": Range(0.0, 5.0, lo_open=True, unit="1"),
    "contact_damping": Range(0.0, 1e9, unit="s/m"),
    "gap": Range(0.0, 1e9, allow_inf=True, unit="m"),
    "preload": Range(-1e12, 1e12, unit="N"),
    "amplitude": Range(0.0, 1e12, unit="N"),
    "frequency": Range(0.0, 1e9, lo_open=True, unit="Hz"),
    "phase": Range(-1e6, 1e6, unit="rad"),
    # -- the paper's nondimensional groups -----------------------------------
    "group.rho": Range(0.0, 1e3, lo_open=True),
    "group.xi": Range(0.0, 10.0),
    "group.eta": Range(0.0, 100.0, lo_open=True),
    "group.a": Range(0.0, 1e3),
    "group.b": Range(-1e3, 1e3),
    "group.r": Range(0.0, 1e12, allow_inf=True),
    "group.mu": Range(0.0, 1.0, lo_open=True),
    "group.gamma_hat": Range(0.0, 1e6),
    "group.kc": Range(0.0, 1e12),
    "group.n": Range(0.0, 5.0, lo_open=True),
    "group.lam_hat": Range(0.0, 1e4),
    "group.phi": Range(-1e6, 1e6, unit="rad"),
    # -- solver options --------------------------------------------------------
    "solver.rtol": Range(1e-15, 1.0),
    "solver.atol": Range(1e-300, 1.0),
    "solver.steps_per_period": Range(4, 1e9),
    "solver.bisection_tol": Range(1e-15, 1.0),
    "solver.max_events_per_period": Range(1, 1e12),
    "solver.max_step": Range(0.0, _INF, lo_open=True, allow_inf=True),
    "solver.graze_tol": Range(0.0, 1.0),
    "solver.max_steps": Range(0, 1e15),
    "solver.max_steps_per_period": Range(0, 1e15),
    # -- a scene (simulate) --------------------------------------------------
    "simulate.periods": Range(0.0, 1e9, lo_open=True),
    "simulate.sample_dt": Range(0.0, 1e9, lo_open=True, unit="s"),
    # -- co-simulation master (hammerbit.cosim.config.CosimConfig) ----------------------
    "cosim.step": Range(0.0, 10.0, lo_open=True, unit="s"),
    "cosim.start": Range(-1e9, 1e9, unit="s"),
    "cosim.stop": Range(-1e9, 1e9, unit="s"),
    "cosim.interface_stiffness": Range(0.0, 1e13, lo_open=True, unit="N/m"),
    "cosim.interface_damping": Range(0.0, 1e10, unit="N s/m"),
    "cosim.ramp": Range(0.0, 1e6, unit="s"),
    "cosim.tol": Range(0.0, 1.0, lo_open=True, hi_open=True),
    "cosim.f_max": Range(0.0, 1e6, lo_open=True, unit="Hz"),
    "cosim.wob": Range(0.0, 1e9, unit="N"),
    # -- the stepper's state and clock (nondimensional: x0, x0 Omega, 1/Omega) --
    "state.hammer_position": Range(-1e12, 1e12),
    "state.hammer_velocity": Range(-1e12, 1e12),
    "state.bit_position": Range(-1e12, 1e12),
    "state.bit_velocity": Range(0.0, 1e12),        # the bit never moves backwards
    "state.subsystem": Range(-1e300, 1e300),       # linear subsystem and energy states: finite
    "state.time": Range(-1e12, 1e12),
    "state.extra_force": Range(-1e12, 1e12),       # constant extra force on the hammer / F0
    # -- the hammer-frequency check (hammerbit.check.frequency) ---------------------
    "check.frequency": Range(0.0, 1e6, lo_open=True, unit="Hz"),
    "check.rpm": Range(0.0, 1e6, lo_open=True, unit="rev/min"),
    "check.factor": Range(0.0, 1e3, lo_open=True),
    "check.margin": Range(0.0, 1.0, lo_open=True, hi_open=True),
    "check.range": Range(0.0, 1e6, unit="Hz"),
    "check.resonance_limit": Range(0.0, 1e6, lo_open=True),
    "check.min_window": Range(0.0, 1.0),
    "check.rtol": Range(1e-10, 1e-2),
    "check.damping_factor": Range(0.0, 100.0, lo_open=True),
    "check.n_grid": Range(11, 1e7),
    # -- the FMU's own parameters and its inputs --------------------------------
    "fmu.tolerance": Range(1e-14, 1e-2, unit="1"),
    # the FMU's clock: start, stop and every communication point (fmi2SetupExperiment, fmi2DoStep)
    "fmu.time": Range(-1e9, 1e9, unit="s"),
    "fmu.initial_hammer_position": Range(-1e6, 1e6, unit="m"),
    "fmu.initial_bit_position": Range(-1e6, 1e6, unit="m"),
    # physical range of the inputs: |force| up to 1e9 N (a 100,000 t load);
    # beyond that a value is a units or wiring error, not a load
    "fmu.preload": Range(-1e9, 1e9, unit="N"),
    "fmu.harmonic_force": Range(-1e9, 1e9, unit="N"),
}
