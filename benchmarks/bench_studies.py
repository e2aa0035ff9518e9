"""Studies on the executor: map throughput, parallel efficiency, Dask overhead, fast sweep.

1. **Map throughput per worker**: forcing periods integrated per second of
   wall time by ``regime_map`` over ``paper-fig9`` (a in [0.05, 0.25], eta in
   [0.6, 1.4], 31 x 31 cells x 300 periods, rtol 1e-8), in process
   (``workers=1``).  Goal >= 120,000.  Beside it, the same map's chunk split
   into the kernel calls (``advance_hammer``) and the per-cell Python around
   them.
2. **Parallel efficiency on 2 local workers**: the same map on a
   ``LocalCluster`` of 2 worker processes: ``t(in process) / (2 t(2 workers))``,
   best of the repeats of each, the repeats alternating so that both see the
   same machine load.  Only the cluster's start-up (start, connect, warm the
   workers) is left out, and reported on its own.  Goal >= 0.85.
3. **Dask overhead**: the same map on a 1-worker ``LocalCluster``
   (``ExecutorOptions(workers=1, dask=True)``) against the in-process run
   (ratio of wall times).
4. **31-frequency ``sweep --fmu``**: ``field-2200m``, 15-30 Hz, the hammer
   FMU, 2 local workers, the CLI's defaults (1.5 s, doubled up to 12 s until
   the WOB amplitude settles), from the call to the result (cluster start-up
   included).  Goal <= 20 s.  The peer is the former sweep (one
   co-simulation per frequency with a fresh string discretisation and a
   fixed 6 s horizon), timed on 2 frequencies and scaled to 31.
5. **The README's optimize example** (full run only): ``hammerbit optimize
   --preset lab --string lab --confirm ...``, its JSON kept under
   ``readme_optimize``.

Run ``python -m benchmarks --only studies [--quick]``.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks import (fmt_ratio, fmt_time, harness_command, kernel_source, machine_info, repo_on_path,
                        save_result, stage_logger, summary_row)

NAME = "studies"
GOAL_PPS = 120_000.0
GOAL_EFF = 0.85
GOAL_SWEEP_S = 20.0
RTOL = 1e-8


def _config(quick: bool) -> dict:
    if quick:
        return {"n_a": 11, "n_eta": 11, "periods": 100, "repeats": 2, "sweep_n": 5, "old_n": 1}
    return {"n_a": 31, "n_eta": 31, "periods": 300, "repeats": 5, "sweep_n": 31, "old_n": 2}


def _axes(cfg):
    from hammerbit.studies.map import Axis
    return [Axis.parse(f"a=0.05:0.25:{cfg['n_a']}"), Axis.parse(f"eta=0.6:1.4:{cfg['n_eta']}")]


def _one_map(cfg, executor):
    from hammerbit.model.presets import preset
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.studies.map import regime_map
    return regime_map(preset("paper-fig9"), _axes(cfg), periods=cfg["periods"],
                      solver=SolverOptions(rtol=RTOL, atol=RTOL * 1e-2), executor=executor)


def _summarise(runs) -> dict:
    """Best (least wall time) of the repeats of one map on one executor."""
    walls = [float(ds.attrs["wall_time_s"]) for ds in runs]
    cpus = [float(ds.attrs["cpu_time_s"]) for ds in runs]
    i = int(np.argmin(walls))
    ds = runs[i]
    tp = int(ds.attrs["total_periods"])
    per = ds["period"].values
    return {"wall_s": walls[i], "cpu_s": cpus[i], "wall_s_repeats": walls, "cpu_s_repeats": cpus,
            "total_periods": tp, "periods_per_second": tp / walls[i], "periods_per_cpu_second": tp / cpus[i],
            "workers": int(ds.attrs["workers"]), "failed_cells": int(ds.attrs["failed_cells"]),
            "period_n_histogram": {("none" if not np.isfinite(k) else str(int(k))): int(np.sum(
                (per == k) if np.isfinite(k) else ~np.isfinite(per))) for k in np.unique(per)},
            "_ds": ds}


def _kernel_share(cfg) -> dict:
    """Wall time of one in-process map chunk split into the kernel calls and the Python around them.

    Every ``advance_hammer`` call is timed (the timer's own cost lands in the
    kernel share); the rest is per-cell Python: scene set-up and validation,
    the Stepper, period detection, ROP and impact/peak-force extraction.
    """
    from hammerbit.model import kernel_driver
    from hammerbit.model.presets import preset
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.studies.map import _map_chunk
    g = preset("paper-fig9")
    solver = SolverOptions(rtol=RTOL, atol=RTOL * 1e-2)
    cells = [(float(a), float(e)) for a in _axes(cfg)[0].values for e in _axes(cfg)[1].values]
    real = kernel_driver.advance_hammer
    spent = [0.0]

    def timed(*args):
        t = time.perf_counter()
        try:
            return real(*args)
        finally:
            spent[0] += time.perf_counter() - t

    best = None
    try:
        kernel_driver.advance_hammer = timed
        for _ in range(cfg["repeats"]):
            spent[0] = 0.0
            t0 = time.perf_counter()
            _map_chunk(cells, g, ("a", "eta"), cfg["periods"], solver)
            total = time.perf_counter() - t0
            if best is None or total < best[0]:
                best = (total, spent[0])
    finally:
        kernel_driver.advance_hammer = real
    total, kern = best
    return {"cells": len(cells), "total_s": total, "kernel_s": kern, "python_s": total - kern,
            "python_us_per_cell": (total - kern) / len(cells) * 1e6, "python_share": (total - kern) / total,
            "kernel_periods_per_second": len(cells) * cfg["periods"] / kern}


def measure_maps(cfg, log) -> dict:
    """The map in process, on a 2-worker and on a 1-worker local cluster.

    The in-process and 2-worker repeats alternate (the machine is shared, so
    both see the same load); each cluster is started and its workers warmed
    before the clock starts, its start-up is reported on its own.
    """
    from hammerbit.studies.executor import Executor, ExecutorOptions
    out = {}
    log("map in process and on a local cluster of 2 workers, alternating ...")
    runs = {"in_process": [], "dask_2": []}
    load0 = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    with Executor(ExecutorOptions(workers=1)) as ip:
        _one_map({**cfg, "n_a": 2, "n_eta": 2, "periods": 10}, ip)          # load the kernels here
        t0 = time.perf_counter()
        with Executor(ExecutorOptions(workers=2)) as d2:
            d2.connect()
            startup2 = time.perf_counter() - t0
            for _ in range(cfg["repeats"]):
                runs["in_process"].append(_one_map(cfg, ip))
                runs["dask_2"].append(_one_map(cfg, d2))
    out["load_average_1min"] = [load0, os.getloadavg()[0] if load0 is not None else None]
    log("map on a local cluster of 1 worker ...")
    t0 = time.perf_counter()
    with Executor(ExecutorOptions(workers=1, dask=True)) as d1:
        d1.connect()
        startup1 = time.perf_counter() - t0
        runs["dask_1"] = [_one_map(cfg, d1) for _ in range(cfg["repeats"])]
    for k, v in runs.items():
        out[k] = _summarise(v)
    out["dask_2"]["cluster_startup_s"] = startup2
    out["dask_1"]["cluster_startup_s"] = startup1
    ref = out["in_process"]["_ds"]
    out["identical"] = all(np.array_equal(ds[v].values, ref[v].values, equal_nan=True)
                           for k in runs for ds in runs[k] for v in ref.data_vars)
    for k in runs:
        out[k].pop("_ds")
    out["parallel_efficiency_2"] = out["in_process"]["wall_s"] / (2.0 * out["dask_2"]["wall_s"])
    out["dask_overhead_1"] = out["dask_1"]["wall_s"] / out["in_process"]["wall_s"]
    log("map chunk split into kernel and Python ...")
    out["kernel_share"] = _kernel_share(cfg)
    return out


def measure_sweep(cfg, log) -> dict:
    repo_on_path()
    from build_fmu import build_fmu
    from hammerbit.cosim.config import CosimConfig
    from hammerbit.cosim.master import cosimulate
    from hammerbit.drillstring import load_string
    from hammerbit.studies.executor import ExecutorOptions
    from hammerbit.studies.sweep import sweep
    string = load_string("field-2200m")
    freqs = np.linspace(15.0, 30.0, cfg["sweep_n"])
    with tempfile.TemporaryDirectory(prefix="hammerbit-bench-studies-") as tmp:
        fmu = str(build_fmu(Path(tmp)))
        log("FMU first load (fills the kernel cache if empty) ...")
        c0 = CosimConfig(stop=0.01, progress=False)
        t0 = time.perf_counter()
        cosimulate(string, c0, fmu=fmu)
        first_load = time.perf_counter() - t0
        log(f"sweep --fmu, {len(freqs)} frequencies, 2 workers ...")
        cfg_s = CosimConfig(stop=1.5, progress=False)
        t0 = time.perf_counter()
        res = sweep(string, freqs, cfg_s, fmu=fmu, max_duration=12.0, options=ExecutorOptions(workers=2))
        wall = time.perf_counter() - t0
        log(f"former sweep (fresh discretisation, 6 s per frequency), {cfg['old_n']} frequencies ...")
        old = []
        for f in freqs[: cfg["old_n"]]:
            c = CosimConfig(stop=6.0, progress=False, record=("wob", "bit_position"))
            t1 = time.perf_counter()
            cosimulate(string, c.replace(rig=c.rig.replace(frequency=float(f))), fmu=fmu)
            old.append(time.perf_counter() - t1)
    old_per = float(np.mean(old))
    return {"frequencies": len(freqs), "range_hz": [float(freqs[0]), float(freqs[-1])], "wall_s": wall,
            "workers": 2, "initial_duration_s": 1.5, "durations_s": res["duration_s"].tolist(),
            "steady": int(res["steady"].sum()), "fmu_first_load_s": first_load,
            "former_per_frequency_s": old_per, "former_frequencies_timed": len(old),
            "former_31_estimate_s": old_per * 31.0,
            "peak_frequency_hz": float(res["frequency_hz"][int(np.argmax(res["wob_amplitude_n"]))])}


#: The README's optimize example (lab rig on the lab string).
README_OPTIMIZE = ["optimize", "--preset", "lab", "--string", "lab", "--confirm", "--interface-stiffness", "700",
                   "--interface-damping", "10", "--workers", "2", "--json"]


def measure_readme_optimize(log) -> dict:
    """Run the README's ``hammerbit optimize`` example and keep its JSON."""
    import contextlib
    import io
    import json
    from hammerbit.cli.main import main
    log("README optimize example ...")
    buf = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(buf):
        rc = main(README_OPTIMIZE)
    out = {"command": "hammerbit " + " ".join(README_OPTIMIZE), "returncode": rc,
           "wall_s": time.perf_counter() - t0}
    if rc == 0:
        out["result"] = json.loads(buf.getvalue())
    return out


def _plot(result):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    m, s = result["maps"], result["sweep"]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5), constrained_layout=True)
    labels = ["in process", "Dask, 1 worker", "Dask, 2 workers\n(per worker)"]
    vals = [m["in_process"]["periods_per_second"], m["dask_1"]["periods_per_second"],
            m["dask_2"]["periods_per_second"] / 2.0]
    ax[0].bar(labels, vals, color=["C0", "C1", "C2"])
    ax[0].axhline(GOAL_PPS, color="r", ls="--", label=f"goal {GOAL_PPS:,.0f}/s per worker")
    for i, v in enumerate(vals):
        ax[0].text(i, v, f"{v:,.0f}", ha="center", va="bottom")
    ax[0].set_ylabel("forcing periods per second per worker")
    c = result["config"]
    ax[0].set_title(f"map paper-fig9 (a, eta) {c['n_a']}x{c['n_eta']} x {c['periods']} periods, "
                    f"rtol {RTOL:g}", fontsize=9)
    ax[0].legend(fontsize=8)
    ax[1].bar(["parallel efficiency\n2 workers", "Dask overhead\n1 worker / in process"],
              [m["parallel_efficiency_2"], m["dask_overhead_1"]], color=["C2", "C1"])
    ax[1].axhline(GOAL_EFF, color="r", ls="--", label=f"efficiency goal {GOAL_EFF}")
    ax[1].axhline(1.0, color="0.5", lw=0.8)
    ax[1].legend(fontsize=8)
    ax[1].set_title(f"local cluster start-up {m['dask_2']['cluster_startup_s']:.1f} s (2 workers)", fontsize=9)
    ax[2].bar(["sweep --fmu\n(2 workers)", "former sweep\n(estimate)"],
              [s["wall_s"], s["former_31_estimate_s"] * s["frequencies"] / 31.0], color=["C0", "0.6"])
    ax[2].axhline(GOAL_SWEEP_S * s["frequencies"] / 31.0, color="r", ls="--", label="goal (scaled)")
    ax[2].set_ylabel("wall time [s]")
    ax[2].set_title(f"field-2200m, {s['frequencies']} frequencies "
                    f"{s['range_hz'][0]:g}-{s['range_hz'][1]:g} Hz, hammer FMU", fontsize=9)
    ax[2].legend(fontsize=8)
    fig.suptitle("Studies on the executor" + (" (quick run)" if result["quick"] else ""))
    return fig


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Measure the studies' throughput; write ``results/studies.{json,png}``."""
    log = stage_logger(NAME, verbose)
    cfg = _config(quick)
    t0 = time.perf_counter()
    machine = machine_info()
    maps = measure_maps(cfg, log)
    sw = measure_sweep(cfg, log)
    readme = None if quick else measure_readme_optimize(log)
    cmd = harness_command(NAME, quick)
    summary = _summary(cfg, maps, sw, cmd)
    result = {"benchmark": NAME, "quick": quick, "command": cmd, "argv": sys.argv, "machine": machine,
              "config": cfg, "rtol": RTOL, "kernels": kernel_source(), "maps": maps, "sweep": sw,
              "identical_results": maps["identical"], "readme_optimize": readme, "summary": summary,
              "elapsed_s": time.perf_counter() - t0}
    save_result(NAME, result, _plot(result))
    return result


def _fmt_load(pair) -> str:
    if not pair or pair[0] is None:
        return "n/a"
    return f"{pair[0]:.1f} before, {pair[1]:.1f} after"


def _summary(cfg, maps, sw, cmd) -> list:
    """The README rows of a run."""
    ip, d2 = maps["in_process"], maps["dask_2"]
    scene = (f"paper-fig9 map a 0.05-0.25 x eta 0.6-1.4 ({cfg['n_a']}x{cfg['n_eta']} cells x "
             f"{cfg['periods']} periods, rtol {RTOL:g})")
    ks = maps["kernel_share"]
    d1 = maps["dask_1"]
    summary = [
        summary_row(f"map throughput per worker, {scene}, in process (wall time; per CPU second of "
                    f"the worker as peer: the machine is shared)",
                    f"{ip['periods_per_second']:,.0f} periods/s",
                    peer=f"{ip['periods_per_cpu_second']:,.0f} periods per CPU second; kernel calls alone "
                         f"{ks['kernel_periods_per_second']:,.0f} periods/s, per-cell Python "
                         f"{100 * ks['python_share']:.1f} % ({ks['python_us_per_cell']:.0f} us per cell)",
                    goal=f">= {GOAL_PPS:,.0f} periods/s",
                    met=ip["periods_per_second"] >= GOAL_PPS, command=cmd),
        summary_row(f"map parallel efficiency, 2 local Dask workers vs in process ({cfg['n_a']}x{cfg['n_eta']} "
                    f"cells x {cfg['periods']} periods; wall time, best of {cfg['repeats']} alternating "
                    f"repeats, cluster start-up excluded; it needs 2 idle cores: see the CPU seconds)",
                    f"{maps['parallel_efficiency_2']:.2f}",
                    peer=f"in process {fmt_time(ip['wall_s'])} ({ip['cpu_s']:.2f} CPU s), 2 workers "
                         f"{fmt_time(d2['wall_s'])} ({d2['cpu_s']:.2f} CPU s over both); 1-min load average "
                         f"{_fmt_load(maps.get('load_average_1min'))}",
                    ratio=f"CPU in process / CPU on 2 workers {ip['cpu_s'] / d2['cpu_s']:.2f}",
                    goal=f">= {GOAL_EFF}", met=maps["parallel_efficiency_2"] >= GOAL_EFF, command=cmd),
        summary_row("Dask overhead: same map on a 1-worker local cluster vs in process (wall-time ratio; "
                    "cluster start-up excluded)", fmt_ratio(maps["dask_overhead_1"]),
                    peer=f"1 worker {fmt_time(d1['wall_s'])}, in process {fmt_time(ip['wall_s'])}; start-up "
                         f"of a local cluster {d2['cluster_startup_s']:.1f} s (2 workers), "
                         f"{d1['cluster_startup_s']:.1f} s (1 worker)", command=cmd),
        summary_row(f"sweep --fmu, field-2200m, {sw['frequencies']} frequencies 15-30 Hz, 2 workers "
                    f"(cluster start-up included)", fmt_time(sw["wall_s"]),
                    peer=f"former sweep ~{fmt_time(sw['former_31_estimate_s'] * sw['frequencies'] / 31.0)} "
                         f"(scaled from {sw['former_frequencies_timed']} frequencies)",
                    ratio=fmt_ratio(sw["former_31_estimate_s"] * sw["frequencies"] / 31.0 / sw["wall_s"]),
                    goal=f"<= {GOAL_SWEEP_S * sw['frequencies'] / 31.0:g} s" if sw["frequencies"] != 31
                    else f"<= {GOAL_SWEEP_S:g} s",
                    met=sw["wall_s"] <= GOAL_SWEEP_S * sw["frequencies"] / 31.0, command=cmd),
    ]
    return summary


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
