"""The numba cache of the kernels: a locator keyed on their content, not their path.

numba's own locators key the cache directory on the source file's *path*.
An FMU is unzipped into a fresh temporary directory on every load, so those
caches never hit.  This locator keys the cache on the *content* of the source
file and on the module name: the same kernels, wherever they were unpacked,
find the same compiled code.  It only claims this package's own modules.

The cache directory (the FMU's shipped kernels or the user's cache) is
decided by :mod:`.numba_cache_place`.

:func:`first_use_report` turns the outcome into one message for the FMI
logger (the reason, and where the compiled code went), so a compilation is
never silent.
"""
import functools
import hashlib
import os
import sys

from .numba_cache_place import decision

_HERE = os.path.dirname(os.path.abspath(__file__))

#: the decision of this process: {"dir", "shipped", "reason"}
DECISION = decision()

from numba.core import caching as _caching  # noqa: E402  (after the CPU target is decided)

from .numba_startup import import_arraymath_lazily  # noqa: E402


def cache_root() -> str:
    """Directory that holds (or receives) this package's compiled kernels in this process."""
    return DECISION["dir"]


#: Prefix of the modules that hold numba kernels (``kernel_layouts.py``, ``kernel_driver.py`` ...).
KERNEL_PREFIX = "kernel_"
#: Runtime modules whose constants the compiled kernels fold in (ranges, Runge-Kutta tableaux,
#: the bound copy of the driver): a change to any of them must miss the cache too.
_COMPILED_IN = ("validation.py", "tableaux.py", "numba_partial.py")


def kernel_sources() -> list:
    """The kernel modules' files of this package, sorted by name."""
    return sorted(os.path.join(_HERE, n) for n in os.listdir(_HERE)
                  if n.startswith(KERNEL_PREFIX) and n.endswith(".py"))


@functools.lru_cache(maxsize=1)
def kernels_digest() -> str:
    """SHA-256 (shortened) of every kernel module and of the modules they fold in.

    One digest for all kernel modules: numba's cache entry of a kernel holds the
    compiled code of the kernels it calls, so a change to a callee in another
    module must miss the caller's entry too.  Computed once per process (every
    cached kernel asks for it when it is decorated).
    """
    h = hashlib.sha256()
    for path in kernel_sources() + [os.path.join(_HERE, n) for n in _COMPILED_IN]:
        h.update(os.path.basename(path).encode() + b"\0")
        try:
            with open(path, "rb") as fh:
                h.update(fh.read())
        except FileNotFoundError:
            h.update(b"-")
    return h.hexdigest()[:20]


class ContentHashCacheLocator(_caching._SourceFileBackedLocatorMixin, _caching._CacheLocator):
    """Cache locator keyed on the SHA-256 of the source (and what it folds in) and the module name,
    not on its path."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        digest = kernels_digest()
        # numba's cache entries remember the module they were compiled in (and re-import it on
        # load): the library (hammerbit.model.kernel_*) and each FMU build
        # (hammerbit_fmu_runtime_<build hash>.kernel_*) have their own entries.
        module = getattr(py_func, "__module__", None) or os.path.splitext(os.path.basename(py_file))[0]
        self._cache_path = os.path.join(DECISION["dir"], f"{module}-{digest}")

    def get_cache_path(self):
        return self._cache_path

    def ensure_cache_path(self):
        # the shipped kernels are only read: an FMU unpacked read-only loads them as they are
        if DECISION["shipped"] and os.path.isdir(self._cache_path):
            return
        super().ensure_cache_path()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not py_file or os.path.dirname(os.path.abspath(py_file)) != _HERE or not os.path.exists(py_file):
            return None
        # numba's locators create their directory here, when a kernel is decorated (at import);
        # this one leaves it to numba's ensure_cache_path() before the first save
        return cls(py_func, py_file)


def _register():
    # numba internal (no public hook for a cache locator): the class list numba tries in order.
    # tests/test_numba_internals.py fails on a numba release that changes it.
    impl = getattr(_caching, "CacheImpl", None) or getattr(_caching, "_CacheImpl")
    classes = impl._locator_classes
    # one registration per package directory, even if the package is imported under two names
    for c in classes:
        if getattr(c, "_hb_dir", None) == _HERE:
            return
    ContentHashCacheLocator._hb_dir = _HERE
    classes.insert(0, ContentHashCacheLocator)


_register()


def register_locator(locator_class) -> None:
    """Let numba try ``locator_class`` right after this package's own locator (once).

    For another package's kernels that call these (the continuation's variational equations): a
    subclass of :class:`ContentHashCacheLocator` that claims their files and keys their cache on
    :func:`kernels_digest` too, so a change to a kernel they call misses their entry.
    """
    impl = getattr(_caching, "CacheImpl", None) or getattr(_caching, "_CacheImpl")
    classes = impl._locator_classes
    if locator_class in classes:
        return
    at = max((i + 1 for i, c in enumerate(classes) if c.__name__ == "ContentHashCacheLocator"), default=0)
    classes.insert(at, locator_class)

# numba's first context refresh would import scipy.linalg for a flag the kernels never read
import_arraymath_lazily()

_REPORTED = []


def kernel_cache_counts() -> tuple:
    """(hits, misses) of the numba cache over every compiled function of this package's kernel
    modules imported so far."""
    hits = misses = 0
    prefix = f"{__package__}.{KERNEL_PREFIX}"
    dispatchers = {id(obj): obj for name, module in list(sys.modules.items()) if name.startswith(prefix)
                   for obj in vars(module).values() if hasattr(obj, "stats")}
    for obj in dispatchers.values():
        stats = getattr(obj, "stats", None)
        if stats is None or not hasattr(stats, "cache_misses"):
            continue
        hits += sum(stats.cache_hits.values())
        misses += sum(stats.cache_misses.values())
    return hits, misses


def first_use_report(seconds: float):
    """The one message of this process about where the kernels came from, or None.

    Returns ``(message, status)`` with the FMI status (0 OK: loaded, 1 Warning:
    compiled) on the first call, None afterwards.
    """
    if _REPORTED:
        return None
    _REPORTED.append(True)
    hits, misses = kernel_cache_counts()
    where = DECISION["dir"]
    if misses == 0:
        if DECISION["shipped"]:
            return (f"numba kernels loaded from the compiled cache shipped in the FMU ({where}, "
                    f"portable CPU target 'generic'): nothing compiled", 0)
        return (f"numba kernels loaded from the cache in {where} ({DECISION['reason']})", 0)
    if DECISION["shipped"]:
        why = "the shipped cache lacks them"
    else:
        why = DECISION["reason"]
    return (f"compiled {misses} numba kernel(s) in {seconds:.1f} s because {why}; the compiled code "
            f"is cached in {where}, so later processes load it", 1)
