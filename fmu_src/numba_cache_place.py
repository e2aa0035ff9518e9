"""Where the compiled kernels come from: the FMU's shipped cache or the user's cache (imports no numba).

Two places:

1. **Shipped** (an FMU built by ``hammerbit fmu build``): the build compiles
   the kernels for numba's portable CPU target (``NUMBA_CPU_NAME=generic``,
   no extra CPU features) into ``_compiled/`` next to this file and records
   the numba and Python versions and the machine in
   ``_compiled/manifest.json``.  The FMU's entry module calls
   :func:`select_shipped_target` before numba is imported: on a machine that
   matches it sets those two environment variables, and numba loads the
   shipped code: nothing is compiled.
2. **User cache** otherwise (the library, a mismatching machine, or numba
   already imported in this process for another CPU):
   ``$HAMMERBIT_CACHE_DIR``, else ``$XDG_CACHE_HOME/hammerbit/numba``
   (``~/.cache/hammerbit/numba``); if that cannot be written (read-only
   HOME), ``<tmp>/hammerbit-<uid>/numba``.  The first process compiles once,
   later processes load it.

Nothing happens at import: :func:`decision` decides once, on first use (no
environment variable set, no directory created; numba creates the directory
when it first saves).
"""
import json
import os
import platform
import sys
import tempfile

from .numba_target import PORTABLE_ENV, runs_portable, select_portable

__all__ = ["SHIPPED_DIR", "MANIFEST", "user_cache_root", "runtime_manifest", "decision",
           "select_shipped_target"]

_HERE = os.path.dirname(os.path.abspath(__file__))

#: directory of the kernels compiled by the FMU build (absent in the library)
SHIPPED_DIR = os.path.join(_HERE, "_compiled")
MANIFEST = "manifest.json"



def user_cache_root() -> str:
    """The user's cache directory of hammerbit's compiled kernels (may not be writable)."""
    env = os.environ.get("HAMMERBIT_CACHE_DIR")
    if env:
        return env
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(xdg, "hammerbit", "numba")


def _writable(path: str) -> bool:
    """True if ``path`` can be created and written, judged from its nearest existing ancestor
    (nothing is created here: numba creates the directory when it first saves)."""
    path = os.path.abspath(path)
    while not os.path.exists(path):
        parent = os.path.dirname(path)
        if parent == path:
            return False
        path = parent
    return os.path.isdir(path) and os.access(path, os.W_OK | os.X_OK)


def _user_cache() -> tuple:
    """(directory, note): the user cache, or a temporary one if it cannot be written."""
    root = user_cache_root()
    if _writable(root):
        return root, None
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    fallback = os.path.join(tempfile.gettempdir(), f"hammerbit-{uid}", "numba")
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


def _decide(select_target: bool) -> dict:
    """Pick the cache directory of this process; with ``select_target`` also the portable CPU
    target when the shipped kernels fit (before numba is imported)."""
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
    if why is None and select_target:
        select_portable()
    if why is None and not runs_portable():
        why = ("the portable CPU target was not selected before numba was imported "
               "(numba_cache_place.select_shipped_target() does it)")
    if why is None:
        return {"dir": SHIPPED_DIR, "shipped": True, "reason": None}
    root, note = _user_cache()
    return {"dir": root, "shipped": False, "reason": why + (f"; {note}" if note else "")}


_DECISION = []


def decision() -> dict:
    """The decision of this process, ``{"dir", "shipped", "reason"}``, made on the first call
    (without selecting a CPU target: see :func:`select_shipped_target`)."""
    if not _DECISION:
        _DECISION.append(_decide(select_target=False))
    return _DECISION[0]


def select_shipped_target() -> dict:
    """Decide now, selecting the portable CPU target if the shipped kernels fit this process.

    For the FMU's entry module, before numba is imported; the decision then holds for the
    process (a later call returns it unchanged).
    """
    if not _DECISION:
        _DECISION.append(_decide(select_target=True))
    return _DECISION[0]
