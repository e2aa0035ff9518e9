"""Speed of the hammer-frequency check and of its eigen-solver.

``python -m benchmarks --only check`` measures

* ``check`` up to 200 Hz on a 3300 m string (2900 m pipe, 200 m heavy-weight,
  200 m collars, 2 % damping), library call after a warm-up, and the same
  through the CLI in a fresh process (``hammerbit check ... --json``); goal
  < 5 s;
* the modes in range on the same mesh: the Sturm-bisection solver against the
  dense ``scipy.linalg.eigh(K, M, subset_by_value=...)`` a user would reach for
  (at a reduced frequency so the dense solve stays short).

Wall and CPU times are both reported: on a shared machine the wall time
follows the load (recorded with the result); the goal is judged on CPU time.
Writes ``results/check.json`` and ``results/check.png``.
"""
from __future__ import annotations

import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks import fmt_ratio, fmt_time, harness_command, machine_info, save_result, summary_row

NAME = "check"
GOAL_S = 5.0

TOML = """
name = "field-3300m"
modal_damping_ratio = 0.02
[boundaries]
top = "fixed"
bottom = "free"
on_bottom = { kind = "spring", stiffness = 5.0e8 }
off_bottom = "free"
[[section]]
name = "drill pipe"
length = 2900.0
od = 0.127
id = 0.1086
[[section]]
name = "heavy-weight"
length = 200.0
od = 0.127
id = 0.0762
[[section]]
name = "drill collars"
length = 200.0
od = 0.1651
id = 0.0714375
"""


def _string():
    from hammerbit.drillstring import loads_string
    return loads_string(TOML, source="field-3300m.toml")


def measure_check(f_hi: float, repeats: int) -> dict:
    from hammerbit.check.frequency import CheckConfig, check
    s = _string()
    cfg = CheckConfig(excitation_hz=f_hi / 2, frequency_range_hz=(0.0, f_hi))
    t0 = time.perf_counter()
    r = check(s, cfg)
    first = time.perf_counter() - t0
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        r = check(s, cfg)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {"f_hi_hz": f_hi, "first_s": first, "best_s": min(times), "best_cpu_s": min(cpu),
            "elements": r.n_elements,
            "modes": int(sum(c.frequencies_hz.size for c in r.configurations)),
            "max_error_estimate": max(c.max_error_estimate or 0.0 for c in r.configurations),
            "verdict": r.verdict_label, "windows": len(r.windows)}


def measure_cli(f_hi: float) -> dict:
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "field-3300m.toml"
        path.write_text(TOML)
        cmd = [sys.executable, "-c", "import sys; from hammerbit.cli.main import main; sys.exit(main())", "check",
               "--string", str(path), "--frequency", f"{f_hi / 2:g}",
               "--range", "0", f"{f_hi:g}", "--json"]
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    # the string is the benchmark's own (TOML above, written to a scratch file), not a file of the repository
    return {"command": "hammerbit check --string STRING.toml --frequency "
                       f"{f_hi / 2:g} --range 0 {f_hi:g} --json", "wall_s": wall, "cpu_s": cpu,
            "returncode": proc.returncode}


def measure_eigen(f_max: float) -> dict:
    import scipy.linalg as sla
    from hammerbit.drillstring import assemble
    from hammerbit.drillstring.eigen import pencil_eigenpairs
    s = _string().for_accuracy(f_max, 5e-6)
    asm = assemble(s, "fixed", "free")
    kd, ke = asm.tridiagonal("K")
    md, me = asm.tridiagonal("M")
    hi = (2 * math.pi * f_max) ** 2
    pencil_eigenpairs(kd, ke, md, me, upper=hi)     # compile / load
    t0 = time.perf_counter()
    lam, _ = pencil_eigenpairs(kd, ke, md, me, upper=hi)
    ours = time.perf_counter() - t0
    K, M = asm.K, asm.M
    t0 = time.perf_counter()
    ref = sla.eigh(K, M, subset_by_value=(-1.0, hi), eigvals_only=False)[0]
    peer = time.perf_counter() - t0
    return {"f_max_hz": f_max, "dof": int(kd.size), "modes": int(lam.size), "ours_s": ours, "dense_eigh_s": peer,
            "max_rel_diff": float(np.max(np.abs(lam / ref - 1))) if lam.size == ref.size else None}


def _plot(result):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    c, cli, e = result["check"], result["cli"], result["eigen"]
    axes[0].bar(["library (warm)", "CLI (new process)"], [c["best_s"], cli["wall_s"]], color=["tab:blue", "tab:gray"])
    axes[0].axhline(GOAL_S, color="r", ls="--", label=f"goal {GOAL_S:g} s")
    axes[0].set_ylabel("wall time [s]")
    axes[0].set_title(f"check 0-{c['f_hi_hz']:g} Hz, 3300 m, {c['elements']} elements", fontsize=10)
    axes[0].legend()
    axes[1].bar(["Sturm bisection", "dense eigh"], [e["ours_s"], e["dense_eigh_s"]], color=["tab:blue", "tab:gray"])
    axes[1].set_yscale("log")
    axes[1].set_ylabel("wall time [s]")
    axes[1].set_title(f"{e['modes']} modes <= {e['f_max_hz']:g} Hz of {e['dof']} DOF", fontsize=10)
    fig.suptitle("Hammer-frequency check" + (" (quick run)" if result["quick"] else ""))
    fig.tight_layout()
    return fig


def run(quick: bool = False) -> dict:
    cmd = harness_command(NAME, quick)
    t0 = time.perf_counter()
    f_hi = 50.0 if quick else 200.0
    chk = measure_check(f_hi, 1 if quick else 3)
    cli = measure_cli(f_hi)
    eig = measure_eigen(20.0 if quick else 40.0)
    summary = [
        summary_row(f"check 0-{f_hi:g} Hz on a 3300 m string ({chk['elements']} elements, {chk['modes']} modes, "
                    f"both bit configurations, 3 damping levels), library call, wall (CPU)",
                    f"{fmt_time(chk['best_s'])} ({fmt_time(chk['best_cpu_s'])})",
                    goal=f"< {GOAL_S:g} s", met=chk["best_cpu_s"] < GOAL_S, command=cmd),
        summary_row(f"same through the CLI in a new process (`{cli['command']}`, STRING.toml: that 3300 m "
                    f"string, written by the benchmark), wall (CPU)",
                    f"{fmt_time(cli['wall_s'])} ({fmt_time(cli['cpu_s'])})",
                    goal=f"< {GOAL_S:g} s", met=cli["cpu_s"] < GOAL_S and cli["returncode"] == 0, command=cmd),
        summary_row(f"modes <= {eig['f_max_hz']:g} Hz of the same string ({eig['dof']} DOF, {eig['modes']} modes); "
                    "peer = dense scipy eigh(K, M, subset_by_value)", fmt_time(eig["ours_s"]),
                    peer=fmt_time(eig["dense_eigh_s"]), ratio=fmt_ratio(eig["dense_eigh_s"] / eig["ours_s"]),
                    command=cmd),
    ]
    result = {"benchmark": NAME, "quick": quick, "command": cmd, "argv": sys.argv, "machine": machine_info(),
              "check": chk, "cli": cli, "eigen": eig, "summary": summary, "elapsed_s": time.perf_counter() - t0}
    save_result(NAME, result, _plot(result))
    return result


if __name__ == "__main__":
    run("--quick" in sys.argv)
