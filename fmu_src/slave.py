"""HammerBitRock: the FMI 2.0 co-simulation slave of the hammer-bit-rock model.

A thin :class:`pythonfmu.Fmi2Slave`: ``do_step`` reads the two inputs, calls
:meth:`Stepper.advance` (the library's adaptive hybrid integrator, every event
inside the step located) and the outputs are read straight from the stepper's
state arrays through the shared force formulas of :mod:`kernels`.  The
variables are declared in :mod:`fmu_variables`; their ranges come from
:data:`validation.RANGES`.

Semantics (see ``docs/fmu.md``):

* **Inputs** ``preload`` and ``harmonic_force`` are held constant over a
  communication step (zero-order hold).  A value beyond 1000 times the static
  friction threshold is refused when it is set (the previous value stays); a
  vector set is all or nothing.  The
  internal harmonic source ``amplitude * sin(2 pi frequency t + phase)`` is a
  function of time inside the step and is added to ``harmonic_force``.
* **Parameters** are ``fixed`` (validated at ``fmi2ExitInitializationMode``),
  except ``tolerance`` which is ``tunable``.  Outputs are valid in
  Initialization Mode: they follow the parameters set so far.
* **Statuses.**  pythonfmu 0.7 can return only OK/Discard from ``do_step`` and
  turns a Python exception into ``fmi2Fatal``, so no exception leaves this
  class.  Every call records the FMI status it should return in the Integer
  variable ``last_status`` (0 OK, 1 Warning, 2 Discard, 3 Error), which the
  FMU's native front returns to the master; every non-OK outcome is logged
  with that status and a message naming the variable, its value and the
  allowed range.  Refused calls change nothing.
* **State.**  ``fmi2GetFMUstate`` saves the whole hidden state, so
  get-step-set-step is bit-identical; it serialises to JSON (floats round-trip
  exactly).
"""
from __future__ import annotations

import json
import math
import os
import time

import numpy as np
from pythonfmu import Boolean, DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Slave, \
    Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

from . import build_info
from . import kernel_driver, kernel_forces, kernel_layouts
from . import numba_cache
from .fmu_description import STATUS_VARIABLE
from .fmu_state import STATE_FORMAT, pop_deserialize_reason, pop_deserialize_status
from .fmu_variable_xml import KIND, RealVar
from .fmu_variables import (DEFAULT_TOLERANCE, FIXED_REALS, HAMMER_VARIABLES, INPUTS, MAX_PERIODS_PER_STEP, OUTPUTS, PARAMETERS, RIG_FIELDS, UNITS, accepted_bounds, input_range, nominal_values, range_key, start_values, variable_range)
from .kernel_layouts import P_B, P_FEXT
from .params import RigParameters
from .pythonfmu_exit import guard_pythonfmu_exit
from .solver_errors import EventStormError, SolverError, StepSizeError, StepStormError
from .solver_options import SolverOptions
from .stepping import NO_LOG, NO_POINCARE, NO_SAMPLE_TIMES, NO_SAMPLES, Stepper
from .validation import RANGES, ParameterError, check
from .numba_dispatch import entry_point as _entry_point
from .fmi_status import DISCARD, ERROR, OK, WARNING
from .fmu_regime import N_CERT, causal_regime
from .regime import oscillator_l1
from .regime_codes import regime_names
from .slave_access import VariableAccess
from .slave_state import SavedState

__all__ = ["HammerBitRock", "PARAMETERS", "INPUTS", "OUTPUTS", "UNITS", "STATE_FORMAT",
           "OK", "WARNING", "DISCARD", "ERROR", "guard_pythonfmu_exit"]

_INF = math.inf
_ST_DONE = kernel_layouts.ST_DONE
#: the kernel's record buffers (``rec``): an FMU step records nothing
NO_REC = (NO_POINCARE, NO_SAMPLE_TIMES, NO_SAMPLES, NO_LOG)
_isfinite = math.isfinite


# Communication times are compared with an absolute tolerance (as the native front does): 1 ns,
# or a few units in the last place where t is so large that its doubles lie farther apart
_TIME_ABS_TOL = 1e-9
_TIME_ULPS = 4

# Solver failures that no shorter communication step can clear: the kernel counts its steps and
# events per forcing period of the model, at absolute times, so every step over that time fails
_STORMS = (StepStormError, EventStormError, StepSizeError)


def _time_tol(t: float) -> float:
    return max(_TIME_ABS_TOL, _TIME_ULPS * math.ulp(t))


def _build_start_values(resources) -> dict:
    """The start values the FMU build recorded in ``resources/start_values.json`` ({} if none)."""
    if not resources:
        return {}
    path = os.path.join(str(resources), build_info.START_VALUES_FILE)
    if not os.path.isfile(path):
        return {}
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def _general_advance(st):
    """``Stepper.advance`` of ``st`` with the kernel's call signature (its status, or it raises)."""
    def kernel(y, ist, fst, tau_end, *_):
        st.advance(tau_end)
        return _ST_DONE
    return kernel


class HammerBitRock(VariableAccess, SavedState, Fmi2Slave):
    """Hammer-bit-rock model of Franca & Weber (2004) as an FMI 2.0 co-simulation slave."""

    author = "hammerbit project"
    description = ("Resonance hammer drilling (Franca & Weber 2004): hammer, bit, spring-damper, "
                   "velocity-weakening dry friction on the rock, optional Hunt-Crossley impact; "
                   "hybrid stick/slip and contact events located inside every step")
    version = "0.1.0"
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3,
                                           tolerance=DEFAULT_TOLERANCE)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name, value in start_values(_build_start_values(self.resources)).items():
            setattr(self, name, value)                # parameters and inputs
        # -- private state -------------------------------------------------------
        self.last_status = OK      # FMI status of the last call (read by the native front)
        self._t_start = 0.0        # start time [s] (fmi2SetupExperiment)
        self._t = 0.0              # current communication point [s]
        self._ready = False        # exit_initialization_mode succeeded
        self._terminated = False   # fmi2Terminate was called
        self._error = "the FMU is not initialised (call fmi2ExitInitializationMode first)"
        self._dirty = False        # the tolerance was set since the last commit
        self._slow = True          # do_step must take the slow path (not ready, or dirty)
        self._stale = False        # Initialization Mode: outputs must follow the parameters
        self._committed = None     # dict of the validated parameter values in use
        self._commit(self._param_values(), warm_up=False)

        self._register(nominal_values(self._rig))
        # value reference -> getter / setter, by type (the fast paths of fmi2Get/Set*)
        self._getters = {t: {} for t in (Real, Integer, Boolean)}
        self._setters = {t: {} for t in (Real, Integer, Boolean)}
        self._names = {}
        for vr, var in self.vars.items():
            kind = KIND[type(var)]
            self._names[vr] = (var.name, kind)
            self._getters[kind][vr] = var.getter
            if var.causality in (Fmi2Causality.input, Fmi2Causality.parameter):
                self._setters[kind][vr] = var.setter
        self._real_get = self._getters[Real]
        self._real_set = self._setters[Real]
        HammerBitRock._STATE_SIZE = self._st.get_state().shape[0]   # the same for every instance
        guard_pythonfmu_exit(self.resources)

    def _register(self, nominal: dict) -> None:
        """Register :data:`~.fmu_description.HAMMER_VARIABLES` in their order: their value references."""
        getters = {**self._output_getters(), STATUS_VARIABLE.name: self._read_last_status}
        for v in HAMMER_VARIABLES:
            kw = dict(causality=getattr(Fmi2Causality, v.causality), description=v.description,
                      variability=getattr(Fmi2Variability, v.variability))
            if v.causality == "parameter":
                kw.update(initial=Fmi2Initial.exact, setter=self._param_setter(v.name))
            elif v.causality == "input":
                kw.update(setter=self._input_setter(v.name))
            else:
                kw.update(initial=Fmi2Initial.calculated, getter=getters[v.name])
            if v.type == "Float64":
                rng = (input_range(v.name, self._F0) if v.causality == "input"
                       else variable_range(v.name) if v.causality == "parameter" else None)
                bounds = {} if rng is None else dict(min=rng.lo, max=rng.hi)
                self.register_variable(RealVar(v.name, v.unit, nominal=nominal.get(v.name), **bounds, **kw))
            else:
                self.register_variable((Boolean if v.type == "Boolean" else Integer)(v.name, **kw))

    # ------------------------------------------------------------------
    # statuses and messages
    # ------------------------------------------------------------------
    def _log(self, message: str, status: int) -> None:
        # the FMI logger treats the message as a printf format: escape '%'
        self.log(message.replace("%", "%%"), Fmi2Status(status))

    def _fail(self, message: str, status: int = ERROR) -> bool:
        """Record ``status`` for this call, log ``message``; False (for do_step)."""
        self.last_status = status
        self._log(message, status)
        return False

    def _read_last_status(self) -> int:
        pending = pop_deserialize_status()
        reason = pop_deserialize_reason()
        if reason:        # the refusal of fmi2DeSerializeFMUstate, a class-level call that cannot log
            self._log(f"fmi2DeSerializeFMUstate: {reason}; refused", ERROR)
        return self.last_status if pending is None else pending

    # ------------------------------------------------------------------
    # parameters -> stepper
    # ------------------------------------------------------------------
    @classmethod
    def _accepts(cls, vals: dict, inputs: dict) -> bool:
        """Would initialisation accept the parameter values ``vals`` with the input values
        ``inputs`` (the checks of _commit and _check_inputs)?"""
        try:
            rig, solver = cls._validate(vals)
            x0 = rig.scales.length
            Stepper(rig.to_groups(), solver=solver, y0=(float(vals["initial_hammer_position"]) / x0, 0.0,
                                                        float(vals["initial_bit_position"]) / x0, 0.0))
        except ParameterError:
            return False
        return all(input_range(name, rig.scales.friction_force).contains(v) for name, v in inputs.items())

    @staticmethod
    def _validate(vals: dict):
        """RigParameters and SolverOptions of ``vals``; ParameterError if one is invalid."""
        for name in FIXED_REALS + ("tolerance",):
            if name in RIG_FIELDS:
                continue                 # RigParameters checks them (and mu_kinetic <= mu_static)
            check(range_key(name), vals[name], label=name)
        rig_kw = {name: vals[name] for name in RIG_FIELDS}
        rig_kw["gap"] = float(vals["gap"]) if vals["impact_enabled"] else _INF
        # the preload is an input, applied at every step; 0 here only fills the dataclass
        rig = RigParameters(preload=0.0, **rig_kw)
        tol = float(vals["tolerance"])
        return rig, SolverOptions(rtol=tol, atol=1e-2 * tol)

    def _commit(self, vals: dict, *, warm_up: bool = True, keep_state=None):
        """Build the stepper of the validated parameters ``vals`` (raises ParameterError)."""
        rig, solver = self._validate(vals)
        s = rig.scales
        groups = rig.to_groups()
        omega_f = 2.0 * math.pi * rig.frequency
        # absolute-time forcing A sin(omega t + phase) on the kernel's clock tau = Omega (t - t_start)
        if self._t_start != 0.0:
            groups = groups.replace(phi=math.fmod(rig.phase + omega_f * self._t_start, 2.0 * math.pi))
        x0 = s.length
        y0 = (float(vals["initial_hammer_position"]) / x0, 0.0, float(vals["initial_bit_position"]) / x0, 0.0)
        st = Stepper(groups, solver=solver, y0=y0, compile_helper=False)   # inputs enter p at every step
        if keep_state is not None:
            st.set_state(keep_state)
        # only now change the instance (nothing above touched it)
        self._st = st
        self._y, self._ist, self._p = st.y, st.istate, st.p      # updated in place by the stepper
        self._yi, self._ii = st.y.item, st.istate.item
        # do_step's hot path calls the stepper's compiled entry point with the stepper's own
        # arrays: Stepper.advance would repeat the argument checks do_step has made already
        self._kernel = kernel_driver.advance_hammer if st.fast else _general_advance(st)
        self._slow = True          # do_step rebuilds its tuple of the stepper's arrays
        self._rig = rig
        self._step_cap = MAX_PERIODS_PER_STEP / rig.frequency     # the longest step accepted [s]
        self._x0 = x0
        self._v0 = s.velocity
        self._F0 = s.friction_force
        self._omega = s.omega
        # in place: the input setters hold this dict
        self.__dict__.setdefault("_input_ranges", {}).update(
            {v.name: input_range(v.name, self._F0) for v in INPUTS})
        self._x3_start = y0[2]
        self._committed = dict(vals)
        self._dirty = False
        self._applied_preload = math.nan       # inputs last written into st.p (NaN: none yet)
        self._applied_force = math.nan
        # the regime verdict's numbers fixed by the parameters, and its scratch
        self._regime_args = (st.y, st.istate, st.fstate, st.p, *oscillator_l1(groups.rho, groups.xi),
                             np.empty(N_CERT))
        self._regime_kernel = causal_regime      # do_step's hot path: its entry point (_prepare_step)
        self._regime_seen = self._regime()
        if warm_up:
            # first call of the kernels: load them from the numba cache (or compile them) now
            # rather than in the first fmi2DoStep (the state is put back exactly)
            saved = st.get_state()
            st.advance(st.time)
            st.set_state(saved)
            for name in ("spring_force", "contact_force", "friction_force", "rock_force"):
                self._output_getters()[name]()

    def _refresh_initial_outputs(self) -> None:
        """Initialization Mode: outputs of the parameters set so far (invalid ones: reported at exit)."""
        self._stale = False
        try:
            self._commit(self._param_values(), warm_up=False)
        except ParameterError:
            pass                # the previous valid values stay; fmi2ExitInitializationMode reports it

    def _apply_tolerance(self) -> bool:
        vals = self._param_values()
        try:
            self._commit(vals, warm_up=False, keep_state=self._st.get_state())
        except ParameterError as e:           # unreachable: the setter checked the range
            self.tolerance = self._committed["tolerance"]
            return self._fail(f"invalid tunable parameter: {e}")
        return True

    # ------------------------------------------------------------------
    # FMI life cycle
    # ------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self.last_status = OK
        rng = RANGES["fmu.time"]
        if not rng.contains(start_time):
            return self._fail(f"fmi2SetupExperiment: startTime = {start_time!r} s is out of range: allowed "
                              f"{rng.text()}; refused, the start time stays {self._t_start!r} s")
        if stop_time is not None and not (rng.contains(stop_time) and stop_time >= start_time):
            return self._fail(f"fmi2SetupExperiment: stopTime = {stop_time!r} s is out of range: allowed "
                              f"[startTime = {start_time!r}, {rng.hi:g}] s; refused, the start time stays "
                              f"{self._t_start!r} s")
        self._t_start = float(start_time)
        self._t = float(start_time)
        self._slow = True
        self._stale = True
        if tolerance is not None:
            rng = variable_range("tolerance")
            if rng.contains(float(tolerance)):
                self.tolerance = float(tolerance)
            else:
                self._fail(f"fmi2SetupExperiment: tolerance = {tolerance!r} is outside {rng.text()}; "
                           f"the FMU's tolerance {self.tolerance!r} is used", WARNING)

    def enter_initialization_mode(self):
        self.last_status = OK

    def exit_initialization_mode(self):
        self.last_status = OK
        self._stale = False
        try:
            t0 = time.perf_counter()
            self._commit(self._param_values())
            self._check_inputs()
            report = numba_cache.first_use_report(time.perf_counter() - t0)
        except ParameterError as e:
            self._ready = False
            self._error = f"initialisation failed: {e}"
            return self._fail(self._error)
        except Exception as e:  # noqa: BLE001 -- an exception would be fmi2Fatal in pythonfmu
            self._ready = False
            self._error = f"initialisation failed: {type(e).__name__}: {e}"
            return self._fail(self._error)
        self._t = self._t_start
        self._ready = True
        self._slow = True
        self._error = None
        if report is not None:
            message, status = report
            if status == OK:
                self._log(message, OK)
            else:
                self._fail(message, status)

    def terminate(self):
        self.last_status = OK
        self._terminated = True
        self._slow = True

    def do_step(self, current_time, step_size):
        try:
            # the checks of the common case first: initialised, on the FMU's time, a valid step
            if (self._slow or current_time != self._t or not 0.0 < step_size <= self._step_cap) \
                    and not self._step_allowed(current_time, step_size):
                return False
            kernel, y, ist, fst, p, opts, t_start, omega, state = self._hot
            # snapshot of y, ist and fst at the step start (views of `state`; bytes: the cheapest
            # copy numpy makes, Stepper.snapshot without the method call)
            snap = state.tobytes()
            old_inputs = None
            if self.preload != self._applied_preload or self.harmonic_force != self._applied_force:
                old_inputs = self._apply_inputs(p)
                if old_inputs is None:
                    return False
            try:
                status = kernel(y, ist, fst, (current_time + step_size - t_start) * omega, p, opts, NO_REC)
                if status != _ST_DONE:
                    self._st.check_status(status)          # raises the solver's error
            except Exception as e:  # noqa: BLE001 -- restore the state, report, never raise
                return self._step_failed(e, snap, old_inputs, current_time, step_size)
            self._t = current_time + step_size
            self.last_status = OK
            regime = self._regime()
            if regime != self._regime_seen:
                self._regime_changed(regime)
            return True
        except Exception as e:  # noqa: BLE001 -- an exception would be fmi2Fatal in pythonfmu
            return self._fail(f"fmi2DoStep failed: {type(e).__name__}: {e}")

    def _regime(self) -> int:
        """The regime bits known now (``fmu_regime.causal_regime``, the inputs as last applied)."""
        return self._regime_kernel(*self._regime_args)

    def _regime_changed(self, regime: int) -> None:
        """Log the one warning of a change of the regime verdict."""
        names = ", ".join(regime_names(regime)) or "none"
        was = ", ".join(regime_names(self._regime_seen)) or "none"
        self._regime_seen = regime
        self._log(f"regime at t = {self._t!r} s: {names} (regime = {regime}; was {was})", WARNING)

    def _step_allowed(self, current_time, step_size) -> bool:
        """The checks of do_step off its common case; False (with the status recorded) to refuse."""
        if self._slow and not self._prepare_step():
            return False
        t = self._t
        if not (0.0 < step_size <= self._step_cap) or (
                current_time != t and not abs(current_time - t) <= _time_tol(t)):
            return self._reject_step(current_time, step_size)
        return True

    def _apply_inputs(self, p):
        """Write the inputs into the kernel's parameters; their previous values, or None if refused."""
        preload, fh = self.preload, self.harmonic_force
        if not (_isfinite(preload) and _isfinite(fh)):
            bad = "preload" if not _isfinite(preload) else "harmonic_force"
            self._fail(f"input {bad!r} = {getattr(self, bad)!r} N is not finite; step refused, "
                       f"state unchanged")
            return None
        old_inputs = (p[P_B], p[P_FEXT], self._applied_preload, self._applied_force)
        p[P_B] = preload / self._F0          # exactly as RigParameters.to_groups()
        p[P_FEXT] = fh / self._F0
        self._applied_preload = preload
        self._applied_force = fh
        return old_inputs

    def _step_failed(self, e, snap, old_inputs, current_time, step_size) -> bool:
        """The kernel failed: put the state and the inputs back as they were, report Discard."""
        self._st.restore(snap)
        if old_inputs is not None:
            self._p[P_B], self._p[P_FEXT], self._applied_preload, self._applied_force = old_inputs
        if isinstance(e, _STORMS):
            t_fail = self._t_start + e.time / self._omega
            return self._fail(f"{e}: the solver cannot get past t = {t_fail!r} s, with this step from "
                              f"t = {current_time!r} s or any shorter one (its limits count per forcing "
                              f"period of the model); state restored to t = {current_time!r} s; change "
                              f"the parameters or the tolerance")
        kind = "solver failure" if isinstance(e, SolverError) else f"failure ({e!r})"
        return self._fail(f"{kind} in the step from t = {current_time!r} s with "
                          f"h = {step_size!r} s: {e}; state restored to t = {current_time!r} s "
                          f"(retry with a shorter step)", DISCARD)

    def _prepare_step(self) -> bool:
        """Slow path of do_step: not initialised, terminated, or the tolerance was set."""
        if self._terminated:
            return self._fail("fmi2DoStep refused: the FMU was terminated (fmi2Terminate)")
        if not self._ready:
            return self._fail(f"fmi2DoStep refused: {self._error}")
        if self._dirty and not self._apply_tolerance():
            return False
        st = self._st
        # what the hot path of do_step reads, in one tuple (the stepper, its arrays and the
        # clock change only when _slow is set)
        if self._kernel is kernel_driver.advance_hammer:     # compiled by now: call it without the type dispatch
            self._kernel = _entry_point(kernel_driver.advance_hammer,
                                        (st.y, st.istate, st.fstate, 0.0, st.p, st.opts, NO_REC))
        self._hot = (self._kernel, st.y, st.istate, st.fstate, st.p, st.opts, self._t_start, self._omega,
                     st.state_buffer)
        self._regime_kernel = _entry_point(causal_regime, self._regime_args)
        self._slow = False
        return True

    def _reject_step(self, current_time, step_size) -> bool:
        if not (0.0 < step_size < _INF):
            return self._fail(f"communication step size h = {step_size!r} s is invalid: "
                              f"it must be > 0 and finite; step refused, state unchanged")
        if step_size > self._step_cap:
            f = self._rig.frequency
            return self._fail(f"communication step size h = {step_size!r} s spans {step_size * f:.6g} forcing "
                              f"periods (frequency = {f!r} Hz), more than MAX_PERIODS_PER_STEP = "
                              f"{MAX_PERIODS_PER_STEP} (h <= {self._step_cap:.6g} s): the solver's limits "
                              f"count per period, so such a step's work has no useful bound; take shorter "
                              f"steps; step refused, state unchanged")
        return self._fail(f"currentCommunicationPoint = {current_time!r} s is not the current "
                          f"time of the FMU, {self._t!r} s (tolerance {_time_tol(self._t):g} s); step "
                          f"refused, state unchanged")

    # ------------------------------------------------------------------
    # Outputs (read from the stepper's arrays when the master asks; the shared force formulas)
    # ------------------------------------------------------------------
    def _output_getters(self) -> dict:
        s = self
        c0 = kernel_layouts.I_COUNT0
        spring, on_bit = kernel_forces.spring_damper_force, kernel_forces.force_on_bit
        contact = kernel_forces.contact_force
        overlap, kinetic = kernel_forces.overlap, kernel_forces.kinetic_friction

        def contact_force():
            y, p, mc = s._y, s._p, s._ii(kernel_layouts.I_CONTACT)
            if mc != kernel_layouts.CONTACT:
                return 0.0
            return contact(overlap(y, p), y[1] - y[3], p, mc) * s._F0

        def friction_force():
            if s._ii(kernel_layouts.I_STICK) == kernel_layouts.SLIP:
                return kinetic(s._yi(3), s._p) * s._F0
            return on_bit(s._y, s._p, s._ii(kernel_layouts.I_CONTACT)) * s._F0

        def rate_of_penetration():
            dt = s._t - s._t_start
            if dt <= 0.0:
                return 0.0
            return (s._yi(2) - s._x3_start) * s._x0 / dt

        return {
            "hammer_position": lambda: s._yi(0) * s._x0,
            "hammer_velocity": lambda: s._yi(1) * s._v0,
            "bit_position": lambda: s._yi(2) * s._x0,
            "bit_velocity": lambda: s._yi(3) * s._v0,
            "spring_force": lambda: spring(s._y, s._p) * s._F0,
            "contact_force": contact_force,
            "friction_force": friction_force,
            "rock_force": lambda: on_bit(s._y, s._p, s._ii(kernel_layouts.I_CONTACT)) * s._F0,
            "rate_of_penetration": rate_of_penetration,
            "stick_slip": lambda: s._ii(kernel_layouts.I_STICK),
            "in_contact": lambda: s._ii(kernel_layouts.I_CONTACT) != kernel_layouts.FREE,
            "impact_count": lambda: s._ii(c0 + kernel_layouts.EV_IMPACT),
            "slip_count": lambda: s._ii(c0 + kernel_layouts.EV_SLIP_START),
            "bounce_count": lambda: s._ii(c0 + kernel_layouts.EV_BOUNCE),
            "regime": lambda: int(causal_regime(*s._regime_args)),
        }

    # ------------------------------------------------------------------
    # Model description
    # ------------------------------------------------------------------
    def to_xml(self, model_options=dict()):
        """pythonfmu's description plus units, state capabilities and InitialUnknowns."""
        from xml.etree.ElementTree import Element, SubElement
        opts = dict(model_options)
        opts.setdefault("canGetAndSetFMUstate", True)
        opts.setdefault("canSerializeFMUstate", True)
        opts.setdefault("canHandleVariableCommunicationStepSize", True)
        root = super().to_xml(opts)
        # min/max of the parameters: exactly the values initialisation accepts (the other
        # parameters and the inputs at their start values)
        inputs = {v.name: getattr(self, v.name) for v in INPUTS}
        bounds = accepted_bounds(self._param_values(), lambda vals: self._accepts(vals, inputs))
        for sv in root.find("ModelVariables"):
            b = bounds.get(sv.get("name"))
            if b is not None:
                sv.find("Real").set("min", repr(b[0]))
                sv.find("Real").set("max", repr(b[1]))
        # <UnitDefinitions> goes right after <CoSimulation> (FMI 2.0 schema order)
        units = Element("UnitDefinitions")
        for uname, base in UNITS.items():
            u = SubElement(units, "Unit", {"name": uname})
            if base is not None:
                SubElement(u, "BaseUnit", {k: str(v) for k, v in base.items()})
        idx = list(root).index(root.find("CoSimulation")) + 1
        root.insert(idx, units)
        # outputs are initial="calculated": list them as InitialUnknowns too
        structure = root.find("ModelStructure")
        outputs = structure.find("Outputs")
        if outputs is not None and structure.find("InitialUnknowns") is None:
            init = SubElement(structure, "InitialUnknowns")
            for u in outputs:
                SubElement(init, "Unknown", {"index": u.get("index")})
        return root
