"""One co-simulation instance of an extracted FMU through fmpy's low-level ``FMU2Slave``, its log
messages captured: the instance the FMU front and runtime tests drive call by call (an FMI 3.0
FMU behind the same calls: tests/fmi3_as_fmi2.py)."""
from __future__ import annotations

import ctypes
from pathlib import Path

import fmpy
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

FMI_OK, FMI_WARNING, FMI_DISCARD, FMI_ERROR = 0, 1, 2, 3
#: the communication step of the tests [s] (the FMU's default experiment step)
STEP = 1e-3


class Slave:
    """An instance, instantiated and initialised: ``reals``/``booleans`` are set in initialisation
    mode, which it leaves unless ``init`` is False; with ``setup`` False it is only instantiated."""

    def __init__(self, fmu_dir: Path, *, logging=False, start_time=0.0, reals=None, booleans=None,
                 init=True, setup=True):
        self.md = read_model_description(str(fmu_dir / "modelDescription.xml"))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.messages = []

        def logger(env, instance, status, category, message):
            self.messages.append((status, message.decode("utf-8", "replace")))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        self.cb = cb
        self.t = start_time
        if self.md.fmiVersion.startswith("3"):     # an FMI 3.0 FMU behind the same FMI 2.0 calls
            from fmi3_as_fmi2 import Fmi3AsFmi2, fmi3_logger
            self.fmu = Fmi3AsFmi2(self.md, fmu_dir, "s")
            self.fmu.instantiate(logMessage=fmi3_logger(self.messages), loggingOn=logging)
        else:
            self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=str(fmu_dir),
                                 modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="s")
            self.fmu.instantiate(callbacks=cb, loggingOn=logging)
        if not setup:
            return
        self.fmu.setupExperiment(startTime=start_time)
        self.fmu.enterInitializationMode()
        for name, value in (reals or {}).items():
            self.fmu.setReal([self.vr[name]], [value])
        for name, value in (booleans or {}).items():
            self.fmu.setBoolean([self.vr[name]], [value])
        if init:
            self.fmu.exitInitializationMode()

    def raw_instantiate(self, kind, guid, uri):
        """``fmi2Instantiate`` called directly (kind 0 Model Exchange, 1 Co-Simulation): its handle or None."""
        return self.fmu.fmi2Instantiate(b"raw", kind, guid.encode(), uri.encode(),
                                        ctypes.byref(self.cb), 0, 0)

    def step(self, h=STEP):
        self.fmu.doStep(self.t, h)
        self.t += h

    def get(self, *names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def errors(self):
        return [m for s, m in self.messages if s >= FMI_ERROR]

    def status_of(self, call, *args) -> int:
        """The FMI status of a call (fmpy raises on a status above warning)."""
        try:
            call(*args)
        except FMICallException as e:
            return e.status
        return FMI_OK

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
