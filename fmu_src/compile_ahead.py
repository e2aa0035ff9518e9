"""A first compile on two cores: a helper process compiles callees while this process compiles the rest.

numba compiles a kernel entry point and every function it calls in one
thread: typing the entry point compiles each callee when it is first met.
The callees are independent compilations cached on disk one by one, so a
second process can compile some of them at the same time; when this process
reaches one the helper has finished, numba loads it from the cache instead.

What a helper must compile (the callees' names and numba signatures, in the
order numba finishes them) is recorded once from a real compile into
``_compile_plan.pkl`` (``python -m hammerbit.model.compile_ahead --record``).
The plan names the source it was recorded from (:func:`_numba_cache.kernels_digest`)
and the numba version; a plan for other kernels or another numba is ignored and
the compile simply runs in one process, as it would without a plan.

The helper walks the plan from its end while this process types the entry
point from its start, so they meet in the middle; it stops when the entry
point is in the cache, and :func:`finish` ends it when this process is done.
Only a plain Python process starts a helper: the FMU turns this off
(:data:`ENABLED`), since an FMI host is no place to start interpreters.
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))
PLAN_FILE = os.path.join(_HERE, "_compile_plan.pkl")

#: start a helper process on a first compile (the FMU sets it False)
ENABLED = True

_helper = None


def _plan_for(entry: str):
    """The plan's [(function name, signature), ...] for ``entry``, or None if absent or stale."""
    try:
        with open(PLAN_FILE, "rb") as fh:
            plan = pickle.load(fh)
        import numba  # noqa: PLC0415
        from . import _numba_cache  # noqa: PLC0415
        if plan.get("numba") != numba.__version__ or plan.get("digest") != _numba_cache.kernels_digest():
            return None
        return plan["entries"].get(entry)
    except Exception:  # noqa: BLE001 -- no plan, an unreadable one, or types of another numba
        return None


def start(entry: str) -> bool:
    """Start a helper for the first compile of ``entry`` (the caller knows it is not cached).

    Returns True if a helper runs.
    """
    global _helper
    if not ENABLED or _helper is not None or (os.cpu_count() or 1) < 2:
        return False
    if not os.path.basename(sys.executable or "").startswith("python"):
        return False
    if not _plan_for(entry):
        return False
    from . import _numba_cache  # noqa: PLC0415
    env = dict(os.environ)
    env["HAMMERBIT_CACHE_DIR"] = _numba_cache.cache_root()  # the same cache as this process
    pkg = __package__
    try:
        # same process group: a Ctrl-C in the terminal ends the helper too
        code = f"from {pkg} import compile_ahead as c; c._helper_main({entry!r})"
        _helper = subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.DEVNULL,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        _helper = None
        return False
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


def _helper_main(entry: str) -> None:
    """The helper: compile the plan's callees of ``entry`` from the last to the first."""
    from . import kernels as K  # noqa: PLC0415
    from .stepping import kernels_cached  # noqa: PLC0415
    items = _plan_for(entry) or []
    for name, sig in reversed(items):
        if kernels_cached(entry):
            return
        disp = getattr(K, name, None)
        if disp is None:
            continue
        try:
            disp.compile(sig)
        except Exception:  # noqa: BLE001 -- the main process compiles whatever the helper could not
            continue


#: a scene that compiles each entry point (``Stepper`` picks the entry from the method)
_RECORD_METHOD = {"advance_hammer": "adaptive", "advance": "rk4"}


def record(entry: str) -> list:
    """Compile ``entry`` in this process (empty cache) and return the callees numba finished, in order."""
    global ENABLED
    from numba.core import event  # noqa: PLC0415
    from . import kernels as K  # noqa: PLC0415
    ENABLED = False  # every callee compiles in this process
    done = []

    class _Listener(event.Listener):
        def on_start(self, ev):
            pass

        def on_end(self, ev):
            disp = ev.data["dispatcher"]
            name = disp.py_func.__name__
            if getattr(K, name, None) is disp and name != entry:
                done.append((name, tuple(ev.data["args"])))

    from .params import preset  # noqa: PLC0415
    from .stepping import SolverOptions, Stepper  # noqa: PLC0415
    with event.install_listener("numba:compile", _Listener()):
        g = preset("paper-fig9")
        st = Stepper(g, solver=SolverOptions(method=_RECORD_METHOD[entry]))
        assert st._entry == entry
        st.advance(g.period)
    return done


def _record_entry(entry: str) -> None:
    """(In a fresh process with an empty cache) print the plan of ``entry`` as a hex pickle."""
    print(pickle.dumps(record(entry)).hex())


def _record_main() -> None:
    """Record the plan of every entry point, each in a fresh process with an empty cache."""
    import tempfile  # noqa: PLC0415
    import numba  # noqa: PLC0415
    from . import _numba_cache  # noqa: PLC0415
    entries = {}
    for entry in _RECORD_METHOD:
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, HAMMERBIT_CACHE_DIR=tmp)
            r = subprocess.run([sys.executable, "-c", f"from {__package__} import compile_ahead as c; "
                                f"c._record_entry({entry!r})"], env=env, check=True, capture_output=True, text=True)
            entries[entry] = pickle.loads(bytes.fromhex(r.stdout.strip().splitlines()[-1]))
    plan = {"numba": numba.__version__, "digest": _numba_cache.kernels_digest(), "entries": entries}
    with open(PLAN_FILE, "wb") as fh:
        pickle.dump(plan, fh)
    print(f"{PLAN_FILE}: " + ", ".join(f"{len(v)} callees of {k}" for k, v in entries.items()))


if __name__ == "__main__":
    if sys.argv[1:] != ["--record"]:
        sys.exit("usage: python -m hammerbit.model.compile_ahead --record")
    _record_main()
