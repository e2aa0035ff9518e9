"""The default co-simulation now against the fixed H = 1 ms run of the code it replaced.

Issue 15 asks for a default (adaptive, error-controlled) co-simulation whose
wall time is no larger than the fixed H = 1 ms run of the day the issue was
filed.  That code is commit :data:`THEN` (the last commit before the
coupling-error estimate).  This script checks it out into a temporary git
worktree, installs it into a temporary virtual environment (sharing this
Python's packages, ``--no-deps``), warms both numba caches, and then runs the
drilling case of the issue with each, alternating, ``--repeats`` times::

    hammerbit cosim --string field-2200m --stop 2 --set frequency=22.5 --json

The old code's default is the fixed step H = 1 ms; today's default is the
adaptive step driven by the estimate (``--tol 1e-3``).  Reported: the stepping
loop's wall time (``wall_time_s`` of each JSON), the whole command's wall
time, the penetration of each, and their medians and ratios.  The current
fixed H = 1 ms run (``--step 0.001``) is measured in the same loop, for the
ratio against today's master as well.

Usage: ``python -m benchmarks.cosim_then_now [--repeats N] [--update]``
(results in the scratch directory unless ``--update``; needs git and the
repository's history).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from benchmarks import REPO_ROOT, configure_output, save_result

#: the code of the day issue 15 was filed (before the coupling-error estimate)
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="alternating runs of each (default 5)")
    ap.add_argument("--update", action="store_true", help="write benchmarks/results (tracked)")
    a = ap.parse_args(argv)
    configure_output(a.update)
    now_exe = os.path.join(os.path.dirname(sys.executable), "hammerbit")
    with tempfile.TemporaryDirectory(prefix="hammerbit-then-") as tmp:
        wt = os.path.join(tmp, "then")
        subprocess.run(["git", "-C", REPO_ROOT, "worktree", "add", "-q", "--detach", wt, THEN], check=True)
        try:
            venv = os.path.join(tmp, "venv")
            subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", venv], check=True)
            subprocess.run([os.path.join(venv, "bin", "pip"), "install", "-q", "--no-deps", "-e", wt],
                           check=True, cwd=tmp, capture_output=True)
            then_exe = os.path.join(venv, "bin", "hammerbit")
            env = dict(os.environ, HAMMERBIT_CACHE_DIR=os.path.join(tmp, "cache"))
            for exe, extra in ((then_exe, []), (now_exe, []), (now_exe, ["--step", "0.001"])):
                _run(exe, CASE + extra, env)  # compile / load the kernels, warm the file cache
            then, now, now_fixed = [], [], []
            for _ in range(a.repeats):
                then.append(_run(then_exe, CASE, env))
                now.append(_run(now_exe, CASE, env))
                now_fixed.append(_run(now_exe, CASE + ["--step", "0.001"], env))
        finally:
            subprocess.run(["git", "-C", REPO_ROOT, "worktree", "remove", "--force", wt], check=False)
    res = {"command": "python -m benchmarks.cosim_then_now", "then_commit": THEN, "case": " ".join(CASE),
           "then_fixed_1ms": _summary(then), "now_default": _summary(now), "now_fixed_1ms": _summary(now_fixed)}
    res["ratio_now_default_to_then_fixed_loop"] = (res["now_default"]["loop_s_median"]
                                                   / res["then_fixed_1ms"]["loop_s_median"])
    res["ratio_now_default_to_then_fixed_total"] = (res["now_default"]["total_s_median"]
                                                    / res["then_fixed_1ms"]["total_s_median"])
    res["ratio_now_default_to_now_fixed_loop"] = (res["now_default"]["loop_s_median"]
                                                  / res["now_fixed_1ms"]["loop_s_median"])
    path = save_result("cosim_then_now", res)
    print(f"then ({THEN}) fixed 1 ms: loop {res['then_fixed_1ms']['loop_s_median'] * 1e3:.1f} ms, "
          f"command {res['then_fixed_1ms']['total_s_median']:.2f} s, penetration "
          f"{res['then_fixed_1ms']['penetration_m'] * 1e3:.3f} mm")
    print(f"now default (adaptive): loop {res['now_default']['loop_s_median'] * 1e3:.1f} ms, "
          f"command {res['now_default']['total_s_median']:.2f} s, penetration "
          f"{res['now_default']['penetration_m'] * 1e3:.3f} mm")
    print(f"now fixed 1 ms: loop {res['now_fixed_1ms']['loop_s_median'] * 1e3:.1f} ms")
    print(f"now default / then fixed: loop {res['ratio_now_default_to_then_fixed_loop']:.2f}, "
          f"command {res['ratio_now_default_to_then_fixed_total']:.2f}; now default / now fixed: loop "
          f"{res['ratio_now_default_to_now_fixed_loop']:.2f}")
    print(f"results: {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
