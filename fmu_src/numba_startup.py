"""Loading compiled kernels without numba's BLAS probe importing ``scipy.linalg``.

The first time numba loads or compiles anything in a process, it refreshes its
typing and target contexts, which imports ``numba.np.arraymath``.  That module
probes for a BLAS at import time (``_HAVE_BLAS = _check_blas()``) by importing
``scipy.linalg.cython_blas``, and so all of ``scipy.linalg``, a large share of
an FMU's first start (``python -m benchmarks --only fmu``), spent on a flag
that only decides how ``np.correlate`` and ``np.convolve`` are lowered.  The
kernels use neither.

:func:`import_arraymath_lazily` imports ``numba.np.arraymath`` first, with
``scipy.linalg`` held back for the duration of that one import, and then sets
the flag to what the probe would have found (scipy installed means its
``cython_blas`` exists).  Functions that really use BLAS (``np.dot``,
``np.linalg``) import ``scipy.linalg`` themselves when they are typed, as
always.  It does nothing when ``scipy.linalg`` or ``numba.np.arraymath`` is
already imported, and falls back to the plain import if numba's module no
longer has the probe.
"""
import importlib.abc
import importlib.util
import sys

_HELD_BACK = "scipy.linalg"


class _HoldBack(importlib.abc.MetaPathFinder):
    """A finder that reports ``scipy.linalg`` missing (only while installed)."""

    def find_spec(self, name, path=None, target=None):
        if name == _HELD_BACK:
            raise ModuleNotFoundError(f"{name} held back while numba.np.arraymath loads", name=name)
        return None


def import_arraymath_lazily() -> bool:
    """Import ``numba.np.arraymath`` without importing ``scipy.linalg``; True if it did."""
    if "numba.np.arraymath" in sys.modules or _HELD_BACK in sys.modules:
        return False
    hold = _HoldBack()
    sys.meta_path.insert(0, hold)
    try:
        import numba.np.arraymath as arraymath  # noqa: PLC0415
    except ImportError:
        arraymath = None
    finally:
        sys.meta_path.remove(hold)
    if arraymath is None or not hasattr(arraymath, "_HAVE_BLAS"):
        # numba changed: undo and let the normal import run its own probe
        sys.modules.pop("numba.np.arraymath", None)
        import numba.np.arraymath  # noqa: F401,PLC0415
        return False
    arraymath._HAVE_BLAS = importlib.util.find_spec("scipy") is not None
    return True
