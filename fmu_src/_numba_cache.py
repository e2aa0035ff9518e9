"""A numba cache that survives a new process *and* a new extraction directory.

numba's own locators key the cache directory on the source file's *path*.
An FMU is unzipped into a fresh temporary directory on every load, so those
caches never hit.  This locator keys the cache on the *content* of the source
file instead: the same kernels, wherever they were unpacked, find the same
compiled code.

The cache lives in ``$HAMMERBIT_CACHE_DIR`` if set, else
``$XDG_CACHE_HOME/hammerbit/numba`` (``~/.cache/hammerbit/numba``).  It only
claims this package's own modules; every other numba function keeps numba's
default behaviour.
"""
import hashlib
import os

from numba.core import caching as _caching

_HERE = os.path.dirname(os.path.abspath(__file__))


def cache_root() -> str:
    """Directory that holds hammerbit's compiled kernels."""
    env = os.environ.get("HAMMERBIT_CACHE_DIR")
    if env:
        return env
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(xdg, "hammerbit", "numba")


class ContentHashCacheLocator(_caching._SourceFileBackedLocatorMixin, _caching._CacheLocator):
    """Cache locator keyed on the source file's SHA-256, not on its path."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        with open(py_file, "rb") as fh:
            digest = hashlib.sha256(fh.read()).hexdigest()[:20]
        # numba's cache entries remember the module they were compiled in (and
        # re-import it on load): the library (hammerbit.model.kernels) and the
        # FMU (hammerbit_fmu_runtime.kernels) must not share entries.
        module = getattr(py_func, "__module__", None) or os.path.splitext(os.path.basename(py_file))[0]
        self._cache_path = os.path.join(cache_root(), f"{module}-{digest}")

    def get_cache_path(self):
        return self._cache_path

    @classmethod
    def from_function(cls, py_func, py_file):
        if not py_file or os.path.dirname(os.path.abspath(py_file)) != _HERE:
            return None
        return super().from_function(py_func, py_file)


def _register():
    impl = getattr(_caching, "CacheImpl", None) or getattr(_caching, "_CacheImpl")
    classes = impl._locator_classes
    # one registration per process even if the package is imported under two names
    for c in classes:
        if getattr(c, "__name__", "") == "ContentHashCacheLocator" and c is not ContentHashCacheLocator:
            if getattr(c, "_hb_dir", None) == _HERE:
                return
    ContentHashCacheLocator._hb_dir = _HERE
    classes.insert(0, ContentHashCacheLocator)


_register()
