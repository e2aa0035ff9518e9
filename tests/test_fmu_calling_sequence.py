"""The FMI 2.0 calling sequence of Co-Simulation (section 4.2.4, its state table), every function in
every state an FMU can reach, for every FMU in both flavours.

The table below is the standard's, written down from it (not from the fronts): for each function,
the states in which a master may call it.  A call outside them is ``fmi2Error`` (and no crash); a
call inside them is not.  States: ``instantiated``, ``init`` (Initialization Mode),
``stepComplete``, ``terminated`` and ``error``.  ``stepInProgress``, ``stepFailed`` and
``stepCanceled`` need an asynchronous ``fmi2DoStep`` (``fmi2Pending``) or a discarded step, which
these FMUs never return, so no master can reach them.

Where the standard leaves a cell open the test only asks for a status and no crash:

* in the Error state, section 2.1.3 lets a simulation go on only through ``fmi2SetFMUstate`` or
  ``fmi2Reset``; the table also marks ``fmi2GetFMUstate`` and the serialisation there;
* ``fmi2GetStatus`` with ``fmi2DoStepStatus`` is only meaningful after ``fmi2Pending``
  (``fmi2Discard`` allowed, section 4.2.3);
* a function whose capability flag is false in the modelDescription.xml
  (``providesDirectionalDerivative``, ``canInterpolateInputs``, ``maxOutputDerivativeOrder`` = 0,
  ``canGetAndSetFMUstate``) must not be called at all: ``fmi2Error`` in every state.
"""
from __future__ import annotations

import ctypes

import pytest

from fmu_spec import (FMI_DISCARD, FMI_ERROR, FMI_OK, FMI_WARNING, STEP, Instance, extract, settable,
                      start_value)

pytest.importorskip("fmpy")

#: the pythonfmu Drillstring (no FMU states: each of the 125 cells re-initialises it, seconds) in the slow set
FMUS = ["built_fmu", "built_native_fmu", pytest.param("built_string_fmu", marks=pytest.mark.slow),
        "built_native_string_fmu", "built_field_system_fmu"]
STATES = ("instantiated", "init", "stepComplete", "terminated", "error")
ALL = frozenset(STATES)
#: FMI 2.0, section 4.2.4: the reachable columns of the Co-Simulation table, per function
TABLE = {
    "fmi2SetupExperiment": {"instantiated"},
    "fmi2EnterInitializationMode": {"instantiated"},
    "fmi2ExitInitializationMode": {"init"},
    "fmi2DoStep": {"stepComplete"},
    "fmi2Terminate": {"stepComplete"},
    "fmi2Reset": ALL,
    "fmi2SetDebugLogging": ALL,
    "fmi2GetReal": {"init", "stepComplete", "terminated", "error"},
    "fmi2GetInteger": {"init", "stepComplete", "terminated", "error"},
    "fmi2GetBoolean": {"init", "stepComplete", "terminated", "error"},
    "fmi2SetReal": {"instantiated", "init", "stepComplete"},
    "fmi2SetInteger": {"instantiated", "init", "stepComplete"},
    "fmi2SetBoolean": {"instantiated", "init", "stepComplete"},
    "fmi2GetFMUstate": ALL,
    "fmi2SetFMUstate": ALL,
    "fmi2SerializedFMUstateSize": ALL,
    "fmi2SerializeFMUstate": ALL,
    "fmi2DeSerializeFMUstate": ALL,
    "fmi2GetStatus": {"stepComplete", "terminated"},
    "fmi2GetRealStatus": {"stepComplete", "terminated"},
    "fmi2GetIntegerStatus": {"stepComplete", "terminated"},
    "fmi2GetBooleanStatus": {"stepComplete", "terminated"},
    "fmi2GetStringStatus": {"stepComplete", "terminated"},
    "fmi2CancelStep": set(),                      # only in stepInProgress
    "fmi2GetDirectionalDerivative": {"init", "stepComplete", "terminated", "error"},
    "fmi2SetRealInputDerivatives": {"instantiated", "init", "stepComplete"},
    "fmi2GetRealOutputDerivatives": {"stepComplete", "terminated", "error"},
}
#: cells the standard leaves open (see the module docstring): any status, no crash
OPEN = {("fmi2GetFMUstate", "error"), ("fmi2SerializedFMUstateSize", "error"), ("fmi2SerializeFMUstate", "error"),
        ("fmi2DeSerializeFMUstate", "error"), ("fmi2SetDebugLogging", "error")}
#: fmi2StatusKind
DO_STEP_STATUS, PENDING_STATUS, LAST_SUCCESSFUL_TIME, TERMINATED = 0, 1, 2, 3


def _capable(md, function: str) -> bool:
    """The modelDescription's capability flag for ``function`` (True for the core functions)."""
    cs = md.coSimulation
    if function == "fmi2GetDirectionalDerivative":
        return bool(cs.providesDirectionalDerivative)
    if function == "fmi2SetRealInputDerivatives":
        return bool(cs.canInterpolateInputs)
    if function == "fmi2GetRealOutputDerivatives":
        return bool(cs.maxOutputDerivativeOrder)
    if function in ("fmi2GetFMUstate", "fmi2SetFMUstate"):
        return bool(cs.canGetAndSetFMUstate)
    if function in ("fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate"):
        return bool(cs.canSerializeFMUstate)
    return True


def _variable(inst, kind: str, state: str):
    """A variable of type ``kind`` to call its getter or setter with: for a setter one the footnotes
    allow in ``state`` (else one they allow after initialisation: refused here by the state)."""
    vs = [v for v in inst.vars if v.type == kind]
    for want in (state, "stepComplete", "init", "instantiated"):
        ok = [v for v in vs if settable(v, want)]
        if ok:
            return ok[0]
    return vs[0] if vs else None


def _call(inst: Instance, function: str, state: str, saved, serialized=b""):
    """``(status, footnote)``: the FMI status of ``function`` called with valid arguments, and
    whether the table's footnotes allow its variable in ``state`` (a setter; True otherwise);
    ``(None, True)`` when the FMU has no variable of the type."""
    fmu, c = inst.fmu, inst.fmu.component
    kind = function[7:] if function.startswith(("fmi2Get", "fmi2Set")) else ""
    if function in ("fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean"):
        v = _variable(inst, kind, state)
        return (None if v is None else inst.status(inst.get, kind, [v.valueReference])), True
    if function in ("fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean"):
        v = _variable(inst, kind, state)
        if v is None:
            return None, True
        value = start_value(v)
        return (inst.status(inst.set, kind, [v.valueReference], [value if value is not None else 0]),
                settable(v, state))
    calls = {
        "fmi2SetupExperiment": lambda: fmu.setupExperiment(startTime=0.0),
        "fmi2EnterInitializationMode": fmu.enterInitializationMode,
        "fmi2ExitInitializationMode": fmu.exitInitializationMode,
        "fmi2DoStep": lambda: fmu.doStep(inst.t, STEP),
        "fmi2Terminate": fmu.terminate,
        "fmi2Reset": fmu.reset,
        "fmi2SetDebugLogging": lambda: fmu.setDebugLogging(True, []),
        "fmi2GetFMUstate": lambda: fmu.freeFMUstate(fmu.getFMUstate()),
        "fmi2SetFMUstate": lambda: fmu.setFMUstate(saved),
        "fmi2SerializedFMUstateSize": lambda: _raw(fmu.fmi2SerializedFMUstateSize, c, saved,
                                                   ctypes.byref(ctypes.c_size_t())),
        "fmi2SerializeFMUstate": lambda: fmu.serializeFMUstate(saved),
        "fmi2DeSerializeFMUstate": lambda: fmu.freeFMUstate(fmu.deSerializeFMUstate(serialized)),
        "fmi2GetStatus": lambda: _raw(fmu.fmi2GetStatus, c, DO_STEP_STATUS, ctypes.byref(ctypes.c_int())),
        "fmi2GetRealStatus": lambda: _raw(fmu.fmi2GetRealStatus, c, LAST_SUCCESSFUL_TIME,
                                          ctypes.byref(ctypes.c_double())),
        "fmi2GetIntegerStatus": lambda: _raw(fmu.fmi2GetIntegerStatus, c, DO_STEP_STATUS,
                                             ctypes.byref(ctypes.c_int())),
        "fmi2GetBooleanStatus": lambda: _raw(fmu.fmi2GetBooleanStatus, c, TERMINATED,
                                             ctypes.byref(ctypes.c_int())),
        "fmi2GetStringStatus": lambda: _raw(fmu.fmi2GetStringStatus, c, PENDING_STATUS,
                                            ctypes.byref(ctypes.c_char_p())),
        "fmi2CancelStep": fmu.cancelStep,
        "fmi2GetDirectionalDerivative": lambda: _directional(inst),
        "fmi2SetRealInputDerivatives": lambda: _input_derivatives(inst),
        "fmi2GetRealOutputDerivatives": lambda: _output_derivatives(inst),
    }
    return inst.status(calls[function]), True


def _raw(f, *args):
    """A C function of the FMU called as is; its status returned through :meth:`Instance.status`."""
    from fmpy.fmi1 import FMICallException
    status = f(*args)
    if status > FMI_WARNING:
        raise FMICallException(function=getattr(f, "__name__", "fmi2"), status=status)


def _first(inst, causality):
    return next((v for v in inst.vars if v.type == "Real" and v.causality == causality), None)


def _directional(inst):
    out, inp = _first(inst, "output"), _first(inst, "input") or _first(inst, "parameter")
    inst.fmu.getDirectionalDerivative([out.valueReference], [inp.valueReference], [1.0])


def _input_derivatives(inst):
    v = _first(inst, "input")
    inst.fmu.setRealInputDerivatives([v.valueReference], [1], [0.0])


def _output_derivatives(inst):
    v = _first(inst, "output")
    inst.fmu.getRealOutputDerivatives([v.valueReference], [1])


@pytest.fixture(scope="module", params=FMUS)
def fmu_dir(request, tmp_path_factory):
    return extract(request.getfixturevalue(request.param), tmp_path_factory.mktemp(request.param))


def test_every_function_in_every_state_is_refused_exactly_where_the_table_forbids_it(fmu_dir):
    inst = Instance(fmu_dir)
    wrong = []
    try:
        inst.to_step_complete()
        saved = inst.fmu.getFMUstate() if inst.states else None
        serialized = inst.fmu.serializeFMUstate(saved) if saved is not None else b""
        for function, allowed in TABLE.items():
            capable = _capable(inst.md, function)
            if function in ("fmi2SetFMUstate", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate") and saved is None:
                capable = False
            for state in STATES:
                inst.reset()
                inst.reach(state)
                n = len(inst.messages)
                status, footnote = _call(inst, function, state, saved, serialized)
                if status is None or (function, state) in OPEN:
                    continue
                expect_error = not (capable and footnote and state in allowed)
                if expect_error and status != FMI_ERROR:
                    wrong.append(f"{function} in {state}: status {status}, the table forbids it")
                elif not expect_error and status not in (FMI_OK, FMI_WARNING, FMI_DISCARD):
                    wrong.append(f"{function} in {state}: status {status}, the table allows it "
                                 f"({inst.messages[n:]})")
        assert not wrong, "\n".join(wrong)
    finally:
        inst.free()
