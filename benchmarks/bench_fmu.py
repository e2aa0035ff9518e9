"""FMU benchmark (issue 3): HammerBitRock.fmu against the FMI floor and against the library.

Measures, in one run:

1. **Per-step overhead on steps with no event.**  fmpy ``FMU2Slave`` driving
   the FMU with one ``setReal`` (preload), one ``doStep`` (h = 1 ms) and one
   ``getReal`` (bit position) per step, against a trivial pythonfmu FMU (one
   input, one output, ``do_step`` returns at once) driven the same way, built
   in a temporary directory: the floor of any pythonfmu FMU.  The scene has no
   event: the lab rig with no harmonic force and the hammer starting in
   equilibrium under the preload, so the bit stays stuck (checked).  Goal:
   at most 1.5x the floor.  Both loops run interleaved, minimum over repeats.
   The in-process split of our step (the slave's ``do_step`` and the
   ``Stepper.advance`` call inside it) is recorded too.
2. **Cold and warm load.**  A fresh process loads the FMU (extract, load the
   binary, instantiate, set up, initialise - the kernels are compiled or
   loaded from the numba cache at initialisation) with an empty
   ``HAMMERBIT_CACHE_DIR`` (cold: compiles), then again with the same cache
   and a new extraction directory (warm).  Goal: warm at most 0.5 s.  The
   first ``doStep`` and the kernel cache hits/misses are recorded.
3. **Time per forcing period** of the lab scene (drilling, events every
   period): the FMU at h = 1 ms through fmpy against the library's
   ``Stepper`` over the same periods in one call, and the library stepped on
   the same 1 ms grid (what the FMU's kernel calls cost without FMI).

Run: ``python -m benchmarks --only fmu`` (``--quick`` for a short run), or
``python benchmarks/bench_fmu.py [--quick]``.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

if __name__ == "__main__":  # run as a script: the package lives in the repository root
    _root = str(Path(__file__).resolve().parents[1])
    if _root not in sys.path:
        sys.path.insert(0, _root)

from benchmarks import (LoadedFMU, build_trivial_fmu, fmt_ratio, fmt_time, harness_command,  # noqa: E402
                        machine_info, repo_on_path, save_result, stage_logger, summary_row)

NAME = "fmu"
STEP = 1e-3                  # communication step [s] (the FMU's DefaultExperiment stepSize)
GOAL_RATIO = 1.5
GOAL_WARM_S = 0.5

# a fresh process: extract + load + instantiate + initialise, then the first doStep
_LOAD_PROBE = textwrap.dedent('''
    import json, sys, time
    t_start = time.perf_counter()
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    t0 = time.perf_counter()
    path = sys.argv[1]
    md = read_model_description(path)
    d = extract(path)
    t1 = time.perf_counter()
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="probe")
    fmu.instantiate()
    t2 = time.perf_counter()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    t3 = time.perf_counter()
    fmu.doStep(0.0, 1e-3)
    t4 = time.perf_counter()
    K = sys.modules["hammerbit_fmu_runtime.kernels"]
    ds = (K.advance_hammer, K.force_on_bit, K.kinetic_friction, K.contact_force)
    out = {"import_fmpy_s": t0 - t_start, "extract_s": t1 - t0, "instantiate_s": t2 - t1,
           "initialise_s": t3 - t2, "load_s": t3 - t0, "first_step_s": t4 - t3,
           "numba_cache_hits": sum(sum(x.stats.cache_hits.values()) for x in ds),
           "numba_cache_misses": sum(sum(x.stats.cache_misses.values()) for x in ds)}
    fmu.terminate()
    fmu.freeInstance()
    print(json.dumps(out), flush=True)
''')


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def _no_event_scene():
    """Parameters of the no-event scene: no harmonic force, hammer in equilibrium under the preload."""
    from hammerbit.model.params import RigParameters
    rig = RigParameters()
    return {"amplitude": 0.0, "initial_hammer_position": rig.preload / rig.stiffness}, rig.preload


# ---------------------------------------------------------------------------
# 1. per-step overhead
# ---------------------------------------------------------------------------
def measure_step_overhead(fmu_path, trivial_path, quick: bool, log) -> dict:
    n = 3000 if quick else 20000
    reps = 5 if quick else 9
    reals, preload = _no_event_scene()
    ours = LoadedFMU(fmu_path, "ours", reals)
    floor = LoadedFMU(trivial_path, "floor")
    v_bit = [ours.vr["bit_position"]]
    try:
        ours.loop(500, ours.vr["preload"], preload, v_bit, STEP)          # warm up both
        floor.loop(500, floor.vr["u"], 1.0, [floor.vr["y0"]], STEP)
        t_ours, t_floor = [], []
        for _ in range(reps):
            t_floor.append(floor.loop(n, floor.vr["u"], 1.0, [floor.vr["y0"]], STEP))
            t_ours.append(ours.loop(n, ours.vr["preload"], preload, v_bit, STEP))
        ints = ours.fmu.getInteger([ours.vr[k] for k in ("slip_count", "impact_count", "bounce_count")])
        events = int(sum(ints))
        bit = ours.fmu.getReal(v_bit)[0]
    finally:
        ours.close()
        floor.close()
    split = _in_process_split(n, reals, preload)
    res = {"steps_per_repeat": n, "repeats": reps, "step_s": STEP,
           "ours_s": min(t_ours), "floor_s": min(t_floor), "ratio": min(t_ours) / min(t_floor),
           "ours_all_s": t_ours, "floor_all_s": t_floor, "events_in_scene": events,
           "bit_position_end_m": bit, **split}
    log(f"per step: ours {res['ours_s'] * 1e6:.2f} us, floor {res['floor_s'] * 1e6:.2f} us, "
        f"ratio {res['ratio']:.2f} (goal <= {GOAL_RATIO}); events {events}")
    return res


def _in_process_split(n, reals, preload) -> dict:
    """The slave's do_step and the Stepper.advance inside it, without FMI (in this process)."""
    from hammerbit.model.slave import HammerBitRock
    s = HammerBitRock(instance_name="split")
    s.setup_experiment(0.0)
    for k, v in reals.items():
        setattr(s, k, v)
    s.preload = preload
    s.exit_initialization_mode()
    best_do = best_adv = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(n):
            s.do_step(s._t, STEP)
        best_do = min(best_do, (time.perf_counter() - t0) / n)
    st, om, t0s = s._st, s._omega, s._t
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(1, n + 1):
            st.advance((t0s + k * STEP) * om)
        best_adv = min(best_adv, (time.perf_counter() - t0) / n)
        t0s += n * STEP
    return {"slave_do_step_s": best_do, "stepper_advance_s": best_adv,
            "slave_python_s": best_do - best_adv}


# ---------------------------------------------------------------------------
# 2. cold and warm load
# ---------------------------------------------------------------------------
def _probe(fmu_path, cache_dir) -> dict:
    env = dict(os.environ, HAMMERBIT_CACHE_DIR=str(cache_dir))
    r = subprocess.run([sys.executable, "-c", _LOAD_PROBE, str(fmu_path)], capture_output=True,
                       text=True, timeout=900, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"load probe failed ({r.returncode}): {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def measure_load(fmu_path, quick: bool, log) -> dict:
    cache = Path(tempfile.mkdtemp(prefix="hammerbit_bench_cache_"))
    try:
        cold = _probe(fmu_path, cache)
        log(f"cold load (compiles): {cold['load_s']:.2f} s, misses {cold['numba_cache_misses']}")
        warm = [_probe(fmu_path, cache) for _ in range(3 if quick else 5)]
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    best = min(warm, key=lambda w: w["load_s"])
    log(f"warm load: {best['load_s']:.3f} s (goal <= {GOAL_WARM_S} s), first step "
        f"{best['first_step_s'] * 1e3:.2f} ms, cache hits {best['numba_cache_hits']}, "
        f"misses {best['numba_cache_misses']}")
    return {"cold": cold, "warm_best": best, "warm_all_load_s": [w["load_s"] for w in warm],
            "cold_load_s": cold["load_s"], "warm_load_s": best["load_s"],
            "warm_cache_misses": best["numba_cache_misses"]}


# ---------------------------------------------------------------------------
# 3. time per forcing period
# ---------------------------------------------------------------------------
def measure_per_period(fmu_path, quick: bool, log) -> dict:
    from hammerbit.model.params import RigParameters
    from hammerbit.model.stepping import SolverOptions, Stepper
    rig = RigParameters()
    periods = 3 if quick else 20
    T = 1.0 / rig.frequency
    n_steps = int(round(periods * T / STEP))
    stop = n_steps * STEP
    reps = 3 if quick else 5
    solver = SolverOptions(rtol=1e-8, atol=1e-10)
    om = rig.scales.omega

    fmu_t, x_fmu = math.inf, None
    for _ in range(reps):
        inst = LoadedFMU(fmu_path, "period")
        try:
            dt = inst.loop(n_steps, inst.vr["preload"], rig.preload, [inst.vr["bit_position"]], STEP) * n_steps
            x_fmu = inst.fmu.getReal([inst.vr["bit_position"]])[0]
        finally:
            inst.close()
        fmu_t = min(fmu_t, dt)
    lib_t = grid_t = math.inf
    for _ in range(reps):
        st = Stepper(rig.to_groups(), solver=solver)
        t0 = time.perf_counter()
        st.advance(stop * om)
        lib_t = min(lib_t, time.perf_counter() - t0)
        x_lib = st.y[2] * rig.scales.length
        st = Stepper(rig.to_groups(), solver=solver)
        t0 = time.perf_counter()
        for k in range(1, n_steps + 1):
            st.advance(k * STEP * om)
        grid_t = min(grid_t, time.perf_counter() - t0)
    nT = stop / T
    res = {"periods": nT, "comm_step_s": STEP, "steps": n_steps,
           "fmu_per_period_s": fmu_t / nT, "library_per_period_s": lib_t / nT,
           "library_1ms_grid_per_period_s": grid_t / nT,
           "ratio_fmu_to_library": fmu_t / lib_t,
           "bit_position_fmu_m": x_fmu, "bit_position_library_m": x_lib,
           "penetration_rel_diff": abs(x_fmu - x_lib) / abs(x_lib)}
    log(f"per forcing period: FMU {res['fmu_per_period_s'] * 1e3:.2f} ms, library "
        f"{res['library_per_period_s'] * 1e6:.1f} us (1 ms grid {res['library_1ms_grid_per_period_s'] * 1e3:.2f} ms); "
        f"penetration agrees to {res['penetration_rel_diff']:.1e}")
    return res


# ---------------------------------------------------------------------------
def _figure(res):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    s, ld, pp = res["step_overhead"], res["load"], res["per_period"]
    fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
    names = ["trivial FMU\n(floor)", "HammerBitRock\n(no event)", "  of which\nslave do_step",
             "  of which\nStepper.advance"]
    vals = [s["floor_s"], s["ours_s"], s["slave_do_step_s"], s["stepper_advance_s"]]
    ax[0].bar(names, [v * 1e6 for v in vals], color=["0.6", "C0", "C1", "C2"])
    ax[0].axhline(GOAL_RATIO * s["floor_s"] * 1e6, color="k", ls="--", lw=1, label=f"goal {GOAL_RATIO}x floor")
    ax[0].set_ylabel("µs per step (setReal + doStep + getReal)")
    ax[0].set_title(f"per-step cost, h = {STEP * 1e3:g} ms: {s['ratio']:.2f}x floor")
    ax[0].legend(fontsize=8)
    ax[0].tick_params(axis="x", labelsize=8)
    w = ld["warm_best"]
    parts = [("extract", w["extract_s"]), ("instantiate\n(imports)", w["instantiate_s"]),
             ("initialise\n(kernels)", w["initialise_s"])]
    bottom = 0.0
    for i, (lab, v) in enumerate(parts):
        ax[1].bar(["warm"], [v], bottom=bottom, label=lab, color=f"C{i}")
        bottom += v
    ax[1].bar(["cold"], [ld["cold_load_s"]], color="C3", label="cold (compile)")
    ax[1].axhline(GOAL_WARM_S, color="k", ls="--", lw=1, label=f"goal {GOAL_WARM_S} s (warm)")
    ax[1].set_yscale("log")
    ax[1].set_ylabel("s (new process, new extraction dir)")
    ax[1].set_title(f"load: warm {ld['warm_load_s']:.2f} s, cold {ld['cold_load_s']:.1f} s")
    ax[1].legend(fontsize=7)
    labels = ["library\n(one call)", "library\n(1 ms grid)", "FMU via fmpy\n(1 ms steps)"]
    vals = [pp["library_per_period_s"], pp["library_1ms_grid_per_period_s"], pp["fmu_per_period_s"]]
    ax[2].bar(labels, [v * 1e3 for v in vals], color=["C2", "C1", "C0"])
    ax[2].set_yscale("log")
    ax[2].set_ylabel("ms per forcing period (lab scene)")
    ax[2].set_title(f"FMU / library = {pp['ratio_fmu_to_library']:.0f}x")
    fig.suptitle("HammerBitRock.fmu (pythonfmu, fmpy FMU2Slave)")
    fig.tight_layout()
    return fig


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Run the FMU benchmark; write ``benchmarks/results/fmu.json`` and ``fmu.png``."""
    log = stage_logger(NAME, verbose)

    repo_on_path()
    from build_fmu import build_fmu
    work = Path(tempfile.mkdtemp(prefix="hammerbit_bench_fmu_"))
    try:
        t0 = time.perf_counter()
        fmu_path = build_fmu(work / "ours")
        trivial = build_trivial_fmu(work / "floor")
        log(f"built {fmu_path.name} and {trivial.name} in {time.perf_counter() - t0:.1f} s")
        load = measure_load(fmu_path, quick, log)          # first: a clean process state
        step = measure_step_overhead(fmu_path, trivial, quick, log)
        period = measure_per_period(fmu_path, quick, log)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    cmd = harness_command(NAME, quick)
    res = {
        "benchmark": NAME, "quick": quick, "command": cmd, "machine": machine_info(),
        "step_overhead": step, "load": load, "per_period": period,
        "summary": [
            summary_row("FMU step with no event, fmpy setReal+doStep+getReal (h = 1 ms), "
                        "vs trivial pythonfmu FMU", fmt_time(step["ours_s"]), peer=fmt_time(step["floor_s"]),
                        ratio=fmt_ratio(step["ratio"]), goal=f"<= {GOAL_RATIO}x",
                        met=step["ratio"] <= GOAL_RATIO, command=cmd),
            summary_row("FMU warm load + instantiate + initialise (new process, new extraction dir)",
                        fmt_time(load["warm_load_s"]), goal=f"<= {GOAL_WARM_S} s",
                        met=load["warm_load_s"] <= GOAL_WARM_S and load["warm_cache_misses"] == 0,
                        command=cmd),
            summary_row("FMU cold load (empty numba cache: compiles the kernels)",
                        fmt_time(load["cold_load_s"]), command=cmd),
            summary_row("FMU time per forcing period (lab scene, h = 1 ms) vs library Stepper",
                        fmt_time(period["fmu_per_period_s"]), peer=fmt_time(period["library_per_period_s"]),
                        ratio=fmt_ratio(period["ratio_fmu_to_library"]), command=cmd),
        ],
    }
    save_result(NAME, res, fig=_figure(res))
    return res


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
