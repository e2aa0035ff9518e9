"""pythonfmu 0.7.0's exit-time double free, and the guard against it (no numba import here).

Any host that loads a pythonfmu FMU into a Python process can call
:func:`guard_pythonfmu_exit` with the FMU's resources directory (both slaves,
HammerBitRock and Drillstring, call it for their own binary).  At every exit
an unguarded wrapper releases a freed control block once more; whether the
process then aborts
(``corrupted double-linked list``, exit 134) depends on what else the exit
frees: FMPy's SSP runner with the two pythonfmu FMUs of ``drilling.ssp`` in
one process aborted in most runs while only HammerBitRock's binary was
guarded.  The native front (``native/pythonfmu_wrapper.c``) resets the same
pointer from its own exit handler, so an FMU with the front is guarded in any
host.
"""
import atexit
import ctypes
import os
import sys

__all__ = ["guard_pythonfmu_exit"]

_PINNED_WRAPPERS = {}   # path of a loaded pythonfmu wrapper library -> its finalizePythonInterpreter


def _release_wrappers():
    for finalize in _PINNED_WRAPPERS.values():
        finalize()


def guard_pythonfmu_exit(resources) -> None:
    """Work around a use-after-free in pythonfmu 0.7.0's native wrapper at process exit.

    The wrapper keeps a static ``std::shared_ptr<PyState>`` and also resets it
    from a ``__attribute__((destructor))`` function.  At exit the C++ static
    destructor runs first and the destructor function then releases the freed
    control block a second time.  Resetting the pointer from a Python
    ``atexit`` hook (which runs first) makes both later calls no-ops.

    Only when the host *is* Python (then the wrapper's interpreter thread did
    nothing).  In a native host the wrapper owns the interpreter, so nothing is
    done.  The library is opened once more here so that it stays mapped until exit.
    """
    if not sys.platform.startswith("linux") or not resources:
        return
    try:
        if os.path.realpath("/proc/self/exe") != os.path.realpath(sys.executable or ""):
            return
        bindir = os.path.join(os.path.dirname(os.path.abspath(str(resources).rstrip("/"))),
                              "binaries", "linux64")
        names = sorted(os.listdir(bindir))
    except OSError:          # no /proc, no binaries directory: nothing to guard
        return
    for name in names:
        path = os.path.join(bindir, name)
        if not name.endswith(".so") or path in _PINNED_WRAPPERS:
            continue
        try:
            finalize = ctypes.CDLL(path).finalizePythonInterpreter
        except (OSError, AttributeError):    # not a pythonfmu wrapper (e.g. the native front)
            continue
        finalize.argtypes = []
        finalize.restype = None
        if not _PINNED_WRAPPERS:
            atexit.register(_release_wrappers)
        _PINNED_WRAPPERS[path] = finalize
