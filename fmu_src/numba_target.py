"""The CPU target numba compiles for: this machine's, or the portable one of the shipped kernels.

numba reads ``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES`` once, when it is
imported, and compiles every kernel of the process for that target (and loads
only cache entries made for it).  An FMU built by ``hammerbit fmu build``
ships its kernels compiled for the portable target :data:`PORTABLE_ENV`, so
other x86-64 machines can load them; a process can load them only if its numba
runs that target.  A host that imported numba for its own CPU before loading
the FMU makes the FMU compile its own copy, once per build.

:func:`select_portable` is for a master that is about to load such an FMU
and has not imported numba yet: its own kernels then run the portable target
too (compiled once into the user cache), and the FMU loads what it ships.
This module imports nothing from numba.
"""
import os
import sys

__all__ = ["PORTABLE_ENV", "select_portable", "runs_portable"]

#: the portable CPU target the FMU build compiles for (no CPU-specific features)
PORTABLE_ENV = {"NUMBA_CPU_NAME": "generic", "NUMBA_CPU_FEATURES": ""}


def runs_portable() -> bool:
    """True if numba in this process runs (or, not imported yet, will run) the portable target."""
    if "numba" in sys.modules:
        from numba.core import config  # noqa: PLC0415
        return config.CPU_NAME == PORTABLE_ENV["NUMBA_CPU_NAME"] and not (config.CPU_FEATURES or "")
    return all(os.environ.get(k) == v for k, v in PORTABLE_ENV.items())


def select_portable() -> bool:
    """Make this process's numba run the portable target, if it is not imported yet.

    A target the user set in the environment is kept.  Returns
    :func:`runs_portable` afterwards.
    """
    if "numba" not in sys.modules and all(os.environ.get(k) in (None, v) for k, v in PORTABLE_ENV.items()):
        os.environ.update(PORTABLE_ENV)
    return runs_portable()
