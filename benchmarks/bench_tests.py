"""Time of the README's test command, ``python -m pytest -q``, with an empty and a warm numba cache.

The first run gets a fresh, empty ``HAMMERBIT_CACHE_DIR`` (numba compiles every
kernel the tests use); the second run reuses that cache.  Goals: <= 3 min
empty, <= 90 s warm (issue 30, for the fast set as it grew).  ``--quick`` times only the warm run of one test file.

The slow and stress tests (``-m slow``) are not part of the command and not
timed here.  Each run also records where its CPU time went (``cpu``): inside
the tests, their own and their subprocesses', and outside them (starting,
collecting and shutting down the test processes), with the tests of the
largest CPU time (:mod:`benchmarks.pytest_cpu`).  CPU time varies less than
wall time on a shared machine.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

from benchmarks import REPO_ROOT, harness_command, save_result, summary_row
from benchmarks.pytest_cpu import DIR_VARIABLE, summarise

NAME = "tests"
COMMAND = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
#: the plugin that records each test's CPU time (not part of the README's command: it only reads clocks)
CPU_PLUGIN = ["-p", "benchmarks.pytest_cpu"]
#: pytest's --durations report: the slowest phases (setup/call/teardown) land in the JSON.
SLOWEST = 15
_DURATION = re.compile(r"^\s*([\d.]+)s (setup|call|teardown)\s+(\S.*)$")
GOAL_COLD_S = 180.0
GOAL_WARM_S = 90.0


def run_pytest(args, env) -> dict:
    """Run the test command with ``args`` in ``env``: wall and CPU time, exit code, counts, slowest
    phases, and where the CPU time went."""
    rows = tempfile.mkdtemp(prefix="hammerbit-tests-cpu-")
    env = dict(env, **{DIR_VARIABLE: rows})
    # the workers import the plugin by name: the repository on their path
    env["PYTHONPATH"] = os.pathsep.join(filter(None, (str(REPO_ROOT), env.get("PYTHONPATH"))))
    t0 = time.perf_counter()
    c0 = os.times()
    p = subprocess.run(COMMAND + CPU_PLUGIN + [f"--durations={SLOWEST}"] + list(args), cwd=REPO_ROOT, env=env,
                       capture_output=True, text=True)
    c1 = os.times()
    wall = time.perf_counter() - t0
    cpu = (c1.children_user - c0.children_user) + (c1.children_system - c0.children_system)
    where = summarise(rows, cpu, SLOWEST)
    shutil.rmtree(rows, ignore_errors=True)
    last = (p.stdout.strip().splitlines() or [""])[-1]
    counts = {k: int(v) for v, k in re.findall(r"(\d+) (passed|failed|skipped|deselected|error)", last)}
    return {"wall_s": wall, "cpu_s": cpu, "cpu": where,
            "returncode": p.returncode, "summary": last, "counts": counts,
            "slowest": [{"seconds": float(m.group(1)), "phase": m.group(2), "test": m.group(3)}
                        for m in map(_DURATION.match, p.stdout.splitlines()) if m]}


def run(quick: bool = False) -> dict:
    cmd = harness_command(NAME, quick)
    args = ["tests/test_docs.py"] if quick else []
    cache = tempfile.mkdtemp(prefix="hammerbit-tests-cache-")
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=cache)
    try:
        cold = run_pytest(args, env)
        warm = run_pytest(args, env)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    what = "python -m pytest -q" + (" tests/test_docs.py" if quick else "")
    rows = [
        summary_row(f"`{what}` with an empty numba cache (compiles the kernels), wall",
                    f"{cold['wall_s']:.0f} s", goal=f"<= {GOAL_COLD_S:.0f} s",
                    met=cold["wall_s"] <= GOAL_COLD_S, command=cmd),
        summary_row(f"`{what}` with a warm cache, wall ({warm['summary']})",
                    f"{warm['wall_s']:.0f} s", goal=f"<= {GOAL_WARM_S:.0f} s",
                    met=warm["wall_s"] <= GOAL_WARM_S, command=cmd),
        summary_row("the warm run's CPU time: inside the tests (their own + their subprocesses'), "
                    "outside them (starting, collecting, shutting down the test processes)",
                    f"{warm['cpu_s']:.0f} s: {warm['cpu']['in_tests_own_s']:.0f} + "
                    f"{warm['cpu']['in_tests_subprocesses_s']:.0f} s in, {warm['cpu']['outside_tests_s']:.0f} s out",
                    command=cmd),
    ]
    result = {"benchmark": NAME, "quick": quick, "command": cmd, "pytest": " ".join(["python"] + COMMAND[1:] + args),
              "cold": cold, "warm": warm, "goals_s": {"cold": GOAL_COLD_S, "warm": GOAL_WARM_S}, "summary": rows}
    save_result(NAME, result)
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
