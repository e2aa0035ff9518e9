"""Test helper: an FMI 3.0 co-simulation instance behind the FMI 2.0 calls the behaviour tests make.

The FMU behaviour tests (states, rollback, statuses, fuzzed states) drive an instance through
fmpy's ``FMU2Slave`` methods.  :class:`Fmi3AsFmi2` gives an FMI 3.0 FMU the same methods over
fmpy's ``FMU3Slave``, each one FMI 3.0 call of the FMI 3 type of the value references (Float64
for Real; Int32 or UInt64 for Integer), so that the same test runs against both versions:

* ``setupExperiment`` is ``fmi3EnterInitializationMode`` with its arguments (FMI 3.0 takes the
  experiment there; a refused time is refused by that call), ``enterInitializationMode`` nothing;
* ``doStep`` is ``fmi3DoStep`` (early return not allowed: the FMI 2.0 semantics);
* a status above Warning raises fmpy's ``FMICallException``, as in ``FMU2Slave``.
"""
from __future__ import annotations

from fmpy.fmi3 import FMU3Slave


class Fmi3AsFmi2:
    """The FMI 2.0 calls of ``FMU2Slave`` over an FMI 3.0 FMU (``md``: its fmpy model description)."""

    def __init__(self, md, unzip_dir, instance_name: str):
        self.md = md
        self.s = FMU3Slave(guid=md.guid, unzipDirectory=str(unzip_dir),
                           modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance_name)
        self.type_of = {v.valueReference: v.type for v in md.modelVariables}

    def instantiate(self, logMessage=None, loggingOn=False):
        self.s.instantiate(loggingOn=loggingOn, logMessage=logMessage)

    def setupExperiment(self, tolerance=None, startTime=0.0, stopTime=None):
        self.s.enterInitializationMode(tolerance=tolerance, startTime=startTime, stopTime=stopTime)

    def enterInitializationMode(self):
        """Nothing: ``setupExperiment`` entered Initialization Mode (FMI 3.0 takes the experiment there)."""

    def exitInitializationMode(self):
        self.s.exitInitializationMode()

    def doStep(self, t, h, noSetFMUStatePriorToCurrentPoint=True):
        self.s.doStep(t, h, noSetFMUStatePriorToCurrentPoint)

    def getReal(self, vrs):
        return self.s.getFloat64(vrs)

    def setReal(self, vrs, values):
        self.s.setFloat64(vrs, values)

    def getInteger(self, vrs):
        return [int((self.s.getUInt64 if self.type_of.get(vr) == "UInt64" else self.s.getInt32)([vr])[0])
                for vr in vrs]

    def setInteger(self, vrs, values):
        for vr, v in zip(vrs, values):
            (self.s.setUInt64 if self.type_of.get(vr) == "UInt64" else self.s.setInt32)([vr], [v])

    def getBoolean(self, vrs):
        return self.s.getBoolean(vrs)

    def setBoolean(self, vrs, values):
        self.s.setBoolean(vrs, values)

    def getFMUstate(self):
        return self.s.getFMUState()

    def setFMUstate(self, state):
        self.s.setFMUState(state)

    def freeFMUstate(self, state):
        self.s.freeFMUState(state)

    def serializeFMUstate(self, state):
        return self.s.serializeFMUState(state)

    def deSerializeFMUstate(self, data):
        return self.s.deserializeFMUState(bytes(data))

    def terminate(self):
        self.s.terminate()

    def reset(self):
        self.s.reset()

    def freeInstance(self):
        self.s.freeInstance()


def fmi3_logger(messages: list):
    """An FMI 3.0 logMessage callback appending ``(status, text)`` to ``messages``."""
    def log(env, status, category, message):
        messages.append((status, message.decode("utf-8", "replace")))
    return log


__all__ = ["Fmi3AsFmi2", "fmi3_logger"]
