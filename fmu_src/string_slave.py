"""Drillstring: the FMI 2.0 co-simulation slave of the linear drillstring with its hammer interface.

The string (built from a TOML description at build time, its arrays in
``resources/string_model.npz``) and the interface spring-dashpot to the
hammer are stepped exactly over any communication step ``h > 0`` by
:mod:`string_step`, the same code as the co-simulation master's string side:
the built steps (``steps`` of ``resources/string_info.json``) with scipy's
exponentials, any other with those of :class:`~string_step.StepTable` (the
kernels the native flavour runs).

Causality (see ``docs/cosim.md``):

* **Inputs** ``hammer_position`` [m] and ``hammer_velocity`` [m/s]: the
  hammer's motion at the start of the step.  Over the step the FMU uses the
  polynomial extrapolated through its last three inputs (order
  ``extrapolation``), as the master's Jacobi scheme does.  The first step
  from the start time takes the hammer at rest at ``hammer_position_at_rest``
  (the system starts in static equilibrium; a master may not have set the
  inputs yet, FMPy's SSP runner sets every connector to 0).
* **Outputs** at the end of a step depend on the state only (no direct
  feedthrough): ``interface_force`` (the force on the hammer at the
  communication point, with the extrapolated hammer motion), ``held_force``
  (its mean over the next step of the same length, extrapolated through the
  last three communication points: what the hammer should hold),
  ``held_force_change`` (``held_force - wob``: wire it to the hammer's
  ``harmonic_force`` with the hammer's ``preload`` at ``wob``, so a
  zero-initialised connector is the equilibrium), and at the top
  ``hook_load``, ``top_position``, ``top_velocity``.
* **Parameters** (fixed): ``damping_ratio`` of every string mode, ``wob`` of
  the static equilibrium, ``hammer_position_at_rest``, ``extrapolation``, and
  the top: ``top_condition`` (0 fixed hook, 1 constant feed at
  ``feed_velocity``, 2 auto-driller with ``proportional_gain`` and
  ``integral_gain``, a PI controller on the hook load holding ``wob``).  The
  geometry is fixed at build time (constants and the description).

Bad parameters are refused at ``fmi2ExitInitializationMode`` and bad inputs
at ``fmi2DoStep`` with an error logged naming the variable, its value and the
allowed range; every refused step leaves the state unchanged.
"""
from __future__ import annotations

import math

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer, \
    Real
from pythonfmu.enums import Fmi2Status

from .pythonfmu_exit import guard_pythonfmu_exit
from .fmu_description import (FMI2_TYPE, STRING_VARIABLES, TOP_CONDITIONS, string_description_fields,
                               top_condition, top_conditions_text)
from .string_model import OUTPUT_ROWS, form_of, load_model, string_matrices
from .numba_dispatch import entry_point
from .string_kernels import (EXCHANGE_HELD, HAMMER_ARG, DenseForm, ExchangeHistory, ExchangeScheme, HammerStep,
                             Interface, ModalForm, exchange_kernel)
from .string_step import BUILT_STEPS, STEP_CACHE, ExactStep, StepTable, StringState

__all__ = ["Drillstring", "INPUT_LIMIT"]

#: largest input magnitude accepted (position [m], velocity [m/s])
INPUT_LIMIT = 1e6
#: largest feed velocity accepted [m/s] (1000 m/h, as the library's top conditions)
MAX_FEED = 1000.0 / 3600.0
#: largest auto-driller gain accepted (SI: m/s per N, m/s per N s), as the library's
MAX_GAIN = 1.0
#: rows of the string side's outputs
ROW_HOOK, ROW_TOP_U, ROW_TOP_V = (OUTPUT_ROWS.index(r) for r in ("hook_tension", "top_position", "top_velocity"))
#: the extrapolation orders of the hammer motion and the held force
ORDERS = (0, 1, 2)
#: relative tolerance on the communication point (a master computing t0 + n h is fine)
TIME_TOLERANCE = 1e-9


class Drillstring(Fmi2Slave):
    """The linear drillstring and its hammer interface, stepped exactly (FMI 2.0 co-simulation)."""

    author = "hammerbit project"
    version = "0.1.0"
    license = "MIT"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=2.0, step_size=1e-3)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        guard_pythonfmu_exit(self.resources)     # pythonfmu 0.7.0's double free at exit
        self._arrays, self._info = load_model(str(self.resources))
        sc = self._info["scalars"]
        self.description = self._info.get("description", "")
        self.damping_ratio = sc["damping_ratio"]
        self.wob = sc["wob"]
        self.hammer_position_at_rest = float(self._info["hammer_position_at_rest"])
        self.extrapolation = 2
        self.top_condition = int(self._info["top_condition"])
        self.feed_velocity = float(self._info["feed_velocity"])
        self.proportional_gain = float(self._info["proportional_gain"])
        self.integral_gain = float(self._info["integral_gain"])
        self.hammer_position = self.hammer_position_at_rest
        self.hammer_velocity = 0.0
        self.interface_force = sc["wob"]
        self.held_force = sc["wob"]
        self.held_force_change = 0.0
        self.hook_load = sc["hook_load"]
        self.top_position = 0.0
        self.top_velocity = 0.0
        self.string_length = float(self._info["length_m"])
        self.interface_stiffness = sc["interface_stiffness"]
        self.interface_damping = sc["interface_damping"]
        self.buoyed_weight = sc["buoyed_weight"]
        self.string_states = int(sc["string_states"])
        # the steps whose exponentials are the build's (scipy); any other: the kernels', cached
        self._built = tuple(float(h) for h in self._info.get("steps", BUILT_STEPS))
        self._t = 0.0
        self._t_start = 0.0
        self._ready = False
        self._error = "not initialised (fmi2ExitInitializationMode)"
        self._register()

    # -- variables -------------------------------------------------------------
    def _register(self) -> None:
        """Register :data:`~.fmu_description.STRING_VARIABLES`, in their order (the value references)."""
        fields = string_description_fields(self.buoyed_weight, MAX_FEED)
        kind = {"parameter": dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed),
                "input": dict(causality=Fmi2Causality.input, variability=Fmi2Variability.continuous),
                "output": dict(causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                               initial=Fmi2Initial.calculated),
                "local": dict(causality=Fmi2Causality.local, variability=Fmi2Variability.constant)}
        for v in STRING_VARIABLES:
            var_type = Real if FMI2_TYPE[v.type] == "Real" else Integer
            self.register_variable(var_type(v.name, description=v.description.format(**fields), **kind[v.causality]))

    def to_xml(self, model_options=dict()):
        """pythonfmu's description; outputs declare no direct dependency on the inputs."""
        from xml.etree.ElementTree import SubElement  # noqa: PLC0415
        root = super().to_xml(model_options)
        root.set("description", self.description)
        for sv in root.find("ModelVariables"):
            real = sv.find("Real")
            if real is not None and real.get("start") is not None:
                # pythonfmu writes 16 significant digits, which do not always read back as the value
                real.set("start", repr(float(getattr(self, sv.get("name")))))
        structure = root.find("ModelStructure")
        outputs = structure.find("Outputs")
        if outputs is not None:
            for u in outputs:
                u.set("dependencies", "")
            if structure.find("InitialUnknowns") is None:
                init = SubElement(structure, "InitialUnknowns")
                for u in outputs:
                    SubElement(init, "Unknown", {"index": u.get("index"), "dependencies": ""})
        return root

    # -- errors ------------------------------------------------------------------
    def _fail(self, message: str) -> bool:
        self.log(message, Fmi2Status.error)
        return False

    def _check_parameters(self) -> "str | None":
        """The first bad parameter as a message naming it, its value and the allowed range; None if fine."""
        checks = (("damping_ratio", self.damping_ratio, 0.0, 1.0, "[0, 1)"),
                  ("wob", self.wob, 0.0, self.buoyed_weight * (1.0 + 1e-12),
                   f"[0, {self.buoyed_weight:.6g}] N (the buoyed weight)"),
                  ("hammer_position_at_rest", self.hammer_position_at_rest, -INPUT_LIMIT, INPUT_LIMIT,
                   f"[-{INPUT_LIMIT:g}, {INPUT_LIMIT:g}] m"))
        for name, value, lo, hi, text in checks:
            v = float(value)
            ok = math.isfinite(v) and lo <= v and (v < hi if name == "damping_ratio" else v <= hi)
            if not ok:
                return f"parameter {name!r} = {value!r} is out of range: allowed {text}"
        if int(self.extrapolation) not in ORDERS:
            return f"parameter 'extrapolation' = {self.extrapolation!r} is out of range: allowed 0, 1, 2"
        if not 0 <= int(self.top_condition) < len(TOP_CONDITIONS):
            return (f"parameter 'top_condition' = {self.top_condition!r} is out of range: allowed "
                    f"{top_conditions_text()}")
        v = float(self.feed_velocity)
        if not (math.isfinite(v) and abs(v) <= MAX_FEED):
            return (f"parameter 'feed_velocity' = {self.feed_velocity!r} is out of range: allowed "
                    f"[-{MAX_FEED:.4g}, {MAX_FEED:.4g}] m/s (1000 m/h)")
        if v != 0.0 and not top_condition(int(self.top_condition)).takes_feed:
            feeds = top_conditions_text([t for t in TOP_CONDITIONS if t.takes_feed])
            return (f"parameter 'feed_velocity' = {self.feed_velocity!r}: only top_condition = {feeds} takes "
                    f"a feed velocity; allowed 0 with top_condition = {int(self.top_condition)}")
        for name in ("proportional_gain", "integral_gain"):
            g = float(getattr(self, name))
            if not (math.isfinite(g) and 0.0 <= g <= MAX_GAIN):
                return f"parameter {name!r} = {getattr(self, name)!r} is out of range: allowed [0, {MAX_GAIN:g}]"
        if form_of(self.top_condition) not in self._arrays["forms"]:
            return (f"parameter 'top_condition' = {self.top_condition!r}: this string has no auto-driller "
                    f"({self._info.get('auto_driller_refused')}); allowed "
                    f"{top_conditions_text([t for t in TOP_CONDITIONS if t.form != 'auto'])}")
        return None

    # -- FMU states: not supported (canGetAndSetFMUstate is false) ------------------------
    # pythonfmu's default saves the variables only, not the string's state: a state restored from
    # it would go on from a wrong string state.  The native front refuses every state call of an
    # FMU that declares no states (fmi2Error); without the front (pythonfmu's binary alone, which
    # returns OK whatever the slave says) these log an error and change nothing.
    _NO_STATES = ("FMU states are not supported by the pythonfmu Drillstring.fmu "
                  "(canGetAndSetFMUstate is false; the native flavour supports them)")

    def _get_fmu_state(self):
        self._fail(f"fmi2GetFMUstate: {self._NO_STATES}")
        return {"format": "unsupported"}

    def _set_fmu_state(self, state):
        self._fail(f"fmi2SetFMUstate: {self._NO_STATES}; state unchanged")

    @classmethod
    def _fmu_state_from_bytes(cls, data: bytes):
        return {"format": "unsupported"}

    # -- life cycle ----------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        if math.isfinite(start_time):
            self._t_start = self._t = float(start_time)

    def exit_initialization_mode(self):
        bad = self._check_parameters()
        if bad is not None:
            self._ready = False
            self._error = f"initialisation failed: {bad}"
            self._fail(self._error)
            return
        values = {"damping_ratio": float(self.damping_ratio), "proportional_gain": float(self.proportional_gain),
                  "integral_gain": float(self.integral_gain)}
        A1, E, frow, rows = string_matrices(self._arrays, form_of(self.top_condition), values)
        sc = self._info["scalars"]
        self._W = float(self.wob)
        self._hook_eq = sc["buoyed_weight"] - self._W
        feed = float(self.feed_velocity) if top_condition(int(self.top_condition)).takes_feed else 0.0
        self._side = ExactStep(A1, E, frow, sc["interface_stiffness"], sc["interface_damping"], rows,
                               self._hook_eq, feed=(feed, self._t_start))
        self._order = int(self.extrapolation)
        self._state = None                        # made at the first step
        self._table = None
        self._hist = np.zeros(16)
        self._th, self._wh = self._hist[0:3], self._hist[3:9].reshape(3, 2)
        self._Fh, self._sc = self._hist[9:12], self._hist[12:16]
        # the string moves with a feed's block from the start, the hammer rests: the interface dashpot
        F0 = self._W + sc["interface_damping"] * feed
        self._Fh[:] = F0
        self._sc[0] = F0
        self._xhist = ExchangeHistory(self._th, self._wh, self._Fh, self._sc, np.zeros(6))
        self._calls = {}                          # step length -> [kernel or its entry point, its arguments, kernel]
        self._scheme = ExchangeScheme(False, self._order, True)   # the master's Jacobi exchange, fmi form
        self._iface = Interface(self._side.ki, self._side.ci, self._W, self._side.feed)
        self._F_held = F0
        self._t = self._t_start
        self._ready = True
        self._error = None
        self._set_outputs()

    def terminate(self):
        self._ready = False
        self._error = "terminated (fmi2Terminate)"

    # -- stepping --------------------------------------------------------------------
    def do_step(self, current_time, step_size):
        try:
            return self._do_step(float(current_time), float(step_size))
        except Exception as e:  # noqa: BLE001 -- an exception would be fmi2Fatal in pythonfmu
            return self._fail(f"fmi2DoStep failed: {type(e).__name__}: {e}")

    def _do_step(self, t: float, h: float) -> bool:
        if not self._ready:
            return self._fail(f"fmi2DoStep refused: {self._error}")
        if not (0.0 < h < math.inf):
            return self._fail(f"communication step size h = {h!r} s is invalid: it must be > 0 and finite; "
                              f"step refused, state unchanged")
        if t != self._t and not abs(t - self._t) <= TIME_TOLERANCE * max(abs(self._t), h):
            return self._fail(f"currentCommunicationPoint = {t!r} s is not the current time of the FMU, "
                              f"{self._t!r} s; step refused, state unchanged")
        first = self._state is None
        if first:
            x, v = 0.0, 0.0                       # the hammer at rest in the static equilibrium
        else:
            for name in ("hammer_position", "hammer_velocity"):
                value = float(getattr(self, name))
                if not (math.isfinite(value) and abs(value) <= INPUT_LIMIT):
                    unit = "m" if name == "hammer_position" else "m/s"
                    return self._fail(f"input {name!r} = {value!r} is out of range: allowed "
                                      f"[-{INPUT_LIMIT:g}, {INPUT_LIMIT:g}] {unit}; step refused, "
                                      f"state unchanged")
            x = float(self.hammer_position) - self.hammer_position_at_rest
            v = float(self.hammer_velocity)
        if first:  # the first built step decides the form, as the native flavour's build does
            self._table = StepTable(self._side, self._built)
            self._state = StringState(self._side, self._built[0])
            self._th[:] = (self._t_start, self._t_start - h, self._t_start - 2 * h)
            self._wh[:] = (x, v)
        self._wh[0, 0], self._wh[0, 1] = x, v
        self._exchange(h)
        self._t = t + h
        self._set_outputs()
        return True

    def _exchange(self, h: float) -> None:
        """The master's Jacobi exchange (fmi form) over ``h``; the held force of a next step of
        the same length comes with it."""
        call = self._calls.get(h)
        if call is None:  # a new step length: its records, typed by numba's dispatcher once
            side, st = self._side, self._state
            d = self._table.get(h)
            if len(self._calls) >= STEP_CACHE + len(self._built):
                del self._calls[next(iter(self._calls))]
            if st.modal:
                form = ModalForm(d.m_d, d.m_G, d.m_irow, d.m_icol, st.v, side.m_frow)
            else:
                form = DenseForm(d.P, st.v, st.buf, st.tmp, side.frow)
            kernel = exchange_kernel(form)
            call = self._calls[h] = [kernel, [self._scheme, h, form, self._iface, self._xhist, None], kernel]
        args = call[1]
        args[HAMMER_ARG] = HammerStep(0.0, 0.0, self._F_held)
        self._F_held = call[0](*args)[EXCHANGE_HELD]
        if call[0] is call[2]:  # compiled by now: later steps of this length skip the dispatcher's typing
            call[0] = entry_point(call[2], args)

    def _set_outputs(self) -> None:
        self.interface_force = float(self._sc[0])
        self.held_force = float(self._F_held)
        self.held_force_change = float(self._F_held - self._W)
        V, t0 = self._side.feed
        if self._state is None:               # the static equilibrium (a feed's block at its start)
            self.hook_load = self._hook_eq
            self.top_position, self.top_velocity = 0.0, float(V)
            return
        o = self._state.outputs(self._t)
        self.hook_load = float(o[ROW_HOOK])
        self.top_position = float(o[ROW_TOP_U] + V * (self._t - t0))
        self.top_velocity = float(o[ROW_TOP_V] + V)
