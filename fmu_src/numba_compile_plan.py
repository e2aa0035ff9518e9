"""Recording the compile plan that :mod:`.numba_compile_ahead` follows: ``python -m hammerbit.model.numba_compile_plan --record``.

The plan lists, per kernel entry point, the callees numba finishes while it
compiles that entry point with an empty cache (kernel module, function name,
numba signature), in order.  It is keyed on the kernels' digest and the numba
version; re-record it after a kernel edit or a numba upgrade (a stale plan is
ignored, and the first compile then runs in one process).
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
import tempfile

from . import numba_cache
from . import numba_compile_ahead
from .kernel_driver import ENTRY_LOOP
from .presets import preset
from .solver_options import SolverOptions
from .stepping import Stepper

__all__ = ["record", "record_all"]

#: a scene that compiles each entry point, as ``(method, energy block)`` (``Stepper`` picks the entry
#: from them: a hammer-only system runs its method's bound copy, the energy block the general one)
RECORD_SCENE = {"advance_hammer": ("adaptive", False), "advance_dp54": ("dp54", False),
                "advance_rk4": ("rk4", False), "advance": ("rk4", True)}


def record(entry: str) -> list:
    """Compile ``entry`` in this process (empty cache) and return the callees numba finished, in
    order, as ``(kernel module, function name, signature)``."""
    import numba  # noqa: PLC0415,F401 -- after numba_cache has picked the CPU target
    from numba.core import event  # noqa: PLC0415
    numba_compile_ahead.ENABLED = False  # every callee compiles in this (recording) process
    prefix = f"{__package__}.{numba_cache.KERNEL_PREFIX}"
    done = []

    class _Listener(event.Listener):
        def on_start(self, ev):
            pass

        def on_end(self, ev):
            disp = ev.data["dispatcher"]
            name = disp.py_func.__name__
            module = disp.py_func.__module__ or ""
            if module.startswith(prefix) and getattr(sys.modules[module], name, None) is disp \
                    and name not in (entry, ENTRY_LOOP[entry]):
                # the loop each entry point runs is left to the compiling process, as the entry
                # point is (a helper starting with it would type the same callees in the same order)
                done.append((module[len(__package__) + 1:], name, tuple(ev.data["args"])))

    with event.install_listener("numba:compile", _Listener()):
        g = preset("paper-fig9")
        method, energy = RECORD_SCENE[entry]
        st = Stepper(g, solver=SolverOptions(method=method), energy=energy)
        if st.entry != entry:
            raise RuntimeError(f"the recording scene runs {st.entry}, not {entry}")
        st.advance(g.period)
    return done


def _record_entry(entry: str) -> None:
    """(In a fresh process with an empty cache) print the plan of ``entry`` as a hex pickle."""
    print(pickle.dumps(record(entry)).hex())


def record_all() -> dict:
    """Record the plan of every entry point, each in a fresh process with an empty cache, and
    write it to :data:`.numba_compile_ahead.PLAN_FILE`."""
    import numba  # noqa: PLC0415
    entries = {}
    for entry in RECORD_SCENE:
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, HAMMERBIT_CACHE_DIR=tmp)
            r = subprocess.run([sys.executable, "-c", f"from {__package__} import numba_compile_plan as c; "
                                f"c._record_entry({entry!r})"], env=env, check=True, capture_output=True, text=True)
            entries[entry] = pickle.loads(bytes.fromhex(r.stdout.strip().splitlines()[-1]))
    plan = {"numba": numba.__version__, "digest": numba_cache.kernels_digest(), "entries": entries}
    with open(numba_compile_ahead.PLAN_FILE, "wb") as fh:
        pickle.dump(plan, fh)
    return plan


if __name__ == "__main__":
    if sys.argv[1:] != ["--record"]:
        sys.exit("usage: python -m hammerbit.model.numba_compile_plan --record")
    recorded = record_all()
    print(f"{numba_compile_ahead.PLAN_FILE}: " + ", ".join(f"{len(v)} callees of {k}"
                                                         for k, v in recorded["entries"].items()))
