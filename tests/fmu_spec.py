"""What FMI 2.0 and an FMU's own modelDescription.xml say about its variables and its calls, for
the specification-derived tests (``test_fmu_spec_values.py``, ``test_fmu_calling_sequence.py``).

Nothing here reads the fronts' code: the variables, their types, causalities, variabilities,
initial kinds and start values come from the modelDescription.xml inside the built FMU, and the
rules from the FMI 2.0 standard (section 3.2.3 for ``initial``, section 4.2.4 for the Co-Simulation
calling sequence and the footnotes of its table that say which variables may be set in which state).
"""
from __future__ import annotations

import math
import zipfile
from pathlib import Path

import fmpy
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

FMI_OK, FMI_WARNING, FMI_DISCARD, FMI_ERROR, FMI_FATAL = 0, 1, 2, 3, 4
#: The four typed accessors of FMI 2.0.
TYPES = ("Real", "Integer", "Boolean", "String")
#: The communication step the tests take [s].
STEP = 1e-3
#: Local variables that report the FMI status of the last call (HammerBitRock's ``last_status``):
#: a refused call changes them by design, so "nothing changed" leaves them out.
LAST_CALL = frozenset({"last_status"})


def extract(fmu: Path, where: Path) -> Path:
    """The FMU unpacked into ``where`` (once)."""
    if not (where / "modelDescription.xml").is_file():
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(where)
    return where


def start_value(v):
    """The start value of a variable as its typed setter takes it (None without one)."""
    if v.start is None:
        return None
    if v.type == "Real":
        return float(v.start)
    if v.type in ("Integer", "Enumeration"):
        return int(v.start)
    if v.type == "Boolean":
        return v.start in (True, "true", "1", 1)
    return str(v.start)


def settable(v, state: str) -> bool:
    """FMI 2.0, section 4.2.4, footnotes of the Co-Simulation table: may ``fmi2Set<type>`` be
    called on ``v`` in ``state`` (``instantiated``, ``init``, ``stepComplete``)?

    * instantiated: variability not constant, with initial ``exact`` or ``approx``;
    * initialization mode: variability not constant, with initial ``exact``, or an input;
    * stepComplete: a tunable parameter or an input.
    """
    if v.variability == "constant":
        return False
    if state == "instantiated":
        return v.initial in ("exact", "approx")
    if state == "init":
        return v.initial == "exact" or v.causality == "input"
    if state == "stepComplete":
        return (v.causality == "parameter" and v.variability == "tunable") or v.causality == "input"
    return False


def near_value(v):
    """A legal value of ``v`` other than its start where its declared range has one: the next float
    inside [min, max] (Real), start +- 1 inside it (Integer), the other truth value (Boolean); the
    start itself when min = max."""
    s = start_value(v)
    if v.type in ("Real", "Integer"):
        real = v.type == "Real"
        lo = (float if real else int)(v.min) if v.min is not None else (-math.inf if real else -2 ** 31)
        hi = (float if real else int)(v.max) if v.max is not None else (math.inf if real else 2 ** 31 - 1)
        up, down = (math.nextafter(s, math.inf), math.nextafter(s, -math.inf)) if real else (s + 1, s - 1)
        return up if up <= hi else down if down >= lo else s
    if v.type == "Boolean":
        return not s
    return s + "x"


class Instance:
    """One Co-Simulation instance of an extracted FMU through fmpy's low-level calls, its log
    captured; :meth:`status` gives the FMI status of any call (fmpy raises above fmi2Warning)."""

    def __init__(self, fmu_dir: Path):
        self.md = read_model_description(str(fmu_dir / "modelDescription.xml"))
        self.vars = list(self.md.modelVariables)
        self.messages = []

        def logger(env, instance, status, category, message):
            self.messages.append((status, message.decode("utf-8", "replace")))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        self.cb = cb
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=str(fmu_dir),
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="spec")
        self.fmu.instantiate(callbacks=cb, loggingOn=True)
        self.t = 0.0
        self.states = bool(self.md.coSimulation.canGetAndSetFMUstate)

    # --------------------------------------------------------------- calls
    @staticmethod
    def status(call, *args) -> int:
        try:
            call(*args)
        except FMICallException as e:
            return e.status
        return FMI_OK

    def get(self, kind: str, vrs):
        return getattr(self.fmu, "get" + kind)(list(vrs))

    def set(self, kind: str, vrs, values):
        return getattr(self.fmu, "set" + kind)(list(vrs), list(values))

    def values(self) -> dict:
        """Every variable's value by its typed getter, ``{name: value}`` (NaN as a string, so that
        two reads compare equal), but the last call's status (:data:`LAST_CALL`)."""
        out = {}
        for kind in TYPES:
            vs = [v for v in self.vars if v.type == kind and v.name not in LAST_CALL]
            if vs:
                for v, x in zip(vs, self.get(kind, [v.valueReference for v in vs])):
                    out[v.name] = repr(x)
        return out

    # --------------------------------------------------------------- states of section 4.2.4
    def to_init(self):
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()

    def to_step_complete(self):
        self.to_init()
        self.fmu.exitInitializationMode()
        self.t = 0.0
        self.step()

    def step(self, h=STEP):
        self.fmu.doStep(self.t, h)
        self.t += h

    def to_terminated(self):
        self.to_step_complete()
        self.fmu.terminate()

    def to_error(self):
        """stepComplete, then a step from a time that is not the FMU's: fmi2Error."""
        self.to_step_complete()
        assert self.status(self.fmu.doStep, self.t + 1.0, STEP) == FMI_ERROR

    def reach(self, state: str):
        """From a fresh or reset instance (``instantiated``) into ``state``."""
        {"instantiated": lambda: None, "init": self.to_init, "stepComplete": self.to_step_complete,
         "terminated": self.to_terminated, "error": self.to_error}[state]()

    def reset(self):
        self.fmu.reset()
        self.t = 0.0

    def free(self):
        self.fmu.freeInstance()
