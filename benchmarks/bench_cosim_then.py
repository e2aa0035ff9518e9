"""The default co-simulation now against the fixed H = 1 ms run of the code it replaced.

The goal is a default (adaptive, error-controlled) co-simulation whose
wall time is no larger than the fixed H = 1 ms run of the code it replaced:
commit :data:`THEN`, the last commit before the coupling-error estimate.  This script checks it out into a temporary git
worktree, installs it into a temporary virtual environment (sharing this
Python's packages, ``--no-deps``), warms both numba caches, and then runs the
drilling case with each, alternating, ``--repeats`` times::

    hammerbit cosim --string field-2200m --stop 2 --set frequency=22.5 --json

The old code's default is the fixed step H = 1 ms; today's default is the
adaptive step driven by the estimate (``--tol 1e-3``).  Reported: the stepping
loop's wall time (``wall_time_s`` of each JSON), the whole command's wall
time, the penetration of each, and their medians and ratios.  The current
fixed H = 1 ms run (``--step 0.001``) is measured in the same loop, for the
ratio against today's master as well.

Run ``python -m benchmarks --only cosim_then [--quick]`` (needs git and the
repository's history; about a minute, most of it installing and warming the old code).
"""
from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from benchmarks import REPO_ROOT, harness_command, save_result, stage_logger, summary_row

NAME = "cosim_then"

#: the code before the coupling-error estimate (the day the goal was set)
THEN = "9db0dea"
CASE = ["cosim", "--string", "field-2200m", "--stop", "2", "--set", "frequency=22.5", "--json"]


def _run(exe: str, args: list, env: dict) -> dict:
    t0 = time.perf_counter()
    p = subprocess.run([exe] + args, capture_output=True, text=True, env=env, check=False)
    total = time.perf_counter() - t0
    if p.returncode not in (0, 5):
        raise RuntimeError(f"{exe} {' '.join(args)} exited {p.returncode}: {p.stderr[-2000:]}")
    d = json.loads(p.stdout)
    return {"loop_s": float(d["wall_time_s"]), "total_s": total, "penetration_m": float(d["penetration_m"]),
            "returncode": p.returncode, "macro_steps": d.get("macro_steps")}


def _summary(rows: list) -> dict:
    return {"loop_s_median": statistics.median(r["loop_s"] for r in rows),
            "total_s_median": statistics.median(r["total_s"] for r in rows),
            "penetration_m": rows[-1]["penetration_m"], "runs": rows}


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Run the comparison; write ``results/cosim_then.json``."""
    log = stage_logger(NAME, verbose)
    repeats = 3 if quick else 5
    now_exe = os.path.join(os.path.dirname(sys.executable), "hammerbit")
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hammerbit-then-") as tmp:
        wt = os.path.join(tmp, "then")
        log(f"checking out {THEN} and installing it into a temporary environment ...")
        subprocess.run(["git", "-C", REPO_ROOT, "worktree", "add", "-q", "--detach", wt, THEN], check=True)
        try:
            venv = os.path.join(tmp, "venv")
            subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", venv], check=True)
            subprocess.run([os.path.join(venv, "bin", "pip"), "install", "-q", "--no-deps", "-e", wt],
                           check=True, cwd=tmp, capture_output=True)
            then_exe = os.path.join(venv, "bin", "hammerbit")
            env = dict(os.environ, HAMMERBIT_CACHE_DIR=os.path.join(tmp, "cache"))
            log("warming both (the old code compiles its kernels) ...")
            for exe, extra in ((then_exe, []), (now_exe, []), (now_exe, ["--step", "0.001"])):
                _run(exe, CASE + extra, env)
            then, now, now_fixed = [], [], []
            for i in range(repeats):
                log(f"round {i + 1}/{repeats} ...")
                then.append(_run(then_exe, CASE, env))
                now.append(_run(now_exe, CASE, env))
                now_fixed.append(_run(now_exe, CASE + ["--step", "0.001"], env))
        finally:
            subprocess.run(["git", "-C", REPO_ROOT, "worktree", "remove", "--force", wt], check=False)
    res = {"quick": quick, "command": harness_command(NAME, quick), "then_commit": THEN, "case": " ".join(CASE),
           "then_fixed_1ms": _summary(then), "now_default": _summary(now), "now_fixed_1ms": _summary(now_fixed)}
    res["ratio_now_default_to_then_fixed_loop"] = (res["now_default"]["loop_s_median"]
                                                   / res["then_fixed_1ms"]["loop_s_median"])
    res["ratio_now_default_to_then_fixed_total"] = (res["now_default"]["total_s_median"]
                                                    / res["then_fixed_1ms"]["total_s_median"])
    res["ratio_now_default_to_now_fixed_loop"] = (res["now_default"]["loop_s_median"]
                                                  / res["now_fixed_1ms"]["loop_s_median"])
    th, nd = res["then_fixed_1ms"], res["now_default"]
    res["summary"] = [summary_row(
        f"`hammerbit {' '.join(CASE)}`: the default run (adaptive, tol 1e-3) against the fixed 1 ms run of "
        f"the code before the estimate ({THEN}), stepping-loop wall time, median of {repeats} alternating runs "
        f"(whole commands: {nd['total_s_median']:.2f} s against {th['total_s_median']:.2f} s)",
        f"{nd['loop_s_median'] * 1e3:.0f} ms, penetration {nd['penetration_m'] * 1e3:.2f} mm",
        peer=f"{th['loop_s_median'] * 1e3:.0f} ms, penetration {th['penetration_m'] * 1e3:.2f} mm",
        ratio=f"{res['ratio_now_default_to_then_fixed_loop']:.2f}x wall",
        goal="<= 1x the fixed 1 ms run of the code before the estimate",
        met=res["ratio_now_default_to_then_fixed_loop"] <= 1.0, command=res["command"])]
    res["elapsed_s"] = time.perf_counter() - t_start
    path = save_result(NAME, res)
    log(f"now default / then fixed: loop {res['ratio_now_default_to_then_fixed_loop']:.2f}, command "
        f"{res['ratio_now_default_to_then_fixed_total']:.2f}; now default / now fixed (CLI): loop "
        f"{res['ratio_now_default_to_now_fixed_loop']:.2f}; {path}")
    return res


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
