"""Throughput of a bifurcation sweep and start-up time of the CLI (issue 6).

1. **Sweep throughput**: forcing periods integrated per second of wall time by
   :func:`hammerbit.studies.bifurcation.bifurcation` over ``paper-fig9`` (no impact),
   a in [0, 0.25], rtol 1e-8 (atol 1e-10), with ``workers=2`` (the machine's
   two cores) and ``workers=1``.  The number is the sweep's own
   ``periods_per_second`` (compilation excluded: ``bifurcation`` warms up
   first); the best of a few repeats.  Goal: >= 200,000 periods/s.
   The cost per forcing period against a (single thread) is also measured.
2. **CLI start-up**: the README's main command, ``hammerbit simulate --preset
   paper-fig9 --set a=0.083 --periods 300 --plot scene.png`` (the figure goes to
   a temporary folder), in a subprocess, first with a fresh, empty
   ``HAMMERBIT_CACHE_DIR`` (cold: numba compiles the kernels), then again with
   that cache (warm).  Goals: cold <= 15 s, warm <= 1 s.  The compile notice
   on stderr is checked: once in the cold run, never in a warm one.
   ``python -c pass`` is measured too, as the floor of any Python command,
   and the imports of numba and of matplotlib, which the command does in two
   processes (:mod:`hammerbit.scene.figure_worker`).
3. **Compiled-code speed, fresh against cache-loaded** (full run only): the
   same 100-period scene timed in a process that compiled the kernels itself
   and in a process that loaded them from the on-disk cache.

Run ``python -m benchmarks --only throughput [--quick]``.
"""
from __future__ import annotations

import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from benchmarks import (stage_logger, REPO_ROOT, fmt_ratio, fmt_time, harness_command, kernel_source,
                        machine_info, save_result, summary_row)

NAME = "throughput"
GOAL_PPS = 200_000.0
RTOL = 1e-8
ATOL = 1e-10
A_RANGE = (0.0, 0.25)
CLI_ARGS = ["simulate", "--preset", "paper-fig9", "--set", "a=0.083", "--periods", "300", "--plot", "scene.png"]
GOAL_COLD_S = 15.0
GOAL_WARM_S = 1.0
NOTICE = "hammerbit: compiling the solver kernels"

_KERNEL_SPEED_SCRIPT = r"""
import json, sys, time
from hammerbit.model.params import preset
from hammerbit.model.stepping import SolverOptions, Stepper
g = preset('paper-fig9')
o = SolverOptions(rtol=1e-8, atol=1e-10)
t0 = time.perf_counter()
Stepper(g, solver=o).advance(g.period)
first = time.perf_counter() - t0
best = float('inf')
for _ in range(int(sys.argv[1])):
    st = Stepper(g, solver=o)
    t0 = time.perf_counter()
    st.advance(100 * g.period)
    best = min(best, time.perf_counter() - t0)
print(json.dumps({"first_call_s": first, "best_100_periods_s": best}))
"""


def _config(quick: bool) -> dict:
    if quick:
        return {"num": 40, "periods": 200, "keep": 32, "repeats": 1, "cold_runs": 1, "warm_runs": 3,
                "per_a_num": 0, "kernel_speed": False}
    return {"num": 200, "periods": 300, "keep": 64, "repeats": 3, "cold_runs": 1, "warm_runs": 5,
            "per_a_num": 26, "kernel_speed": True}


def _cli_cmd() -> list:
    """The ``hammerbit`` console script of this Python's environment (not another one on PATH)."""
    exe = os.path.join(os.path.dirname(sys.executable), "hammerbit")
    if os.path.isfile(exe) and os.access(exe, os.X_OK):
        return [exe]
    return [sys.executable, "-m", "hammerbit"]


def _timed_subprocess(cmd, env, timeout=600.0, cwd=REPO_ROOT) -> dict:
    """Run a command; its wall time and its CPU time (user + sys, less sensitive to a busy machine)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout, cwd=cwd)
    dt = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    out = {"wall_s": dt, "cpu_s": cpu, "returncode": p.returncode,
           "compile_notices": p.stderr.count(NOTICE)}
    if p.returncode != 0:
        out["stderr"] = p.stderr[-2000:]
    else:
        out["stdout"] = p.stdout[-4000:]
    return out


def measure_sweep(cfg: dict, workers: int) -> dict:
    """Best-of-``repeats`` periods/s of a bifurcation sweep on ``workers`` executor workers
    (1: in process; else local Dask worker processes, started before the clock)."""
    from hammerbit.studies.bifurcation import bifurcation
    from hammerbit.studies.executor import ExecutorOptions
    from hammerbit.model.presets import preset
    from hammerbit.model.solver_options import SolverOptions
    g = preset("paper-fig9")
    values = np.linspace(*A_RANGE, cfg["num"])
    solver = SolverOptions(rtol=RTOL, atol=ATOL)
    runs = []
    res = None
    for _ in range(cfg["repeats"]):
        t0 = time.perf_counter()
        res = bifurcation(g, "a", values, periods=cfg["periods"], keep=cfg["keep"], solver=solver,
                          options=ExecutorOptions(workers=workers))
        outer = time.perf_counter() - t0
        runs.append({"periods_per_second": res.periods_per_second, "sweep_wall_s": res.wall_time_s,
                     "call_wall_s": outer})
    best = max(runs, key=lambda r: r["periods_per_second"])
    n_per = [p for p in res.periods]
    return {"workers": workers, "values": cfg["num"], "periods_per_value": cfg["periods"],
            "total_periods": res.total_periods, "runs": runs,
            "periods_per_second": best["periods_per_second"], "wall_s": best["sweep_wall_s"],
            "period_n_histogram": {str(k): n_per.count(k) for k in sorted(set(n_per), key=lambda x: (x is None, x))}}


def measure_per_a(cfg: dict) -> dict:
    """Single-thread cost of one forcing period against a (min of 3 runs per value)."""
    from hammerbit.model.presets import preset
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.scene.simulate import simulate
    g = preset("paper-fig9")
    solver = SolverOptions(rtol=RTOL, atol=ATOL)
    simulate(g, 1, solver=solver)
    a_vals = np.linspace(*A_RANGE, cfg["per_a_num"])
    rows = []
    for a in a_vals:
        ga = g.replace(a=float(a))
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            r = simulate(ga, cfg["periods"], solver=solver)
            best = min(best, time.perf_counter() - t0)
        rows.append({"a": float(a), "time_s": best, "periods_per_second": cfg["periods"] / best,
                     "steps": r.stats["steps"], "rejected": r.stats["rejected"], "rhs": r.stats["rhs"],
                     "events": int(sum(r.counts.values()))})
    return {"periods": cfg["periods"], "rows": rows}


def measure_cli(cfg: dict) -> dict:
    """Cold (empty cache) and warm wall time of the CLI command in subprocesses."""
    cmd = _cli_cmd() + CLI_ARGS
    base_env = dict(os.environ)
    floor = [_timed_subprocess([sys.executable, "-c", "pass"], base_env)["wall_s"] for _ in range(3)]
    imp = [_timed_subprocess([sys.executable, "-c", "import hammerbit.scene.simulate"], base_env)["wall_s"]
           for _ in range(3)]
    # the two halves of the command, which run in two processes: the solver's imports and the figure's
    numba_imp = [_timed_subprocess([sys.executable, "-c", "import numba"], base_env)["wall_s"]
                 for _ in range(3)]
    mpl_imp = [_timed_subprocess([sys.executable, "-c", "import matplotlib.figure, "
                                  "matplotlib.backends.backend_agg"], base_env)["wall_s"] for _ in range(3)]
    cold, warm = [], []
    last_out = None
    for _ in range(cfg["cold_runs"]):
        cache = tempfile.mkdtemp(prefix="hammerbit-cold-")
        work = tempfile.mkdtemp(prefix="hammerbit-cli-")  # scene.png goes here
        env = dict(base_env, HAMMERBIT_CACHE_DIR=cache)
        try:
            r = _timed_subprocess(cmd, env, cwd=work)
            cold.append(r)
            for _ in range(cfg["warm_runs"]):
                w = _timed_subprocess(cmd, env, cwd=work)
                warm.append(w)
                last_out = w
            plot_ok = os.path.exists(os.path.join(work, "scene.png"))
        finally:
            shutil.rmtree(cache, ignore_errors=True)
            shutil.rmtree(work, ignore_errors=True)
    ok = all(r["returncode"] == 0 for r in cold + warm) and plot_ok
    parsed = last_out["stdout"].strip().splitlines() if last_out and last_out.get("returncode") == 0 else None
    cold_s = min(r["wall_s"] for r in cold)
    warm_s = min(r["wall_s"] for r in warm) if warm else None
    return {
        "command": " ".join(["hammerbit"] + CLI_ARGS),
        "argv": cmd,
        "ok": ok,
        "cold_s": cold_s,
        "warm_s": warm_s,
        "goal_cold_s": GOAL_COLD_S,
        "goal_warm_s": GOAL_WARM_S,
        "cold_met": cold_s <= GOAL_COLD_S,
        "warm_met": warm_s is not None and warm_s <= GOAL_WARM_S,
        # the compile notice: once in every cold run, never in a warm one
        "notice_ok": all(r["compile_notices"] == 1 for r in cold) and all(w["compile_notices"] == 0 for w in warm),
        "cold_cpu_s": min(r["cpu_s"] for r in cold),
        "warm_cpu_s": min(r["cpu_s"] for r in warm) if warm else None,
        "warm_median_s": float(np.median([r["wall_s"] for r in warm])) if warm else None,
        "python_floor_s": min(floor),
        "import_hammerbit_simulate_s": min(imp),
        "import_numba_s": min(numba_imp),
        "import_matplotlib_s": min(mpl_imp),
        "cold_runs": cold, "warm_runs": [{k: v for k, v in w.items() if k != "stdout"} for w in warm],
        "cli_output": parsed,
    }


def measure_kernel_speed() -> dict:
    """Speed of compiled code: a process that compiles itself vs one that loads the cache."""
    cache = tempfile.mkdtemp(prefix="hammerbit-speed-")
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=cache)
    cmd = [sys.executable, "-c", _KERNEL_SPEED_SCRIPT, "9"]
    try:
        rows = []
        for label in ("fresh_compile", "cache_load", "cache_load_2"):
            r = _timed_subprocess(cmd, env)
            if r["returncode"] != 0:
                return {"error": r.get("stderr")}
            d = json.loads(r["stdout"].strip().splitlines()[-1])
            d["label"] = label
            rows.append(d)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    fresh = rows[0]["best_100_periods_s"]
    cached = min(r["best_100_periods_s"] for r in rows[1:])
    return {"scene": "paper-fig9, a=0.11, 100 periods, rtol 1e-8 (Stepper.advance only)", "runs": rows,
            "fresh_s": fresh, "cached_s": cached, "cached_over_fresh": cached / fresh}


def _plot(result):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    has_a = bool(result.get("per_a"))
    fig, axes = plt.subplots(1, 3 if has_a else 2, figsize=(15 if has_a else 10, 4.5),
                             constrained_layout=True)
    ax = axes[0]
    labels, vals = [], []
    for s in result["sweeps"]:
        labels.append(f"workers={s['workers']}")
        vals.append(s["periods_per_second"])
    ax.bar(labels, vals, color=["C0", "C1"][: len(vals)])
    ax.axhline(GOAL_PPS, color="r", ls="--", label=f"goal {GOAL_PPS:,.0f}/s")
    for i, v in enumerate(vals):
        ax.text(i, v, f"{v:,.0f}", ha="center", va="bottom")
    ax.set_yscale("log")
    ax.set_ylim(min(vals + [GOAL_PPS]) / 3.0, max(vals + [GOAL_PPS]) * 2.0)
    ax.set_ylabel("forcing periods per second")
    ax.set_title(f"bifurcation sweep, paper-fig9, a in [0, 0.25]\n{result['config']['num']} values x "
                 f"{result['config']['periods']} periods, rtol {RTOL:g}", fontsize=10)
    ax.legend()
    ax = axes[1]
    c = result["cli"]
    names = ["python -c pass", "import\nhammerbit.simulate", "CLI warm", "CLI cold\n(compile)"]
    v = [c["python_floor_s"], c["import_hammerbit_simulate_s"], c["warm_s"] or np.nan, c["cold_s"]]
    ax.bar(names, v, color=["0.6", "0.6", "C2", "C3"])
    for i, x in enumerate(v):
        ax.text(i, x, f"{x:.2f} s", ha="center", va="bottom")
    ax.set_ylabel("wall time [s]")
    ax.set_title("`" + c["command"] + "`", fontsize=9)
    if has_a:
        ax = axes[2]
        rows = result["per_a"]["rows"]
        ax.semilogy([r["a"] for r in rows], [r["periods_per_second"] for r in rows], "o-")
        ax.axhline(GOAL_PPS, color="r", ls="--")
        ax.set_xlabel("a")
        ax.set_ylabel("periods per second (1 thread)")
        ax.set_title("cost against a (simulate, 1 thread)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Throughput and start-up" + (" (quick run)" if result["quick"] else ""))
    return fig


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Measure sweep throughput and CLI start-up; write ``results/throughput.{json,png}``."""
    log = stage_logger("throughput", verbose)

    cfg = _config(quick)
    machine = machine_info()
    t0 = time.perf_counter()
    log("sweep, 2 workers ...")
    sweeps = [measure_sweep(cfg, 2)]
    log("sweep, 1 worker ...")
    sweeps.append(measure_sweep(cfg, 1))
    per_a = None
    if cfg["per_a_num"]:
        log("cost against a ...")
        per_a = measure_per_a(cfg)
    log("CLI cold/warm ...")
    cli = measure_cli(cfg)
    kspeed = None
    if cfg["kernel_speed"]:
        log("compiled-code speed, fresh vs cache-loaded ...")
        kspeed = measure_kernel_speed()
    cmd = harness_command(NAME, quick)
    s2, s1 = sweeps
    summary = [
        summary_row(f"bifurcation sweep throughput, paper-fig9 a in [0, 0.25] ({cfg['num']} values x "
                    f"{cfg['periods']} periods, rtol {RTOL:g}), workers=2",
                    f"{s2['periods_per_second']:,.0f} periods/s", goal=f">= {GOAL_PPS:,.0f} periods/s",
                    met=s2["periods_per_second"] >= GOAL_PPS, command=cmd),
        summary_row("same sweep, single thread (workers=1)", f"{s1['periods_per_second']:,.0f} periods/s",
                    ratio=f"2-worker speed-up {fmt_ratio(s2['periods_per_second'] / s1['periods_per_second'])}",
                    goal=f">= {GOAL_PPS:,.0f} periods/s", met=s1["periods_per_second"] >= GOAL_PPS,
                    command=cmd),
        summary_row(f"CLI cold start (`{cli['command']}`, empty HAMMERBIT_CACHE_DIR: numba compiles), "
                    f"wall (CPU)", f"{cli['cold_s']:.2f} s ({cli['cold_cpu_s']:.2f} s)",
                    goal=f"<= {GOAL_COLD_S:g} s", met=cli["cold_met"], command=cmd),
        summary_row(f"CLI warm start (same command, cached kernels; `python -c pass` takes "
                    f"{cli['python_floor_s']:.2f} s, `import numba` {cli['import_numba_s']:.2f} s, "
                    f"importing matplotlib {cli['import_matplotlib_s']:.2f} s: the command does them in "
                    f"two processes), wall (CPU of both)",
                    f"{cli['warm_s']:.2f} s ({cli['warm_cpu_s']:.2f} s)" if cli["warm_s"] else "n/a",
                    peer=f"cold {cli['cold_s']:.2f} s",
                    ratio=fmt_ratio(cli["cold_s"] / cli["warm_s"]) if cli["warm_s"] else None,
                    goal=f"<= {GOAL_WARM_S:g} s", met=cli["warm_met"], command=cmd),
    ]
    if kspeed and "error" not in kspeed:
        summary.append(summary_row(
            "compiled-kernel speed, 100 periods paper-fig9 rtol 1e-8: cache-loaded vs freshly compiled",
            fmt_time(kspeed["cached_s"]), peer=f"fresh {fmt_time(kspeed['fresh_s'])}",
            ratio=f"{kspeed['cached_over_fresh']:.2f}x slower" if kspeed["cached_over_fresh"] > 1
            else f"{1 / kspeed['cached_over_fresh']:.2f}x faster",
            goal="1x (no penalty)", met=kspeed["cached_over_fresh"] <= 1.2, command=cmd))
    result = {
        "benchmark": NAME, "quick": quick, "command": cmd, "argv": sys.argv, "machine": machine,
        "config": cfg, "rtol": RTOL, "atol": ATOL, "goal_periods_per_second": GOAL_PPS,
        "kernels": kernel_source(),
        "sweeps": sweeps, "per_a": per_a, "cli": cli, "kernel_speed": kspeed,
        "summary": summary, "elapsed_s": time.perf_counter() - t0,
    }
    save_result(NAME, result, _plot(result))
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
