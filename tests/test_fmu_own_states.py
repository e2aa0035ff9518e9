"""Every state an FMU holds can be restored: after each accepted ``fmi2DoStep`` — also with every
input at the ends of its declared range — ``fmi2GetFMUstate`` then ``fmi2SetFMUstate`` succeeds, and
a step the FMU refuses leaves its state as it was.

A checkpointing master (rollback, an adaptive step, a fixed-point iteration) relies on this: an FMU
whose range checks on restore are stricter than what its steps produce fails in the master's hands
after a long run, and only then.  The inputs at their declared bounds drive the states far (a hammer
thrown by the largest force a host may apply, the bit run away); the FMU may refuse such a step,
naming why, but it must never hold a state it then refuses.
"""
import math

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException

#: communication steps per case: enough to carry a thrown hammer or a running-away bit past the
#: range checks of every FMU built by the fixtures (DrillingSystem refuses within 2 steps at the
#: largest amplitude; without its refusal, its state was unrestorable after 1)
STEPS = 6
#: the co-simulation FMUs that declare FMU states (pythonfmu's Drillstring declares none), FMI 2 and 3
FMUS = ["built_fmu", "built_native_fmu", "built_native_string_fmu", "built_system_fmu",
        "built_native_fmu3", "built_native_string_fmu3", "built_field_system_fmu3"]


#: an input's end where its range is not declared: large values in SI units (a force of 1e9 N, a
#: position of 1e6 m); one the FMU refuses on fmi2SetReal is no case
UNDECLARED_ENDS = (1e6, 1e9)


def _extreme_inputs(md):
    """(name, value reference, value) of every Real input at each end of its declared range (or
    at :data:`UNDECLARED_ENDS` on a side with none)."""
    cases = []
    for v in md.modelVariables:
        if v.causality != "input" or v.type not in ("Real", "Float64"):
            continue
        ends = []
        for bound, sign in ((v.min, -1.0), (v.max, 1.0)):
            ends += [float(bound)] if bound is not None else [sign * e for e in UNDECLARED_ENDS]
        cases += [(v.name, v.valueReference, e) for e in ends if math.isfinite(e) and e != float(v.start)]
    return cases


class _Run:
    """One instance of ``path`` (FMI 2 or 3), initialised at its start values, with its log; the
    calls this test makes, named as FMI 2 names them."""

    def __init__(self, path, md, unzipdir):
        self.log = []
        self.fmi3 = md.fmiVersion.startswith("3")
        self.outputs = [v.valueReference for v in md.modelVariables
                        if v.causality == "output" and v.type in ("Real", "Float64")]
        kw = dict(guid=md.guid, unzipDirectory=unzipdir, instanceName="own_states",
                  modelIdentifier=md.coSimulation.modelIdentifier)
        if self.fmi3:
            from fmpy.fmi3 import FMU3Slave
            self.fmu = FMU3Slave(**kw)
            self.fmu.instantiate(loggingOn=True, logMessage=lambda env, status, cat, msg:
                                 self.log.append(msg.decode(errors="replace")))
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
            self.fmu = FMU2Slave(**kw)
            callbacks = fmi2CallbackFunctions()
            callbacks.logger = fmi2CallbackLoggerTYPE(
                lambda env, name, status, cat, msg: self.log.append(msg.decode(errors="replace")))
            callbacks.allocateMemory = defaultCallbacks.allocateMemory
            callbacks.freeMemory = defaultCallbacks.freeMemory
            self._callbacks = callbacks     # kept alive as long as the instance
            self.fmu.instantiate(callbacks=callbacks, loggingOn=True)
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def set_real(self, vr, value):
        (self.fmu.setFloat64 if self.fmi3 else self.fmu.setReal)([vr], [value])

    def outputs_now(self):
        return list((self.fmu.getFloat64 if self.fmi3 else self.fmu.getReal)(self.outputs))

    def get_state(self):
        return self.fmu.getFMUState() if self.fmi3 else self.fmu.getFMUstate()

    def set_state(self, state):
        (self.fmu.setFMUState if self.fmi3 else self.fmu.setFMUstate)(state)

    def free_state(self, state):
        (self.fmu.freeFMUState if self.fmi3 else self.fmu.freeFMUstate)(state)

    def close(self):
        try:
            self.fmu.freeInstance()
        except Exception:
            pass


def _step_size(md) -> float:
    de = md.defaultExperiment
    return float(de.stepSize) if de is not None and de.stepSize else 1e-3


@pytest.mark.parametrize("built", FMUS, indirect=True)
def test_every_state_an_fmu_steps_to_can_be_restored(built, request, tmp_path):
    fixture, path = request.node.callspec.params["built"], built
    md = read_model_description(str(path))
    assert md.coSimulation.canGetAndSetFMUstate, fixture
    unzipdir = extract(str(path), unzipdir=str(tmp_path / "fmu"))
    h = _step_size(md)
    cases = _extreme_inputs(md)
    assert cases, f"{fixture}: no input with a declared bound"
    refused = accepted = 0
    for name, vr, value in cases:
        run = _Run(path, md, unzipdir)
        try:
            try:
                run.set_real(vr, value)
            except FMICallException:
                continue            # refused as an input, before any work
            accepted += 1
            t = 0.0
            for k in range(STEPS):
                before = run.get_state()
                outputs = run.outputs_now()
                try:
                    run.fmu.doStep(t, h)
                except FMICallException:
                    # a refused step names why and keeps the state of its start
                    refused += 1
                    assert "refused" in run.log[-1] or "failed" in run.log[-1], (fixture, name, value, run.log[-1])
                    run.set_state(before)     # out of the error state (FMI 2.0.4)
                    assert run.outputs_now() == outputs, (fixture, name, value)
                    break
                t += h
                state = run.get_state()
                try:
                    run.set_state(state)
                except FMICallException:
                    pytest.fail(f"{fixture}: with {name} = {value!r}, the state after step {k + 1} "
                                f"(t = {t!r} s) is refused on restore: {run.log[-1]}")
                run.free_state(state)
                run.free_state(before)
        finally:
            run.close()
    assert accepted, f"{fixture}: every extreme input was refused"
    if fixture in ("built_system_fmu", "built_field_system_fmu3"):
        # the largest amplitude throws the hammer metres from the bit within a step or two: the
        # case this test is known to reach on both strings (not a restatement of which inputs are
        # refused)
        assert refused >= 1
