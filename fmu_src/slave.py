"""HammerBitRock: the FMI 2.0 co-simulation slave of the hammer-bit-rock model.

A thin :class:`pythonfmu.Fmi2Slave`: ``do_step`` reads the two inputs, calls
:meth:`Stepper.advance` (the library's adaptive hybrid integrator, every event
inside the step located) and the outputs are read straight from the stepper's
state arrays.  SI values are converted to the paper's nondimensional form with
:class:`RigParameters` / :class:`Scales`; variable names are the
:class:`RigParameters` field names wherever one exists.

Semantics (see ``docs/fmu.md``):

* **Inputs** ``preload`` and ``harmonic_force`` are held constant over a
  communication step (zero-order hold: the values set before ``fmi2DoStep``
  apply to the whole step ``[t, t + h]``).  The internal harmonic source
  ``amplitude * sin(2 pi frequency t + phase)`` is a function of time inside the
  step (no hold) and is added to ``harmonic_force``.
* **Parameters** are ``fixed`` (validated at ``fmi2ExitInitializationMode``),
  except ``tolerance`` which is ``tunable`` (validated and applied at the next
  ``fmi2DoStep``).
* **Rejections.**  pythonfmu 0.7.0 turns a Python exception into ``fmi2Fatal``
  and frees the Python object behind the instance, so no exception may leave
  this class.  Every rejected request is logged with status ``fmi2Error`` (the
  message names the variable and its value) and ``fmi2DoStep`` returns
  ``fmi2Discard`` (the only non-fatal failure status pythonfmu can return)
  with the state exactly as before the call (last successful time = the
  current communication point).
* **State.**  ``fmi2GetFMUstate`` saves the whole hidden state (stepper state:
  positions, velocities, stick/slip and contact modes, event counters, solver
  step proposal, applied inputs; plus the communication time and the
  parameters), so get-step-set-step is bit-identical.  It serialises to JSON
  (floats round-trip exactly).
"""
from __future__ import annotations

import atexit
import ctypes
import functools
import json
import math
import os
import sys

import numpy as np
from pythonfmu import Boolean, DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Slave, \
    Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

from . import kernels as K
from .params import P_B, P_FEXT, ParameterError, RigParameters
from .stepping import SolverError, SolverOptions, Stepper

__all__ = ["HammerBitRock", "PARAMETERS", "INPUTS", "OUTPUTS", "UNITS", "STATE_FORMAT", "guard_pythonfmu_exit"]

_RIG = RigParameters()          # the lab rig at the paper's Fig. 9 operating point
_INF = math.inf
_isfinite = math.isfinite


def _restore(arr, data: bytes) -> None:
    """Write a ``tobytes()`` snapshot back into ``arr`` (in place)."""
    arr[:] = np.frombuffer(data, dtype=arr.dtype)


#: Format tag of a saved FMU state (checked when a state is restored).
STATE_FORMAT = "hammerbit-fmu-state/1"

#: unit name -> SI base-unit exponents (FMI 2.0 <UnitDefinitions>); None: no base unit
UNITS = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "s/m": {"s": 1, "m": -1},
    "Hz": {"s": -1},
    "rad": {"rad": 1},
    "s": {"s": 1},
    "1": {},
    "N/m^n": None,   # Hunt-Crossley stiffness: the exponent n is a parameter
}

#: Real parameters: (name, unit, description).  Names are RigParameters fields
#: where one exists; start values are the ``lab`` preset (RigParameters()).
PARAMETERS = (
    ("hammer_mass", "kg", "m1, mass of the hammer (drillstring side); > 0"),
    ("bit_mass", "kg", "m2, mass of the bit/slider (rock side); > 0"),
    ("stiffness", "N/m", "K, stiffness of the spring joining hammer and bit; > 0"),
    ("damping", "N.s/m", "C, viscous damping between hammer and bit; >= 0"),
    ("mu_static", "1", "mu_e, static friction coefficient of the bit on the rock; > 0"),
    ("mu_kinetic", "1", "mu_d, kinetic friction coefficient at high speed; 0 < mu_d <= mu_e"),
    ("friction_decay", "s/m", "gamma, velocity-weakening decay of the kinetic friction; >= 0"),
    ("normal_force", "N", "F_N, normal force of the bit on the rock; static threshold F0 = mu_e F_N; > 0"),
    ("contact_stiffness", "N/m^n", "Kc, Hunt-Crossley contact stiffness [N/m^n, n = contact_exponent]; >= 0"),
    ("contact_exponent", "1", "n, Hunt-Crossley exponent; 0 < n <= 5"),
    ("contact_damping", "s/m", "lam, Hunt-Crossley damping; >= 0"),
    ("gap", "m", "R, hammer-bit gap that closes before an impact; used only when impact_enabled; >= 0"),
    ("amplitude", "N", "A, amplitude of the internal harmonic source A sin(2 pi f t + phase) on the "
                       "hammer, added to the input harmonic_force; >= 0"),
    ("frequency", "Hz", "f, frequency of the internal harmonic source; > 0"),
    ("phase", "rad", "phase of the internal harmonic source at t = 0"),
    ("initial_hammer_position", "m", "hammer position x_b at the start time (velocities start at 0)"),
    ("initial_bit_position", "m", "bit position x_s at the start time; penetration is measured from it"),
    ("tolerance", "1", "relative tolerance of the adaptive solver (DOP853; absolute tolerance "
                       "1e-2 * tolerance in the length scale F0/K); tunable"),
)
_FIXED_REALS = tuple(n for n, _, _ in PARAMETERS if n != "tolerance")
_RIG_FIELDS = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
               "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
               "contact_damping", "amplitude", "frequency", "phase")
_BOOL_PARAMETERS = (
    ("impact_enabled", "true: the hammer closes the gap and impacts the bit (Hunt-Crossley contact); "
                       "false: no impact device (R = infinity)"),
)

_DEFAULT_GAP = 0.84 * _RIG.scales.length     # the paper's Fig. 12 gap r = 0.84 (impact off by default)
_DEFAULT_TOL = 1e-8

#: Real inputs: (name, unit, start, description)
INPUTS = (
    ("preload", "N", _RIG.preload,
     "B, weight on bit pushing the hammer toward the rock; held over each communication step"),
    ("harmonic_force", "N", 0.0,
     "F_h, instantaneous external harmonic force on the hammer; held over each communication step "
     "(zero-order hold) and added to the internal source"),
)

#: Outputs: (name, type, unit, description)
OUTPUTS = (
    ("hammer_position", "Real", "m", "x_b, hammer position (drilling direction positive)"),
    ("hammer_velocity", "Real", "m/s", "v_b, hammer velocity"),
    ("bit_position", "Real", "m", "x_s, bit position: the penetration (from the start time on)"),
    ("bit_velocity", "Real", "m/s", "v_s, bit velocity (>= 0: the bit only moves forward)"),
    ("spring_force", "Real", "N", "F_k = K (x_b - x_s) + C (v_b - v_s), spring and damper force on the bit"),
    ("contact_force", "Real", "N", "F_c, Hunt-Crossley impact force of the hammer on the bit (0 when free)"),
    ("friction_force", "Real", "N", "friction of the rock on the bit, positive against drilling: "
                                    "F_N (mu_d + (mu_e - mu_d) exp(-gamma v_s)) in slip, the static "
                                    "reaction F_d in stick"),
    ("rock_force", "Real", "N", "F_d = F_k + F_c, the force the bit drives into the rock"),
    ("rate_of_penetration", "Real", "m/s", "mean rate of penetration since the start time, "
                                           "(x_s - x_s(t_start)) / (t - t_start)"),
    ("stick_slip", "Integer", None, "bit state: 0 stick, 1 slip"),
    ("in_contact", "Boolean", None, "true while the hammer is in contact with the bit (gap closed)"),
    ("impact_count", "Integer", None, "number of impacts (gap closures) since the start time"),
    ("slip_count", "Integer", None, "number of stick-to-slip transitions since the start time"),
    ("bounce_count", "Integer", None, "number of bit-bounce violations (F_d < -F_s while stuck: the "
                                      "rock would have to pull the bit back; the bit is held)"),
)


# ---------------------------------------------------------------------------
# pythonfmu 0.7.0 exit-time double free (Linux, Python host)
# ---------------------------------------------------------------------------
_PINNED_WRAPPERS = {}   # path of a loaded pythonfmu wrapper library -> its finalizePythonInterpreter


def _release_wrappers():
    for finalize in _PINNED_WRAPPERS.values():
        finalize()


def guard_pythonfmu_exit(resources) -> None:
    """Work around a use-after-free in pythonfmu 0.7.0's native wrapper at process exit.

    The wrapper keeps a static ``std::shared_ptr<PyState>`` and also resets it
    from a ``__attribute__((destructor))`` function.  At exit the C++ static
    destructor runs first and the destructor function then releases the freed
    control block a second time: glibc later aborts ("corrupted double-linked
    list") or the heap is silently corrupted.  Resetting the pointer from a
    Python ``atexit`` hook (which runs first) makes both later calls no-ops.

    Only when the host *is* Python (then the wrapper's interpreter thread did
    nothing).  In a native host the wrapper owns the interpreter and runs
    Python's atexit hooks from inside that destructor, so nothing is done.
    The library is opened once more here so that it stays mapped until exit.
    """
    if not sys.platform.startswith("linux") or not resources:
        return
    try:
        if os.path.realpath("/proc/self/exe") != os.path.realpath(sys.executable or ""):
            return
        bindir = os.path.join(os.path.dirname(os.path.abspath(str(resources).rstrip("/"))),
                              "binaries", "linux64")
        for name in sorted(os.listdir(bindir)):
            path = os.path.join(bindir, name)
            if not name.endswith(".so") or path in _PINNED_WRAPPERS:
                continue
            finalize = ctypes.CDLL(path).finalizePythonInterpreter
            finalize.argtypes = []
            finalize.restype = None
            if not _PINNED_WRAPPERS:
                atexit.register(_release_wrappers)
            _PINNED_WRAPPERS[path] = finalize
    except Exception:  # not a pythonfmu wrapper, no /proc ...: nothing to guard
        pass


class _RealWithUnit(Real):
    """pythonfmu ``Real`` that also writes the ``unit`` attribute."""

    def __init__(self, name, unit=None, **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self):
        node = super().to_xml()
        if self.unit is not None:
            node.find("Real").set("unit", self.unit)
        return node


_KIND = {Real: Real, _RealWithUnit: Real, Integer: Integer, Boolean: Boolean}


class HammerBitRock(Fmi2Slave):
    """Hammer-bit-rock model of Franca & Weber (2004) as an FMI 2.0 co-simulation slave."""

    author = "hammerbit project"
    description = ("Resonance hammer drilling (Franca & Weber 2004): hammer, bit, spring-damper, "
                   "velocity-weakening dry friction on the rock, optional Hunt-Crossley impact; "
                   "hybrid stick/slip and contact events located inside every step")
    version = "0.1.0"
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3,
                                           tolerance=_DEFAULT_TOL)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # -- parameters (start values: the lab preset) -----------------------
        for name in _RIG_FIELDS:
            setattr(self, name, float(getattr(_RIG, name)))
        self.gap = _DEFAULT_GAP
        self.impact_enabled = False
        self.initial_hammer_position = 0.0
        self.initial_bit_position = 0.0
        self.tolerance = _DEFAULT_TOL
        # -- inputs ------------------------------------------------------------
        for name, _unit, start, _desc in INPUTS:
            setattr(self, name, float(start))
        # -- private state -------------------------------------------------------
        self._t_start = 0.0        # start time [s] (fmi2SetupExperiment)
        self._t = 0.0              # current communication point [s]
        self._ready = False        # exit_initialization_mode succeeded
        self._error = "the FMU is not initialised (call fmi2ExitInitializationMode first)"
        self._dirty = False        # a parameter was set since the last commit
        self._slow = True          # do_step must take the slow path (not ready, or dirty)
        self._committed = None     # dict of the validated parameter values in use
        self._commit(self._param_values(), warm_up=False)
        self._ready = False

        for name, unit, _start, desc in INPUTS:
            self.register_variable(_RealWithUnit(name, unit, causality=Fmi2Causality.input,
                                                 variability=Fmi2Variability.continuous,
                                                 description=desc))
        for name, unit, desc in PARAMETERS:
            var = _RealWithUnit(name, unit, causality=Fmi2Causality.parameter,
                                variability=(Fmi2Variability.tunable if name == "tolerance"
                                             else Fmi2Variability.fixed),
                                initial=Fmi2Initial.exact, description=desc,
                                setter=self._param_setter(name))
            self.register_variable(var)
        for name, desc in _BOOL_PARAMETERS:
            self.register_variable(Boolean(name, causality=Fmi2Causality.parameter,
                                           variability=Fmi2Variability.fixed,
                                           initial=Fmi2Initial.exact, description=desc,
                                           setter=self._param_setter(name)))
        getters = self._output_getters()
        for name, typ, unit, desc in OUTPUTS:
            kw = dict(causality=Fmi2Causality.output, initial=Fmi2Initial.calculated,
                      description=desc, getter=getters[name])
            if typ == "Real":
                var = _RealWithUnit(name, unit, variability=Fmi2Variability.continuous, **kw)
            elif typ == "Integer":
                var = Integer(name, variability=Fmi2Variability.discrete, **kw)
            else:
                var = Boolean(name, variability=Fmi2Variability.discrete, **kw)
            self.register_variable(var)
        # value reference -> getter / setter, by type (the fast paths of fmi2Get/Set*)
        self._getters = {t: {} for t in (Real, Integer, Boolean)}
        self._setters = {t: {} for t in (Real, Integer, Boolean)}
        for vr, var in self.vars.items():
            self._getters[_KIND[type(var)]][vr] = var.getter
            if var.setter is not None:
                self._setters[_KIND[type(var)]][vr] = var.setter
            if var.causality == Fmi2Causality.input:        # plain attributes: C-level setter
                self._setters[Real][vr] = functools.partial(self.__dict__.__setitem__, var.name)
        self._real_get = self._getters[Real]
        self._real_set = self._setters[Real]
        guard_pythonfmu_exit(self.resources)

    # ------------------------------------------------------------------
    # fmi2Get*/fmi2Set*: dictionary lookups; never raise into the C wrapper
    # ------------------------------------------------------------------
    def _bad_access(self, what, vrs, e) -> None:
        self._log_error(f"{what}: invalid access to value references {list(vrs)!r}: {e!r}; "
                        f"nothing changed")

    def get_real(self, vrs):
        g = self._real_get
        try:
            if len(vrs) == 1:
                return [g[vrs[0]]()]
            return [g[vr]() for vr in vrs]     # getters return numbers; the wrapper converts
        except Exception as e:
            self._bad_access("fmi2GetReal", vrs, e)
            return [math.nan] * len(vrs)

    def set_real(self, vrs, values):
        s = self._real_set
        if len(vrs) == 1:
            f = s.get(vrs[0])
            if f is not None:
                f(values[0])
                return
        try:
            setters = [s[vr] for vr in vrs]
        except Exception as e:
            return self._bad_access("fmi2SetReal (not a settable Real)", vrs, e)
        for f, v in zip(setters, values):
            f(v)

    def _get_other(self, kind, conv, vrs, what):
        g = self._getters[kind]
        try:
            return [conv(g[vr]()) for vr in vrs]
        except Exception as e:
            self._bad_access(what, vrs, e)
            return [conv(0)] * len(vrs)

    def _set_other(self, kind, conv, vrs, values, what):
        s = self._setters[kind]
        try:
            pairs = [(s[vr], conv(v)) for vr, v in zip(vrs, values)]
        except Exception as e:
            return self._bad_access(what, vrs, e)
        for f, v in pairs:
            f(v)

    def get_integer(self, vrs):
        return self._get_other(Integer, int, vrs, "fmi2GetInteger")

    def get_boolean(self, vrs):
        return self._get_other(Boolean, bool, vrs, "fmi2GetBoolean")

    def get_string(self, vrs):
        self._bad_access("fmi2GetString (the model has no String variables)", vrs, KeyError(list(vrs)))
        return [""] * len(vrs)

    def set_integer(self, vrs, values):
        self._set_other(Integer, int, vrs, values, "fmi2SetInteger")

    def set_boolean(self, vrs, values):
        self._set_other(Boolean, bool, vrs, values, "fmi2SetBoolean")

    def set_string(self, vrs, values):
        self._bad_access("fmi2SetString (the model has no String variables)", vrs, KeyError(list(vrs)))

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

    # ------------------------------------------------------------------
    # Parameters
    # ------------------------------------------------------------------
    def _param_setter(self, name):
        def setter(value):
            setattr(self, name, value)
            self._dirty = True
            self._slow = True
        return setter

    def _param_values(self) -> dict:
        vals = {name: getattr(self, name) for name in _FIXED_REALS}
        vals["impact_enabled"] = bool(self.impact_enabled)
        vals["tolerance"] = self.tolerance
        return vals

    @staticmethod
    def _validate(vals: dict):
        """RigParameters and SolverOptions of ``vals``; ParameterError if one is invalid."""
        for name, v in vals.items():
            if name == "impact_enabled":
                continue
            try:
                f = float(v)
            except (TypeError, ValueError):
                raise ParameterError(name, v, "a real number") from None
            if not _isfinite(f):
                raise ParameterError(name, v, "a finite number")
        rig_kw = {name: float(vals[name]) for name in _RIG_FIELDS}
        rig_kw["gap"] = float(vals["gap"]) if vals["impact_enabled"] else _INF
        if not vals["impact_enabled"]:
            # the gap is unused but must still be a sensible number
            g = float(vals["gap"])
            if g < 0.0:
                raise ParameterError("gap", vals["gap"], "[0, 1e+09]")
        # the preload is an input, applied at every step; 0 here only fills the dataclass
        rig = RigParameters(preload=0.0, **rig_kw)
        tol = float(vals["tolerance"])
        if not (1e-14 <= tol <= 1e-2):
            raise ParameterError("tolerance", vals["tolerance"], "[1e-14, 0.01]")
        solver = SolverOptions(rtol=tol, atol=1e-2 * tol)
        for name in ("initial_hammer_position", "initial_bit_position"):
            if abs(float(vals[name])) > 1e6:
                raise ParameterError(name, vals[name], "[-1e+06, 1e+06] m")
        return rig, solver

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
        st = Stepper(groups, solver=solver, y0=y0)   # inputs enter p at every step
        if keep_state is not None:
            st.set_state(keep_state)
        # only now change the instance (nothing above touched it)
        self._st = st
        self._y, self._ist, self._p = st.y, st.istate, st.p      # updated in place by the stepper
        self._yi, self._ii = st.y.item, st.istate.item
        self._rig = rig
        self._x0 = x0
        self._v0 = s.velocity
        self._F0 = s.friction_force
        self._omega = s.omega
        self._two_xi = 2.0 * groups.xi
        self._x3_start = y0[2]
        self._committed = dict(vals)
        self._dirty = False
        self._applied_preload = math.nan       # inputs last written into st.p (NaN: none yet)
        self._applied_force = math.nan
        if warm_up:
            # first call of the kernels: compile them, or load them from the numba cache, now
            # rather than in the first fmi2DoStep (the state is put back exactly)
            saved = st.get_state()
            st.advance(st.time)
            st.set_state(saved)
            mc = st.istate[K.I_CONTACT]
            K.force_on_bit(st.y, st.p, mc)
            K.contact_force(st.y[0], st.y[1], st.p, mc)
            K.kinetic_friction(st.y[3], st.p)

    def _apply_parameter_changes(self) -> bool:
        """A parameter was set after initialisation: apply tunables, refuse fixed ones."""
        vals = self._param_values()
        old = self._committed
        for name in _FIXED_REALS + ("impact_enabled",):
            if vals[name] != old[name]:
                setattr(self, name, old[name])       # keep the committed value
                return self._reject(f"parameter {name!r} = {vals[name]!r} was set after "
                                    f"initialisation, but it is fixed (causality=parameter, "
                                    f"variability=fixed); the value {old[name]!r} stays in use")
        if vals["tolerance"] != old["tolerance"]:
            try:
                self._commit(vals, warm_up=False, keep_state=self._st.get_state())
            except ParameterError as e:
                self.tolerance = old["tolerance"]
                return self._reject(f"invalid tunable parameter: {e}")
        self._dirty = False
        return True

    # ------------------------------------------------------------------
    # FMI life cycle
    # ------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        try:
            if _isfinite(start_time):
                self._t_start = float(start_time)
                self._t = float(start_time)
            else:
                self._log_error(f"start time {start_time!r} is not finite; 0 is used")
            if tolerance is not None and tolerance > 0.0:
                self.tolerance = float(tolerance)
        except Exception as e:  # never let an exception reach the C wrapper
            self._log_error(f"setup_experiment failed: {e!r}")

    def exit_initialization_mode(self):
        try:
            self._commit(self._param_values())
            self._t = self._t_start
            self._ready = True
            self._slow = True
            self._error = None
        except ParameterError as e:
            self._ready = False
            self._error = f"initialisation failed: invalid {e}"
            self._log_error(self._error + "; every fmi2DoStep will be refused")
        except Exception as e:
            self._ready = False
            self._error = f"initialisation failed: {e!r}"
            self._log_error(self._error)

    def _log_error(self, message: str) -> None:
        # the FMI logger treats the message as a printf format: escape '%'
        self.log(message.replace("%", "%%"), Fmi2Status.error)

    def _reject(self, message: str) -> bool:
        self._log_error(message)
        return False

    def do_step(self, current_time, step_size):
        try:
            if self._slow and not self._prepare_step():
                return False
            t = self._t
            if not (0.0 < step_size < _INF) or (
                    current_time != t and not abs(current_time - t) <= 1e-9 * max(abs(t), step_size)):
                return self._reject_step(current_time, step_size)
            preload = self.preload
            fh = self.harmonic_force
            st = self._st
            y, ist, fst, p = self._y, self._ist, st.fstate, self._p
            # snapshot of the state at the step start (bytes: the cheapest copy numpy makes)
            snap = (y.tobytes(), ist.tobytes(), fst.tobytes())
            old_inputs = None
            if preload != self._applied_preload or fh != self._applied_force:
                if not (_isfinite(preload) and _isfinite(fh)):
                    bad = "preload" if not _isfinite(preload) else "harmonic_force"
                    return self._reject(f"input {bad!r} = {getattr(self, bad)!r} N is not finite; "
                                        f"step refused, state unchanged")
                old_inputs = (p[P_B], p[P_FEXT], self._applied_preload, self._applied_force)
                p[P_B] = preload / self._F0          # exactly as RigParameters.to_groups()
                p[P_FEXT] = fh / self._F0
                self._applied_preload = preload
                self._applied_force = fh
            tau_end = (current_time + step_size - self._t_start) * self._omega
            try:
                st.advance(tau_end)
            except Exception as e:
                _restore(y, snap[0])
                _restore(ist, snap[1])
                _restore(fst, snap[2])
                if old_inputs is not None:
                    p[P_B], p[P_FEXT], self._applied_preload, self._applied_force = old_inputs
                kind = "solver failure" if isinstance(e, SolverError) else f"failure ({e!r})"
                return self._reject(f"{kind} in the step from t = {current_time!r} s with "
                                    f"h = {step_size!r} s: {e}; state restored to t = {current_time!r} s")
            self._t = current_time + step_size
            return True
        except Exception as e:  # never let an exception reach the C wrapper
            return self._reject(f"fmi2DoStep failed: {e!r}")

    def _prepare_step(self) -> bool:
        """Slow path of do_step: not initialised, or a parameter was set."""
        if not self._ready:
            return self._reject(f"fmi2DoStep refused: {self._error}")
        if self._dirty and not self._apply_parameter_changes():
            return False
        self._slow = False
        return True

    def _reject_step(self, current_time, step_size) -> bool:
        if not (0.0 < step_size < _INF):
            return self._reject(f"communication step size h = {step_size!r} s is invalid: "
                                f"it must be > 0 and finite; step refused, state unchanged")
        return self._reject(f"currentCommunicationPoint = {current_time!r} s is not the current "
                            f"time of the FMU, {self._t!r} s; step refused, state unchanged")

    # ------------------------------------------------------------------
    # Outputs (read from the stepper's arrays when the master asks)
    # ------------------------------------------------------------------
    def _contact(self) -> float:
        ist = self._ist
        mc = ist[K.I_CONTACT]
        if mc != K.CONTACT:
            return 0.0
        y, p = self._y, self._p
        return K.contact_force(y[0] - y[2] - p[K.P_R], y[1] - y[3], p, mc) * self._F0

    def _drive(self) -> float:
        return K.force_on_bit(self._y, self._p, self._ist[K.I_CONTACT]) * self._F0

    def _friction(self) -> float:
        if self._ist[K.I_STICK] == K.SLIP:
            return K.kinetic_friction(self._y[3], self._p) * self._F0
        return self._drive()

    def _rop(self) -> float:
        dt = self._t - self._t_start
        if dt <= 0.0:
            return 0.0
        return (self._yi(2) - self._x3_start) * self._x0 / dt

    def _spring(self) -> float:
        yi = self._yi
        return ((yi(0) - yi(2)) + self._two_xi * (yi(1) - yi(3))) * self._F0

    def _output_getters(self) -> dict:
        # Python floats/ints from the stepper's arrays (bound in _commit; the stepper updates
        # them in place), converted on demand: do_step itself computes no output.
        s = self
        c0 = K.I_COUNT0
        return {
            "hammer_position": lambda: s._yi(0) * s._x0,
            "hammer_velocity": lambda: s._yi(1) * s._v0,
            "bit_position": lambda: s._yi(2) * s._x0,
            "bit_velocity": lambda: s._yi(3) * s._v0,
            "spring_force": s._spring,
            "contact_force": s._contact,
            "friction_force": s._friction,
            "rock_force": s._drive,
            "rate_of_penetration": s._rop,
            "stick_slip": lambda: s._ii(K.I_STICK),
            "in_contact": lambda: s._ii(K.I_CONTACT) != K.FREE,
            "impact_count": lambda: s._ii(c0 + K.EV_IMPACT),
            "slip_count": lambda: s._ii(c0 + K.EV_SLIP_START),
            "bounce_count": lambda: s._ii(c0 + K.EV_BOUNCE),
        }

    # ------------------------------------------------------------------
    # FMU state
    # ------------------------------------------------------------------
    def _get_fmu_state(self):
        try:
            return {
                "format": STATE_FORMAT,
                "stepper": self._st.get_state(),
                "committed": dict(self._committed),
                "params": self._param_values(),
                "inputs": (float(self.preload), float(self.harmonic_force)),
                "t": self._t,
                "t_start": self._t_start,
                "ready": self._ready,
                "error": self._error,
            }
        except Exception as e:
            self._log_error(f"fmi2GetFMUstate failed: {e!r}")
            return {"format": "invalid", "reason": repr(e)}

    def _set_fmu_state(self, state):
        try:
            if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
                reason = state.get("reason") if isinstance(state, dict) else None
                self._log_error(f"fmi2SetFMUstate: not a {STATE_FORMAT} state"
                         + (f" ({reason})" if reason else "") + "; state unchanged")
                return
            arr = np.asarray(state["stepper"], dtype=np.float64)
            if arr.shape != self._st.get_state().shape:
                self._log_error(f"fmi2SetFMUstate: stepper state of length {arr.shape} does not fit; "
                         f"state unchanged")
                return
            committed = state["committed"]
            t_start_old = self._t_start
            self._t_start = float(state["t_start"])
            try:
                if committed != self._committed or self._t_start != t_start_old:
                    self._commit(committed, warm_up=False, keep_state=arr)
                else:
                    self._st.set_state(arr)
                    self._applied_preload = self._applied_force = math.nan
            except Exception:
                self._t_start = t_start_old
                raise
            for name, v in state["params"].items():
                setattr(self, name, v)
            self._dirty = state["params"] != committed
            self._slow = True
            self.preload, self.harmonic_force = state["inputs"]
            self._t = float(state["t"])
            self._ready = bool(state["ready"])
            self._error = state["error"]
        except Exception as e:
            self._log_error(f"fmi2SetFMUstate failed: {e!r}; state unchanged")

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        s = dict(state)
        if "stepper" in s:
            s["stepper"] = [float(v) for v in s["stepper"]]
        return json.dumps(s).encode("utf-8")

    @staticmethod
    def _fmu_state_from_bytes(data: bytes):
        try:
            s = json.loads(bytes(data).decode("utf-8"))
            if not isinstance(s, dict):
                raise ValueError("not a JSON object")
            if "inputs" in s:
                s["inputs"] = tuple(s["inputs"])
            return s
        except Exception as e:  # never raise into the C wrapper
            return {"format": "invalid", "reason": f"cannot deserialise the FMU state: {e!r}"}
