"""Where the compiled kernels come from: the FMU's shipped cache, or a cache keyed on content.

numba's own locators key the cache directory on the source file's *path*.
An FMU is unzipped into a fresh temporary directory on every load, so those
caches never hit.  This locator keys the cache on the *content* of the source
file and on the module name: the same kernels, wherever they were unpacked,
find the same compiled code.  It only claims this package's own modules.

Two places, decided once when this module is imported (before numba is):

1. **Shipped** (an FMU built by ``hammerbit fmu build``): the build compiles
   the kernels for numba's portable CPU target (``NUMBA_CPU_NAME=generic``,
   no extra CPU features) into ``_compiled/`` next to this file and records
   the numba and Python versions and the machine in
   ``_compiled/manifest.json``.  On a machine that matches, this module sets
   the same two environment variables before numba is imported, and numba
   loads the shipped code: nothing is compiled.
2. **User cache** otherwise (the library, a mismatching machine, or numba
   already imported in this process for another CPU):
   ``$HAMMERBIT_CACHE_DIR``, else ``$XDG_CACHE_HOME/hammerbit/numba``
   (``~/.cache/hammerbit/numba``); if that cannot be written (read-only
   HOME), ``<tmp>/hammerbit-<uid>/numba``.  The first process compiles once,
   later processes load it.  A cache directory must be a directory of this
   user that other users cannot write (numba loads machine code from it into
   the process); otherwise this process compiles into a fresh private
   directory of its own and says why.

The shipped kernels are only read, so an FMU unpacked into a read-only
directory loads them all the same.

:func:`first_use_report` turns the outcome into one message for the FMI
logger (the reason, and where the compiled code went), so a compilation is
never silent.
"""
import functools
import hashlib
import json
import os
import platform
import stat
import sys
import tempfile

_HERE = os.path.dirname(os.path.abspath(__file__))

#: directory of the kernels compiled by the FMU build (absent in the library)
SHIPPED_DIR = os.path.join(_HERE, "_compiled")
MANIFEST = "manifest.json"

from .numba_target import PORTABLE_ENV, runs_portable, select_portable  # noqa: E402


def user_cache_root() -> str:
    """The user's cache directory of hammerbit's compiled kernels (may not be writable)."""
    env = os.environ.get("HAMMERBIT_CACHE_DIR")
    if env:
        return env
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(xdg, "hammerbit", "numba")


def _writable(path: str) -> bool:
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def untrusted(path: str):
    """Why compiled code must not be loaded from the directory ``path`` (None: it may be): it is
    not a directory (a link, say), belongs to another user, or other users can write to it."""
    try:
        st = os.lstat(path)
    except OSError as e:
        return f"{path} cannot be inspected ({e.strerror})"
    if not stat.S_ISDIR(st.st_mode):
        return f"{path} is not a directory"
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        return f"{path} belongs to the user id {st.st_uid}, not to this user ({os.getuid()})"
    if st.st_mode & stat.S_IWOTH:
        return f"other users can write to {path} (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def _private_cache(why: str) -> tuple:
    """(directory, note): a fresh directory only this process uses (it compiles into it)."""
    path = tempfile.mkdtemp(prefix="hammerbit-numba-")      # mode 0700, a new name
    return path, f"{why}, so this process compiles into its own new directory {path}"


def _user_cache() -> tuple:
    """(directory, note): the user cache, else a temporary one of this user; a directory that
    others could have planted code in is never used."""
    root = user_cache_root()
    if _writable(root):
        why = untrusted(root)
        return (root, None) if why is None else _private_cache(why)
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    base = os.path.join(tempfile.gettempdir(), f"hammerbit-{uid}")
    fallback = os.path.join(base, "numba")
    try:
        os.makedirs(fallback, mode=0o700, exist_ok=True)
    except OSError:
        pass                                  # untrusted() below says what is wrong
    why = untrusted(base) or untrusted(fallback)
    if why is not None:
        return _private_cache(f"{root} cannot be written (read-only HOME?) and {why}")
    return fallback, f"{root} cannot be written (read-only HOME?), so the cache is {fallback}"


def runtime_manifest() -> dict:
    """What a shipped cache must match: numba version, Python minor version, machine."""
    import numba  # noqa: PLC0415 -- only after the CPU target is decided
    return {"numba": numba.__version__, "python": "%d.%d" % sys.version_info[:2],
            "machine": platform.machine(), "cpu_name": PORTABLE_ENV["NUMBA_CPU_NAME"]}


def _shipped_mismatch(manifest: dict):
    """Why the shipped cache cannot be used in this process (None: it can)."""
    py = "%d.%d" % sys.version_info[:2]
    if manifest.get("python") != py:
        return f"the shipped kernels are for Python {manifest.get('python')}, this is Python {py}"
    if manifest.get("machine") != platform.machine():
        return (f"the shipped kernels are for {manifest.get('machine')}, this machine is "
                f"{platform.machine()}")
    if "numba" in sys.modules:
        from numba.core import config  # noqa: PLC0415
        if not runs_portable():
            from llvmlite import binding as ll  # noqa: PLC0415
            cpu = config.CPU_NAME or ll.get_host_cpu_name()
            return (f"numba was already imported in this process for the CPU {cpu!r}; the shipped "
                    f"kernels are compiled for the portable target 'generic'")
    else:
        for key, value in PORTABLE_ENV.items():
            have = os.environ.get(key)
            if have is not None and have != value:
                return f"the environment sets {key}={have!r}; the shipped kernels are for {value!r}"
    from importlib.metadata import PackageNotFoundError, version  # noqa: PLC0415
    try:
        nb = version("numba")
    except PackageNotFoundError:
        return "numba is not installed in this Python"
    if manifest.get("numba") != nb:
        return f"the shipped kernels are for numba {manifest.get('numba')}, this is numba {nb}"
    return None


def _decide() -> dict:
    """Pick the cache directory of this process (sets the CPU target if the shipped one fits)."""
    path = os.path.join(SHIPPED_DIR, MANIFEST)
    if not os.path.isfile(path):
        root, note = _user_cache()
        return {"dir": root, "shipped": False, "reason": "no compiled kernels are shipped with this copy "
                "of the model" + (f"; {note}" if note else "")}
    try:
        with open(path) as fh:
            manifest = json.load(fh)
    except (OSError, ValueError) as e:
        manifest, why = {}, f"the shipped manifest cannot be read ({e})"
    else:
        why = _shipped_mismatch(manifest)
    if why is None:
        select_portable()
        return {"dir": SHIPPED_DIR, "shipped": True, "reason": None}
    root, note = _user_cache()
    return {"dir": root, "shipped": False, "reason": why + (f"; {note}" if note else "")}


#: the decision of this process: {"dir", "shipped", "reason"}
DECISION = _decide()

from numba.core import caching as _caching  # noqa: E402  (after the CPU target is set)

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
        if not py_file or os.path.dirname(os.path.abspath(py_file)) != _HERE:
            return None
        return super().from_function(py_func, py_file)


def _register():
    impl = getattr(_caching, "CacheImpl", None) or getattr(_caching, "_CacheImpl")
    classes = impl._locator_classes
    # one registration per package directory, even if the package is imported under two names
    for c in classes:
        if getattr(c, "_hb_dir", None) == _HERE:
            return
    ContentHashCacheLocator._hb_dir = _HERE
    classes.insert(0, ContentHashCacheLocator)


_register()

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
