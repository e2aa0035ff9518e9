"""A first compile on two cores: a helper process compiles callees while this process compiles the rest.

numba compiles a kernel entry point and every function it calls in one
thread: typing the entry point compiles each callee when it is first met.
The callees are independent compilations cached on disk one by one, so a
second process can compile some of them at the same time; when this process
reaches one the helper has finished, numba loads it from the cache instead.

What a helper must compile (the callees' names and numba signatures, in the
order numba finishes them) is recorded once from a real compile into
``_compile_plan.pkl`` (``python -m hammerbit.model.numba_compile_plan --record``).
The plan is for one numba version (a plan for another one is ignored and the
compile simply runs in one process, as it would without a plan).  An entry
whose function is gone or takes another number of arguments is skipped; any
other stale entry costs the helper one useless compile and nothing else (the
plan only decides what is compiled early, never what runs), so an edit of the
kernels that keeps their signatures keeps the plan useful.

The helper walks the plan from its end while this process types the entry
point from its start, so they meet in the middle; it stops when the entry
point is in the cache, and :func:`finish` ends it when this process is done.
Only a plain Python process starts a helper: the FMU turns this off
(:data:`ENABLED`), since an FMI host is no place to start interpreters.
"""
from __future__ import annotations

import atexit
import importlib
import os
import pickle
import subprocess
import sys

from . import numba_cache
from .numba_compile_notice import kernels_cached

_HERE = os.path.dirname(os.path.abspath(__file__))
PLAN_FILE = os.path.join(_HERE, "_compile_plan.pkl")

#: start a helper process on a first compile (a switch for the user; the FMU's steppers ask for
#: no helper through ``Stepper(compile_helper=False)`` instead)
ENABLED = True

_helper = None


def plan_for(entry: str):
    """The plan's [(kernel module, function name, signature), ...] for ``entry`` whose functions
    exist with that many arguments, or None without a plan for this numba."""
    try:
        with open(PLAN_FILE, "rb") as fh:
            plan = pickle.load(fh)
        import numba  # noqa: PLC0415 -- numba_cache picks the CPU target first
        if plan.get("numba") != numba.__version__:
            return None
        items = plan["entries"].get(entry)
    except Exception:  # noqa: BLE001 -- no plan, an unreadable one, or types of another numba
        return None
    if not items:
        return None
    return [item for item in items if _resolves(*item)] or None


def _resolves(module: str, name: str, sig) -> bool:
    """True if ``module.name`` is a kernel of this package taking ``len(sig)`` arguments."""
    if not module.startswith(numba_cache.KERNEL_PREFIX):
        return False
    try:
        disp = getattr(importlib.import_module(f"{__package__}.{module}"), name)
        return disp.py_func.__code__.co_argcount == len(sig)
    except Exception:  # noqa: BLE001 -- gone, or not a dispatcher
        return False


def start(entry: str) -> bool:
    """Start a helper for the first compile of ``entry`` (the caller knows it is not cached).

    Returns True if a helper runs.
    """
    global _helper
    if not ENABLED or _helper is not None or (os.cpu_count() or 1) < 2:
        return False
    if not os.path.basename(sys.executable or "").startswith("python"):
        return False
    if not plan_for(entry):
        return False
    env = dict(os.environ)
    env["HAMMERBIT_CACHE_DIR"] = numba_cache.cache_root()  # the same cache as this process
    pkg = __package__
    try:
        # same process group: a Ctrl-C in the terminal ends the helper too
        code = f"from {pkg} import numba_compile_ahead as c; c.helper_main({entry!r})"
        _helper = subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.DEVNULL,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        _helper = None
        return False
    atexit.register(finish)     # an interrupted caller does not leave the helper compiling
    return True


def running() -> bool:
    """True while a helper started by this process may run."""
    return _helper is not None


def finish() -> None:
    """End the helper, if one runs (this process has compiled what it needed)."""
    global _helper
    h, _helper = _helper, None
    if h is None:
        return
    if h.poll() is None:
        h.terminate()
    try:
        h.wait(timeout=5)
    except subprocess.TimeoutExpired:  # pragma: no cover
        h.kill()


def helper_main(entry: str) -> None:
    """The helper: compile the plan's callees of ``entry`` from the last to the first."""
    items = plan_for(entry) or []
    for module, name, sig in reversed(items):
        if kernels_cached(entry):
            return
        disp = getattr(importlib.import_module(f"{__package__}.{module}"), name)
        try:
            disp.compile(sig)
        except Exception:  # noqa: BLE001 -- the main process compiles whatever the helper could not
            continue
