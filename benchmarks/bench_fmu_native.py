"""Native-flavour FMU benchmark: HammerBitRock.fmu built with ``--runtime native``.

Measures, in one run:

1. **First start.**  A new process with the extracted FMU and ``HOME`` read-only
   (as tools that unpack FMUs read-only do): load the binary, instantiate, set
   up, initialise; timed inside the process from before ``dlopen`` to after
   ``fmi2ExitInitializationMode`` (the host's own start-up, e.g. importing
   fmpy, is not the FMU's).  Goal: at most 20 ms.  Also the whole run of the
   C test host (``env -i``, no Python anywhere) for 1 s of model time, process
   start to exit.
2. **Warm step** with no event: one ``fmi2SetReal`` of one input (preload), one
   ``fmi2DoStep`` (h = 1 ms) and one ``fmi2GetReal`` of one output (bit position),
   against the trivial pythonfmu FMU (one input, one output, ``do_step`` returns
   at once), built in the same run.  The headline is timed from a C host
   (``fmu_step_host.c``, built here with the system's C compiler), as FMI
   toolchains (libcosim, ecos, Simulink, Dymola) call an FMU: both FMUs in one
   process, blocks of steps alternating (ABBA), each block in CPU time of the
   process; the ratio is the median over the pairs.  Goal: at most 0.5x, i.e.
   faster than any pythonfmu FMU can be.  For context, the same steps from
   Python: through fmpy's ``FMU2Slave`` (its Python wrappers of the three calls
   cost several microseconds whatever the FMU, so no FMU gets under 0.5x that
   way), through ctypes with prebuilt arrays, and the same ctypes calls into a C
   library whose functions return at once (the call floor of ctypes): less that
   floor, what is left is each FMU's own cost.
3. **Model Exchange against Co-Simulation**: fmpy ``simulate_fmu`` of
   paper-fig9 at a = 0.083 over 100 forcing periods, ME with CVode at
   rtol 1e-10, CS with the FMU's own solver at ``tolerance`` 1e-10 and
   h = 1 ms; wall time of each and their penetrations.

Run: ``python -m benchmarks --only fmu_native`` (``--quick`` for a short run).
"""
from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import textwrap
import time
import zipfile
from pathlib import Path

if __name__ == "__main__":  # run as a script: the package lives in the repository root
    _root = str(Path(__file__).resolve().parents[1])
    if _root not in sys.path:
        sys.path.insert(0, _root)

from benchmarks import (build_trivial_fmu, fmt_ratio, fmt_time, harness_command,  # noqa: E402
                        machine_info, save_result, stage_logger, summary_row)

NAME = "fmu_native"
STEP = 1e-3
GOAL_FIRST_S = 0.020
GOAL_RATIO = 0.5
ME_PERIODS = 100
ME_RTOL = 1e-10

# ---------------------------------------------------------------------------
# 1. first start, read-only directories
# ---------------------------------------------------------------------------
_FIRST_PROBE = textwrap.dedent('''
    import json, sys, time
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave
    d = sys.argv[1]
    md = read_model_description(d + "/modelDescription.xml")
    t0 = time.perf_counter()
    s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="first")
    t1 = time.perf_counter()
    s.instantiate()
    t2 = time.perf_counter()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    t3 = time.perf_counter()
    s.doStep(0.0, 1e-3)
    x = s.getReal([0])[0]
    s.terminate()
    s.freeInstance()
    print(json.dumps({"load_s": t1 - t0, "instantiate_s": t2 - t1, "initialise_s": t3 - t2,
                      "first_s": t3 - t0}))
''')


def _read_only(path: Path) -> None:
    for p in [path, *path.rglob("*")]:
        mode = p.stat().st_mode
        p.chmod(mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def _writable(path: Path) -> None:
    for p in [path, *path.rglob("*")]:
        p.chmod(p.stat().st_mode | stat.S_IWUSR)


def measure_first_start(fmu_dir: Path, work: Path, quick: bool, log) -> dict:
    home = work / "home"
    home.mkdir()
    _read_only(fmu_dir)
    _read_only(home)
    env = {"HOME": str(home), "PATH": os.environ.get("PATH", "/usr/bin:/bin")}
    runs = []
    try:
        for _ in range(3 if quick else 7):
            r = subprocess.run([sys.executable, "-c", _FIRST_PROBE, str(fmu_dir)], capture_output=True,
                               text=True, env=env, timeout=300)
            if r.returncode != 0:
                raise RuntimeError(f"first-start probe failed ({r.returncode}): {r.stderr[-2000:]}")
            runs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    finally:
        _writable(fmu_dir)
        _writable(home)
    first = sorted(runs, key=lambda x: x["first_s"])[len(runs) // 2]   # the median run
    res = {"runs": runs, **{k: first[k] for k in ("load_s", "instantiate_s", "initialise_s", "first_s")}}
    log(f"first start (new process, read-only FMU directory and HOME), median of {len(runs)}: "
        f"{first['first_s'] * 1e3:.2f} ms (dlopen {first['load_s'] * 1e3:.2f} ms, instantiate "
        f"{first['instantiate_s'] * 1e3:.2f} ms, initialise {first['initialise_s'] * 1e3:.2f} ms); "
        f"goal <= {GOAL_FIRST_S * 1e3:g} ms")
    return res


def measure_c_host(fmu_dir: Path, work: Path, log) -> dict:
    """The C test host under ``env -i`` (no Python): 1 s of model time, process start to exit."""
    from hammerbit.fmu.native import find_compiler
    import fmpy
    from fmpy import read_model_description
    host = work / "fmu_native_host"
    src = Path(__file__).resolve().parents[1] / "tests" / "fmu_native_host.c"
    subprocess.run([find_compiler(), "-O1", "-I", str(Path(fmpy.__file__).parent / "c-code"), "-o",
                    str(host), str(src), "-ldl", "-lpthread"], check=True)
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    so = fmu_dir / "binaries" / "linux64" / "HammerBitRock.so"
    walls = []
    for _ in range(5):
        t0 = time.perf_counter()
        r = subprocess.run(["env", "-i", str(host), str(so), (fmu_dir / "resources").as_uri(), md.guid,
                            "steps=1000"], capture_output=True, text=True, timeout=60)
        walls.append(time.perf_counter() - t0)
        if r.returncode != 0:
            raise RuntimeError(f"C host failed ({r.returncode}): {r.stdout[-1000:]}")
    walls.sort()
    log(f"C host, env -i, 1000 steps of 1 ms, process start to exit: median {walls[2] * 1e3:.1f} ms")
    return {"c_host_process_s": walls[2], "c_host_all_s": walls}


# ---------------------------------------------------------------------------
# 2. warm step against the trivial pythonfmu FMU
# ---------------------------------------------------------------------------
_STEP_PROBE = textwrap.dedent('''
    import json, sys, time
    sys.path.insert(0, sys.argv[1])
    from benchmarks import LoadedFMU
    ours_path, floor_path, n, pairs, step = sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5]), \\
        float(sys.argv[6])
    reals, preload = json.loads(sys.argv[7]), float(sys.argv[8])
    ours = LoadedFMU(ours_path, "ours", reals)
    floor = LoadedFMU(floor_path, "floor")

    def stepper(inst, vin, value, vout):
        setReal, doStep, getReal = inst.fmu.setReal, inst.fmu.doStep, inst.fmu.getReal
        vin, vals, vout = [vin], [value], [vout]
        cpu = time.process_time

        def run(m):
            k0 = inst.n
            c0 = cpu()
            for k in range(k0, k0 + m):
                setReal(vin, vals)
                doStep(k * step, step)
                getReal(vout)
            c1 = cpu()
            inst.n = k0 + m
            return (c1 - c0) / m
        return run

    run_ours = stepper(ours, ours.vr["preload"], preload, ours.vr["bit_position"])
    run_floor = stepper(floor, floor.vr["u"], 1.0, floor.vr["y0"])
    run_ours(2000)
    run_floor(2000)
    t_ours, t_floor = [], []
    for i in range(pairs):
        if i % 2 == 0:
            t_floor.append(run_floor(n))
            t_ours.append(run_ours(n))
        else:
            t_ours.append(run_ours(n))
            t_floor.append(run_floor(n))
    # the same calls straight through ctypes with prebuilt arrays: what the FMUs themselves cost
    import ctypes

    def raw(inst, vin, value, vout):
        dll, c = inst.fmu.dll, inst.fmu.component
        set_real, do_step, get_real = dll.fmi2SetReal, dll.fmi2DoStep, dll.fmi2GetReal
        for f in (set_real, get_real):
            f.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
            f.restype = ctypes.c_int
        do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        do_step.restype = ctypes.c_int
        vin_a, val_a = (ctypes.c_uint * 1)(vin), (ctypes.c_double * 1)(value)
        vout_a, out_a = (ctypes.c_uint * 1)(vout), (ctypes.c_double * 1)()
        cpu = time.process_time

        def run(m):
            k0 = inst.n
            c0 = cpu()
            for k in range(k0, k0 + m):
                set_real(c, vin_a, 1, val_a)
                if do_step(c, k * step, step, 1):
                    raise RuntimeError("doStep failed")
                get_real(c, vout_a, 1, out_a)
            c1 = cpu()
            inst.n = k0 + m
            return (c1 - c0) / m
        return run

    raw_ours = raw(ours, ours.vr["preload"], preload, ours.vr["bit_position"])
    raw_floor = raw(floor, floor.vr["u"], 1.0, floor.vr["y0"])

    class NoOp:                      # the three calls into C functions that return at once
        n = 0
        class fmu:
            dll = ctypes.CDLL(sys.argv[9])
            component = None
    raw_noop = raw(NoOp, 0, 1.0, 0)
    r_ours, r_floor, r_noop = [], [], []
    for i in range(pairs):
        order = [(raw_floor, r_floor), (raw_ours, r_ours), (raw_noop, r_noop)]
        for run, out in (order if i % 2 == 0 else order[::-1]):
            out.append(run(n))
    events = sum(ours.fmu.getInteger([ours.vr[k] for k in ("slip_count", "impact_count")]))
    print(json.dumps({"ours": t_ours, "floor": t_floor, "raw_ours": r_ours, "raw_floor": r_floor,
                      "raw_noop": r_noop, "events": int(events)}), flush=True)
    ours.close()
    floor.close()
''')


_NOOP_SOURCE = """
int fmi2SetReal(void *c, const unsigned *vr, unsigned long n, const double *v) { return 0; }
int fmi2GetReal(void *c, const unsigned *vr, unsigned long n, double *v) { return 0; }
int fmi2DoStep(void *c, double t, double h, int no_prior) { return 0; }
"""


def _noop_library(work: Path) -> Path:
    """A C library whose fmi2SetReal/DoStep/GetReal return at once: the ctypes call floor."""
    from hammerbit.fmu.native import find_compiler
    src, lib = work / "noop.c", work / "libnoop.so"
    src.write_text(_NOOP_SOURCE)
    subprocess.run([find_compiler(), "-O2", "-shared", "-fPIC", "-o", str(lib), str(src)], check=True)
    return lib


def own_cost_ratio(ours, floor, noop) -> dict:
    """Median over the triples of blocks of (ours - noop) / (floor - noop): the FMUs' own cost,
    the host's call floor (the same calls into functions that return at once) taken off both."""
    import numpy as np
    o, f, z = (np.asarray(x, dtype=float) for x in (ours, floor, noop))
    r = (o - z) / (f - z)
    q1, q3 = np.percentile(r, [25, 75])
    return {"own_ratio": float(np.median(r)), "own_ratio_q1": float(q1), "own_ratio_q3": float(q3),
            "ours_own_s": float(np.median(o - z)), "floor_own_s": float(np.median(f - z)),
            "call_floor_s": float(np.median(z))}


def measure_step(fmu_path: Path, trivial: Path, work: Path, quick: bool, log) -> dict:
    from benchmarks import REPO_ROOT
    from benchmarks.bench_fmu import no_event_scene, step_statistics
    n, pairs = (1000, 21) if quick else (2000, 101)
    reals, preload = no_event_scene()
    r = subprocess.run([sys.executable, "-c", _STEP_PROBE, REPO_ROOT, str(fmu_path), str(trivial), str(n),
                        str(pairs), repr(STEP), json.dumps(reals), repr(preload), str(_noop_library(work))],
                       capture_output=True, text=True, timeout=1800)
    if r.returncode != 0:
        raise RuntimeError(f"step probe failed ({r.returncode}): {r.stderr[-2000:]}")
    p = json.loads(r.stdout.strip().splitlines()[-1])
    res = {"steps_per_block": n, "pairs": pairs, "clock": "process CPU time", "events_in_scene": p["events"],
           **step_statistics(p["ours"], p["floor"]), "ours_all_s": p["ours"], "floor_all_s": p["floor"],
           "raw": {**step_statistics(p["raw_ours"], p["raw_floor"]),
                   **own_cost_ratio(p["raw_ours"], p["raw_floor"], p["raw_noop"])},
           "raw_ours_all_s": p["raw_ours"], "raw_floor_all_s": p["raw_floor"], "raw_noop_all_s": p["raw_noop"]}
    raw = res["raw"]
    res["fmpy_wrapper_s"] = res["ours_s"] - raw["ours_s"]
    log(f"context, the same steps from Python through fmpy's FMU2Slave.setReal/doStep/getReal, CPU time, "
        f"median of {pairs} paired blocks of {n}: native {res['ours_s'] * 1e6:.2f} us, trivial pythonfmu "
        f"{res['floor_s'] * 1e6:.2f} us, ratio {res['ratio']:.3f} (quartiles {res['ratio_q1']:.3f}-"
        f"{res['ratio_q3']:.3f}): fmpy's Python wrappers (lists to ctypes arrays, checks) cost about "
        f"{res['fmpy_wrapper_s'] * 1e6:.1f} us per step whatever the FMU, so no FMU gets under "
        f"{GOAL_RATIO}x through fmpy; events {p['events']}")
    log(f"the same calls through ctypes with prebuilt arrays: native {raw['ours_s'] * 1e6:.2f} us, trivial "
        f"pythonfmu {raw['floor_s'] * 1e6:.2f} us, ratio {raw['ratio']:.3f} (quartiles "
        f"{raw['ratio_q1']:.3f}-{raw['ratio_q3']:.3f}); above the call floor of {raw['call_floor_s'] * 1e6:.2f} us "
        f"(the same calls into C functions that return at once): native {raw['ours_own_s'] * 1e6:.2f} us, "
        f"trivial pythonfmu {raw['floor_own_s'] * 1e6:.2f} us, ratio {raw['own_ratio']:.3f} (quartiles "
        f"{raw['own_ratio_q1']:.3f}-{raw['own_ratio_q3']:.3f})")
    return res


def measure_c_step(fmu_dir: Path, trivial: Path, work: Path, quick: bool, log) -> dict:
    """The warm step from a C host: the native FMU and the trivial pythonfmu FMU in one process."""
    from benchmarks.bench_fmu import no_event_scene, step_statistics
    from benchmarks.c_step_host import HostUnavailable, build_step_host, hosted_fmu, run_step_host
    n, pairs = (1000, 21) if quick else (2000, 101)
    reals, preload = no_event_scene()
    trivial_dir = work / "trivial_x"
    with zipfile.ZipFile(trivial) as zf:
        zf.extractall(trivial_dir)
    try:
        host = build_step_host(work)
        fmus = [hosted_fmu(fmu_dir, "native", "preload", preload, "bit_position", reals),
                hosted_fmu(trivial_dir, "trivial", "u", 1.0, "y0")]
        p = run_step_host(host, fmus, steps=n, pairs=pairs, h=STEP, python=True)
    except HostUnavailable as e:
        log(f"warm step from a C host: skipped, {e}")
        return {"skipped": str(e)}
    ours, floor = p["fmus"]
    res = {"host": "benchmarks/fmu_step_host.c", "steps_per_block": n, "pairs": pairs,
           "clock": "process CPU time", **step_statistics(ours["cpu_s"], floor["cpu_s"]),
           **{f"wall_{k}": v for k, v in step_statistics(ours["wall_s"], floor["wall_s"]).items()},
           "ours_all_s": ours["cpu_s"], "floor_all_s": floor["cpu_s"],
           "ours_wall_all_s": ours["wall_s"], "floor_wall_all_s": floor["wall_s"],
           "bit_position_end_m": ours["output"], "steps_each": ours["steps"]}
    log(f"warm step from a C host (fmu_step_host.c: fmi2SetReal + fmi2DoStep + fmi2GetReal, h = 1 ms), "
        f"CPU time, median of {pairs} interleaved block pairs of {n}: native {res['ours_s'] * 1e6:.3f} us, "
        f"trivial pythonfmu {res['floor_s'] * 1e6:.2f} us, ratio {res['ratio']:.4f} (quartiles "
        f"{res['ratio_q1']:.4f}-{res['ratio_q3']:.4f}; goal <= {GOAL_RATIO}); wall-clock ratio "
        f"{res['wall_ratio']:.4f}")
    return res


# ---------------------------------------------------------------------------
# 3. Model Exchange against Co-Simulation
# ---------------------------------------------------------------------------
def measure_me_vs_cs(fmu_path: Path, quick: bool, log) -> dict:
    import fmpy
    from hammerbit.model.presets import preset
    g = preset("paper-fig9").replace(a=0.083)
    rig, sc = g.to_rig(), g.scales
    names = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic", "friction_decay",
             "normal_force", "contact_stiffness", "contact_exponent", "contact_damping", "amplitude",
             "frequency", "phase", "preload")
    sv = {n: getattr(rig, n) for n in names}
    periods = 20 if quick else ME_PERIODS
    stop = periods * g.period_s
    out = {}
    for kind, kw in (("ModelExchange", dict(relative_tolerance=ME_RTOL)),
                     ("CoSimulation", dict(step_size=STEP, start_values={**sv, "tolerance": ME_RTOL}))):
        kw.setdefault("start_values", sv)
        t0 = time.perf_counter()
        res = fmpy.simulate_fmu(str(fmu_path), fmi_type=kind, stop_time=stop, output_interval=g.period_s,
                                record_events=False, output=["bit_position"], **kw)
        out[kind] = {"wall_s": time.perf_counter() - t0, "bit_position_m": float(res["bit_position"][-1])}
    me, cs = out["ModelExchange"], out["CoSimulation"]
    res = {"scene": "paper-fig9, a = 0.083", "periods": periods, "rtol": ME_RTOL, "me": me, "cs": cs,
           "ratio_me_to_cs": me["wall_s"] / cs["wall_s"],
           "penetration_rel_diff": abs(me["bit_position_m"] - cs["bit_position_m"]) / abs(cs["bit_position_m"]),
           "length_scale_m": sc.length}
    log(f"ME (CVode, rtol {ME_RTOL:g}) {me['wall_s']:.2f} s vs CS (h = 1 ms, tolerance {ME_RTOL:g}) "
        f"{cs['wall_s']:.2f} s over {periods} periods: {res['ratio_me_to_cs']:.2f}x; penetrations differ "
        f"by {res['penetration_rel_diff']:.1e} relative")
    return res


def _c_host_row(step: dict, cmd: str) -> dict:
    """The goal's row: the warm step from a C host (or why it was skipped)."""
    c = step["c_host"]
    metric = ("native FMU warm set + doStep + get from a C host (fmi2SetReal of 1 input, fmi2DoStep h = 1 ms "
              "with no event, fmi2GetReal of 1 output), vs the trivial pythonfmu FMU in the same C host")
    if "skipped" in c:
        return summary_row(metric, f"skipped: {c['skipped']}", goal=f"<= {GOAL_RATIO}x", command=cmd)
    return summary_row(metric + f"; CPU time, median over {c['pairs']} interleaved block pairs (quartiles "
                       f"{c['ratio_q1']:.3g}-{c['ratio_q3']:.3g})",
                       fmt_time(c["ours_s"]), peer=fmt_time(c["floor_s"]), ratio=fmt_ratio(c["ratio"]),
                       goal=f"<= {GOAL_RATIO}x", met=c["ratio"] <= GOAL_RATIO, command=cmd)


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Run the native-flavour benchmark; write ``benchmarks/results/fmu_native.json``."""
    log = stage_logger(NAME, verbose)
    from hammerbit.fmu.build import build_fmu
    work = Path(tempfile.mkdtemp(prefix="hammerbit_bench_fmu_native_"))
    try:
        t0 = time.perf_counter()
        fmu_path = build_fmu(work / "native" / "HammerBitRock.fmu", runtime="native")
        trivial = build_trivial_fmu(work / "floor")
        log(f"built {fmu_path.name} (native) and {trivial.name} in {time.perf_counter() - t0:.1f} s")
        fmu_dir = work / "x"
        with zipfile.ZipFile(fmu_path) as zf:
            zf.extractall(fmu_dir)
        first = measure_first_start(fmu_dir, work, quick, log)
        first.update(measure_c_host(fmu_dir, work, log))
        step = measure_step(fmu_path, trivial, work, quick, log)
        step["c_host"] = c = measure_c_step(fmu_dir, trivial, work, quick, log)
        if "skipped" not in c:
            # the pythonfmu FMU at its cheapest: its own cost called from a Python host
            c["ratio_to_floor_own_cost_from_python"] = c["ours_s"] / step["raw"]["floor_own_s"]
            log(f"the native step from C against the trivial pythonfmu FMU's own cost from Python (its "
                f"cheapest setting, {step['raw']['floor_own_s'] * 1e6:.2f} us): "
                f"{c['ratio_to_floor_own_cost_from_python']:.3f}x")
        me = measure_me_vs_cs(fmu_path, quick, log)
    finally:
        _writable(work)
        shutil.rmtree(work, ignore_errors=True)
    cmd = harness_command(NAME, quick)
    res = {
        "benchmark": NAME, "quick": quick, "command": cmd, "machine": machine_info(),
        "first_start": first, "step": step, "me_vs_cs": me,
        "summary": [
            summary_row("native FMU first start: new process, read-only FMU directory and HOME "
                        "(dlopen + instantiate + initialise)", fmt_time(first["first_s"]),
                        goal=f"<= {GOAL_FIRST_S * 1e3:g} ms", met=first["first_s"] <= GOAL_FIRST_S,
                        command=cmd),
            _c_host_row(step, cmd),
            summary_row("context: the same step from Python through fmpy's FMU2Slave setReal+doStep+getReal, "
                        "vs trivial pythonfmu FMU; fmpy's own Python wrappers (about "
                        f"{step['fmpy_wrapper_s'] * 1e6:.1f} µs per step) dominate both, so no FMU gets under "
                        f"{GOAL_RATIO}x this way; CPU time, median over {step['pairs']} paired blocks",
                        fmt_time(step["ours_s"]), peer=fmt_time(step["floor_s"]), ratio=fmt_ratio(step["ratio"]),
                        command=cmd),
            summary_row("context: the same three calls from Python through ctypes with prebuilt arrays (no fmpy "
                        "wrapper cost), vs trivial pythonfmu FMU; CPU time, median over "
                        f"{step['pairs']} paired blocks", fmt_time(step["raw"]["ours_s"]),
                        peer=fmt_time(step["raw"]["floor_s"]), ratio=fmt_ratio(step["raw"]["ratio"]),
                        command=cmd),
            summary_row("context: the FMUs' own cost from Python, the ctypes calls less the call floor (the "
                        "same calls into C functions that return at once); CPU time, median over "
                        f"{step['pairs']} blocks", fmt_time(step["raw"]["ours_own_s"]),
                        peer=fmt_time(step["raw"]["floor_own_s"]), ratio=fmt_ratio(step["raw"]["own_ratio"]),
                        command=cmd),
            summary_row(f"native FMU Model Exchange (fmpy CVode, rtol {ME_RTOL:g}) vs Co-Simulation "
                        f"(h = 1 ms), paper-fig9 a = 0.083, {me['periods']} periods, wall time",
                        fmt_time(me["me"]["wall_s"]), peer=fmt_time(me["cs"]["wall_s"]),
                        ratio=fmt_ratio(me["ratio_me_to_cs"]), command=cmd),
        ],
    }
    save_result(NAME, res)
    return res


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
