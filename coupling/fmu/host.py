"""The project's one FMU loader: an FMI 2.0 co-simulation FMU driven through fmpy's ``FMU2Slave``.

Used by the co-simulation master (:class:`hammerbit.cosim.hammer_fmu.FMUHammer`), the
benchmarks and the tests.  It extracts the FMU, instantiates it with a logger
that keeps every message (status, text), sets start values, and gives
variables by name.  Importing it imports neither numba nor the model, so an
FMU loaded through it can still use its shipped (portable) compiled kernels.
"""
from __future__ import annotations

import os
import shutil

from hammerbit.fmu.native_build import NATIVE_GENERATION_TOOL

__all__ = ["FMUInstance", "FMI_OK", "FMI_WARNING", "FMI_DISCARD", "FMI_ERROR", "FMI_FATAL"]

FMI_OK, FMI_WARNING, FMI_DISCARD, FMI_ERROR, FMI_FATAL = 0, 1, 2, 3, 4

#: ``{(real path, size, mtime in ns): fmpy's ModelDescription}``: a master instantiates the same
#: FMU again and again (a study's cells, a rollback), with the same description
_DESCRIPTIONS: dict = {}
_DESCRIPTIONS_KEPT = 16


def model_description(path):
    """fmpy's ``read_model_description`` of the FMU ``path``, parsed once per file version."""
    from fmpy import read_model_description
    st = os.stat(path)
    key = (os.path.realpath(path), st.st_size, st.st_mtime_ns)
    md = _DESCRIPTIONS.get(key)
    if md is None:
        md = read_model_description(str(path))
        if len(_DESCRIPTIONS) >= _DESCRIPTIONS_KEPT:
            _DESCRIPTIONS.pop(next(iter(_DESCRIPTIONS)))
        _DESCRIPTIONS[key] = md
    return md


class FMUInstance:
    """One instance of a co-simulation FMU, set up to Initialization Mode or beyond.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file.
    name : str
        Instance name.
    start_time : float
        ``startTime`` of ``fmi2SetupExperiment`` [s]; the instance's clock
        :attr:`t` starts there.
    reals, booleans : dict, optional
        ``{variable: value}`` set in Initialization Mode.
    init : bool
        Leave Initialization Mode (``fmi2ExitInitializationMode``); False stays in it.
    setup : bool
        Call ``fmi2SetupExperiment`` and enter Initialization Mode; False stops
        right after ``fmi2Instantiate`` (``reals``, ``booleans``, ``init`` unused).
    logging : bool
        ``loggingOn`` of ``fmi2Instantiate``.
    unzipdir : path, optional
        An existing extraction directory (kept by :meth:`close`); by default
        the FMU is extracted into a temporary directory that :meth:`close` removes.

    Attributes
    ----------
    vr : dict
        Variable name -> value reference.
    messages : list of (int, str)
        Every logged message: FMI status and text.
    has_front : bool
        The FMU's binary is the native front, which returns the model's real
        statuses: pythonfmu's binary beside it, or the native runtime flavour.
    """

    def __init__(self, path, name: str = "hammer", *, start_time: float = 0.0, reals=None, booleans=None,
                 init: bool = True, setup: bool = True, logging: bool = True, unzipdir=None):
        import fmpy
        from fmpy import extract
        from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
        self.path = str(path)
        self.md = model_description(self.path)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.var = {v.name: v for v in self.md.modelVariables}
        self._own_dir = unzipdir is None
        self.dir = str(unzipdir) if unzipdir is not None else extract(self.path)
        ident = self.md.coSimulation.modelIdentifier
        native = (self.md.generationTool or "").startswith(NATIVE_GENERATION_TOOL)
        self.has_front = native or os.path.isfile(os.path.join(self.dir, "binaries", "linux64",
                                                               f"{ident}_python.so"))
        self.messages = []

        def logger(env, instance, status, category, message):
            self.messages.append((int(status), message.decode("utf-8", "replace")))

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(logger)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        self._callbacks = cb
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir, modelIdentifier=ident,
                             instanceName=name)
        self.fmu.instantiate(callbacks=cb, loggingOn=logging)
        self._guard()
        self._closed = False
        self.t = float(start_time)
        if not setup:
            return
        self.fmu.setupExperiment(startTime=start_time)
        self.fmu.enterInitializationMode()
        if reals:
            self.set(**reals)
        if booleans:
            self.fmu.setBoolean([self.vr[k] for k in booleans], [bool(v) for v in booleans.values()])
        if init:
            self.fmu.exitInitializationMode()

    def _guard(self) -> None:
        """pythonfmu 0.7.0's exit-time double free: pin its binary's finalizer (Python hosts)."""
        from hammerbit.model.pythonfmu_exit import guard_pythonfmu_exit
        guard_pythonfmu_exit(os.path.join(self.dir, "resources"))

    # -- variables by name --------------------------------------------------
    def set(self, **values) -> None:
        """``fmi2SetReal`` by name."""
        self.fmu.setReal([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names) -> list:
        """``fmi2GetReal`` by name."""
        return self.fmu.getReal([self.vr[n] for n in names])

    def get_int(self, *names) -> list:
        """``fmi2GetInteger`` by name."""
        return self.fmu.getInteger([self.vr[n] for n in names])

    def get_bool(self, *names) -> list:
        """``fmi2GetBoolean`` by name."""
        return self.fmu.getBoolean([self.vr[n] for n in names])

    # -- time ------------------------------------------------------------------
    def step(self, h: float) -> None:
        """``fmi2DoStep(t, h)`` at the instance's clock; the clock advances only on success."""
        self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h

    def set_time(self, t: float) -> None:
        """Set the clock (after a rollback with ``fmi2SetFMUstate``)."""
        self.t = float(t)

    # -- messages ----------------------------------------------------------------
    def errors(self) -> list:
        """Messages logged with status fmi2Error or worse."""
        return [m for s, m in self.messages if s >= FMI_ERROR]

    def close(self) -> None:
        """``fmi2Terminate`` + ``fmi2FreeInstance``; remove the extraction directory if it is ours."""
        if self._closed:
            return
        self._closed = True
        from fmpy.fmi1 import FMICallException
        try:
            self.fmu.terminate()
        except FMICallException:     # not allowed after fmi2Error (FMI 2.0.4); freeing is
            pass
        finally:
            self.fmu.freeInstance()
            if self._own_dir:
                shutil.rmtree(self.dir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
