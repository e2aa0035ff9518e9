"""The project's one FMU loader: an FMI 2.0 co-simulation FMU driven through fmpy's ``FMU2Slave``.

Used by the co-simulation master (:class:`hammerbit.cosim.hammer_fmu.FMUHammer`), the
benchmarks and the tests.  It extracts the FMU, instantiates it with a logger
that keeps every message (status, text), sets start values, and gives
variables by name.  Importing it imports neither numba nor the model, so an
FMU loaded through it can still use its shipped (portable) compiled kernels.

The instances of one FMU file (one version of it: :func:`_file_version`) share
one extraction directory and so one loaded binary, as libcosim's and most
hosts' instances do: a study's cells and a master's instances skip the
unzipping and the loading.  A directory no instance
uses is kept for the next one, up to :data:`UNUSED_EXTRACTIONS_KEPT` of them,
and removed at the latest when the process exits.
"""
from __future__ import annotations

import atexit
import os
import shutil
import threading

from hammerbit.fmu.native_build import NATIVE_GENERATION_TOOL

__all__ = ["FMUInstance", "FMI_OK", "FMI_WARNING", "FMI_DISCARD", "FMI_ERROR", "FMI_FATAL"]

FMI_OK, FMI_WARNING, FMI_DISCARD, FMI_ERROR, FMI_FATAL = 0, 1, 2, 3, 4

#: ``{file version (:func:`_file_version`): fmpy's ModelDescription}``: a master instantiates the same
#: FMU again and again (a study's cells, a rollback), with the same description
_DESCRIPTIONS: dict = {}
_DESCRIPTIONS_KEPT = 16


#: extraction directories no instance uses, kept for the next instance of the same file version
UNUSED_EXTRACTIONS_KEPT = 4
#: ``{file version: [directory, instances using it]}``, the least recently used first
_EXTRACTIONS: dict = {}
_EXTRACTIONS_LOCK = threading.Lock()


def _file_version(path) -> tuple:
    """``(real path, inode, size, mtime, ctime)``: a rebuilt FMU at the same path is another version
    (the change time too: a copy that keeps the size and sets the old modification time back)."""
    st = os.stat(path)
    return os.path.realpath(path), st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns


def acquire_extraction(path) -> tuple:
    """``(file version, directory)``: the extraction directory of ``path``'s version, shared by
    its instances (unzipped on first use); give it back with :func:`release_extraction`."""
    from fmpy import extract
    key = _file_version(path)
    with _EXTRACTIONS_LOCK:
        entry = _EXTRACTIONS.pop(key, None)            # re-inserted: the most recently used last
        if entry is None or not os.path.isdir(entry[0]):
            entry = [extract(str(path)), 0]
        _EXTRACTIONS[key] = entry
        entry[1] += 1
        return key, entry[0]


def release_extraction(key) -> None:
    """One instance less on ``key``'s directory; the least recently used directories no instance
    uses are removed beyond :data:`UNUSED_EXTRACTIONS_KEPT`."""
    with _EXTRACTIONS_LOCK:
        _EXTRACTIONS[key][1] -= 1
        unused = [k for k, (_, users) in _EXTRACTIONS.items() if users == 0]
        for k in unused[:max(len(unused) - UNUSED_EXTRACTIONS_KEPT, 0)]:
            shutil.rmtree(_EXTRACTIONS.pop(k)[0], ignore_errors=True)


@atexit.register
def _remove_extractions() -> None:
    for directory, _ in _EXTRACTIONS.values():
        shutil.rmtree(directory, ignore_errors=True)
    _EXTRACTIONS.clear()


def model_description(path):
    """fmpy's ``read_model_description`` of the FMU ``path``, parsed once per file version."""
    from fmpy import read_model_description
    key = _file_version(path)
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
        the extraction directory this FMU file's instances share
        (:func:`acquire_extraction`).

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
        self.path = str(path)
        self.md = model_description(self.path)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.var = {v.name: v for v in self.md.modelVariables}
        self._extraction = None
        if unzipdir is None:
            self._extraction, self.dir = acquire_extraction(self.path)
        else:
            self.dir = str(unzipdir)
        self._closed = True       # until fmi2Instantiate succeeds: close() gives the directory back
        try:
            self._instantiate(name, logging)
        except BaseException:
            self._release()
            raise
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

    def _instantiate(self, name: str, logging: bool) -> None:
        import fmpy
        from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
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

    def _release(self) -> None:
        if self._extraction is not None:
            release_extraction(self._extraction)
            self._extraction = None

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
        """``fmi2Terminate`` + ``fmi2FreeInstance``; give the shared extraction directory back."""
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
            self._release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
