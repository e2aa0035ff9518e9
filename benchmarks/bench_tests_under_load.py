"""The README's test command beside a CPU hog: the fast set must pass on a busy machine.

The fast set asserts no wall time (timing goals live in ``benchmarks/``; hang
guards exclude compilation and are generous), so it must pass however busy
the machine is.  This benchmark checks that: it starts ``HOG_PER_CORE`` busy
processes per core (pure Python spin loops, niced to 0 like the tests), then
runs ``python -m pytest -q`` twice in a row -- first with an empty numba cache
(every kernel compiles under load), then warm -- and reports both outcomes
with the load average seen.  Goal: both runs pass.

``--quick`` runs two test files only (``tests/test_stress.py`` and
``tests/test_stepper.py``, the ones with hang guards).  The integrator runs
the full version: ``python -m benchmarks --only tests_under_load``.
"""
from __future__ import annotations

import multiprocessing
import os
import shutil
import tempfile
import time

from benchmarks import harness_command, save_result, summary_row
from benchmarks.bench_tests import run_pytest

NAME = "tests_under_load"
#: busy processes per core: with the test run's own workers the load is about 3 per core
#: (load 6-8 on two cores, the load at which the first report saw timed tests fail)
HOG_PER_CORE = 3
QUICK_FILES = ["tests/test_stress.py", "tests/test_stepper.py"]


def _spin(stop) -> None:
    """A CPU hog: spins until ``stop`` is set."""
    x = 0
    while not stop.is_set():
        for _ in range(100_000):
            x = (x * 1103515245 + 12345) & 0xFFFFFFFF


def run(quick: bool = False) -> dict:
    cmd = harness_command(NAME, quick)
    args = QUICK_FILES if quick else []
    n_hogs = HOG_PER_CORE * (os.cpu_count() or 1)
    ctx = multiprocessing.get_context("spawn")
    stop = ctx.Event()
    hogs = [ctx.Process(target=_spin, args=(stop,), daemon=True) for _ in range(n_hogs)]
    cache = tempfile.mkdtemp(prefix="hammerbit-tests-load-cache-")
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=cache)
    for h in hogs:
        h.start()
    try:
        time.sleep(5.0)                       # let the load average rise before the first run
        load_before = os.getloadavg()
        cold = run_pytest(args, env)
        load_mid = os.getloadavg()
        warm = run_pytest(args, env)
        load_after = os.getloadavg()
    finally:
        stop.set()
        for h in hogs:
            h.join(timeout=10)
            if h.is_alive():
                h.terminate()
        shutil.rmtree(cache, ignore_errors=True)
    what = "python -m pytest -q" + ("".join(" " + a for a in args))
    load = max(load_mid[0], load_after[0])
    rows = [
        summary_row(f"`{what}` beside {n_hogs} CPU hogs, empty numba cache ({cold['summary']}); "
                    f"1-min load average {load_mid[0]:.1f}", "pass" if cold["returncode"] == 0 else "FAIL",
                    goal="passes", met=cold["returncode"] == 0, command=cmd),
        summary_row(f"same, run again with the warm cache ({warm['summary']}); 1-min load average "
                    f"{load_after[0]:.1f}", "pass" if warm["returncode"] == 0 else "FAIL",
                    goal="passes", met=warm["returncode"] == 0, command=cmd),
    ]
    result = {"benchmark": NAME, "quick": quick, "command": cmd, "hogs": n_hogs,
              "load_average": {"before": load_before, "after_cold": load_mid, "after_warm": load_after,
                               "max_1min": load},
              "cold": cold, "warm": warm, "summary": rows}
    save_result(NAME, result)
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
