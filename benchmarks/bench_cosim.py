"""Co-simulation benchmark (issue 5): coupling error, its order, and cost against the FMI floor.

Measures, on the example string ``field-2200m`` (220 elements, 440 states)
coupled to the field hammer (:func:`hammerbit.cosim.field_hammer`):

1. **Coupling error against the macro step** for each scheme (Jacobi,
   Gauss–Seidel) and extrapolation order (0, 1, 2): maximum WOB error over the
   run relative to the monolithic reference's dynamic WOB amplitude, and the
   relative error of that amplitude; the measured order is the least-squares
   slope of log(error) against log(H).  The hammer runs in process (the FMU's
   kernels; the FMU gives the same numbers to 5e-8 N, ``tests/test_cosim.py``).
2. **Wall time against error** for each scheme (same runs).
3. **Cost of a 60 s run at H = 1 ms** (60 000 macro steps) through the real
   ``HammerBitRock.fmu`` (fmpy ``FMU2Slave``) against the **FMI call floor**:
   a trivial pythonfmu FMU (one input, four outputs, ``do_step`` returns at
   once), built in a temporary directory and driven with the same calls per
   step (one ``setReal``, one ``doStep``, one ``getReal`` of 5 values).
   Goal: at most 2x the floor.

Run: ``python -m benchmarks --only cosim`` (``--quick`` for a short run).
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks import (LoadedFMU, build_trivial_fmu, fmt_time, harness_command, machine_info, repo_on_path,
                        save_result, stage_logger, summary_row)

NAME = "cosim"


def fmi_floor(fmu_path, n_steps: int, H: float) -> float:
    """Seconds for ``n_steps`` of (setReal 1, doStep, getReal 5) on the trivial FMU."""
    fmu = LoadedFMU(fmu_path, "floor")
    try:
        vout = [fmu.vr[n] for n in ("y0", "y1", "y2", "y3", "y4")]
        return fmu.loop(n_steps, fmu.vr["u"], 1.0, vout, H) * n_steps
    finally:
        fmu.close()


def _config(quick: bool) -> dict:
    if quick:
        return {"stop": 1.5, "steps": [0.5e-3, 1e-3, 2e-3], "long_stop": 10.0}
    return {"stop": 3.0, "steps": [0.25e-3, 0.5e-3, 1e-3, 2e-3], "long_stop": 60.0}


def _order(H, err):
    H, err = np.asarray(H), np.asarray(err)
    ok = err > 0
    if ok.sum() < 2:
        return math.nan
    return float(np.polyfit(np.log(H[ok]), np.log(err[ok]), 1)[0])


def measure_errors(cfg: dict, log) -> dict:
    from hammerbit.cosim import CosimConfig, SCHEMES, cosimulate, monolithic
    from hammerbit.drillstring import load_string
    string = load_string("field-2200m")
    # reference on the finest grid; coarser grids are sub-samples of it
    Hmin = min(cfg["steps"])
    base = CosimConfig(stop=cfg["stop"], step=Hmin, record=("wob",))
    log("monolithic reference ...")
    ref = monolithic(string, base)
    # the reference on each grid H and its dynamic WOB amplitude
    ref_on = {}
    for H in cfg["steps"]:
        rw = ref.data[::int(round(H / Hmin))]
        ref_on[H] = (rw, 0.5 * np.ptp(rw["wob"][rw["time"] >= cfg["stop"] / 2]))
    rows = []
    for scheme in SCHEMES:
        for order in (0, 1, 2):
            for H in cfg["steps"]:
                c = base.replace(step=H, scheme=scheme, extrapolation=order)
                r = cosimulate(string, c)
                rw, ref_amp = ref_on[H]
                assert np.allclose(rw["time"], r.data["time"], rtol=0, atol=1e-12)
                amp = r.wob_amplitude()
                rows.append({"scheme": scheme, "extrapolation": order, "step_s": H,
                             "max_wob_error_rel": float(np.max(np.abs(r.data["wob"] - rw["wob"])) / ref_amp),
                             "wob_amplitude_error_rel": abs(amp / ref_amp - 1.0),
                             "wall_time_s": r.wall_time_s, "macro_steps": r.macro_steps})
                log(f"{scheme:13s} order {order} H {H * 1e3:5.2f} ms: max WOB error "
                    f"{rows[-1]['max_wob_error_rel']:.3e}, amplitude error "
                    f"{rows[-1]['wob_amplitude_error_rel']:.3e}, wall {r.wall_time_s:.3f} s")
    orders = []
    for scheme in SCHEMES:
        for order in (0, 1, 2):
            sel = [r for r in rows if r["scheme"] == scheme and r["extrapolation"] == order]
            orders.append({"scheme": scheme, "extrapolation": order,
                           "measured_order": _order([r["step_s"] for r in sel],
                                                    [r["max_wob_error_rel"] for r in sel])})
    return {"reference": {"rtol": base.rtol, "wall_time_s": ref.wall_time_s,
                          "wob_amplitude_n": ref.wob_amplitude(), "stop_s": cfg["stop"]},
            "rows": rows, "orders": orders}


def measure_long_run(cfg: dict, log) -> dict:
    repo_on_path()
    from build_fmu import build_fmu
    from hammerbit.cosim import CosimConfig, cosimulate
    from hammerbit.drillstring import load_string
    string = load_string("field-2200m")
    H = 1e-3
    with tempfile.TemporaryDirectory(prefix="hammerbit_bench_cosim_") as tmp:
        fmu = build_fmu(Path(tmp) / "real")
        triv = build_trivial_fmu(Path(tmp) / "trivial", n_outputs=5)
        out = {}
        for label, f_max in (("nodal", None), ("modal_f_max_100hz", 100.0)):
            c = CosimConfig(stop=cfg["long_stop"], step=H, record=("wob",), progress=False, f_max=f_max,
                            rtol=1e-8)
            log(f"{cfg['long_stop']:g} s at H = 1 ms through the FMU, string {label} ...")
            r = cosimulate(string, c, fmu=fmu)
            out[label] = {"wall_time_s": r.wall_time_s, "setup_time_s": r.setup_time_s,
                          "macro_steps": r.macro_steps, "string_states": r.stats["string_states"],
                          "wob_amplitude_n": r.wob_amplitude()}
        n = out["nodal"]["macro_steps"]
        log(f"HammerBitRock.fmu alone (constant preload, same calls), {n} steps ...")
        from hammerbit.cosim import FMUHammer, field_hammer
        rig = field_hammer()
        hm = FMUHammer(fmu, rig, rig.preload, rtol=1e-8)
        t1 = time.perf_counter()
        for k in range(n):
            hm.step(k * H, H, rig.preload)
            hm.read()
        out["fmu_alone_s"] = time.perf_counter() - t1
        hm.close()
        log(f"FMI floor: trivial FMU, {n} steps ...")
        floor = min(fmi_floor(triv, n, H) for _ in range(2))
        out["floor_s"] = floor
        out["floor_per_step_us"] = floor / n * 1e6
    return out


def _plot(result):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    rows = result["errors"]["rows"]
    marks = {"jacobi": "o-", "gauss-seidel": "s--"}
    for scheme in ("jacobi", "gauss-seidel"):
        for order in (0, 1, 2):
            sel = [r for r in rows if r["scheme"] == scheme and r["extrapolation"] == order]
            H = [r["step_s"] * 1e3 for r in sel]
            e = [r["max_wob_error_rel"] for r in sel]
            w = [r["wall_time_s"] for r in sel]
            lab = f"{scheme}, order {order}"
            ax[0].loglog(H, e, marks[scheme], label=lab, color=f"C{order}")
            ax[1].loglog(e, w, marks[scheme], label=lab, color=f"C{order}")
    ax[0].set_xlabel("macro step H [ms]")
    ax[0].set_ylabel("max |WOB error| / WOB amplitude")
    ax[0].set_title("coupling error vs macro step")
    ax[0].grid(True, which="both", alpha=0.3)
    ax[0].legend(fontsize=7)
    ax[1].set_xlabel("max |WOB error| / WOB amplitude")
    ax[1].set_ylabel("wall time [s] (in-process hammer)")
    ax[1].set_title("wall time vs error")
    ax[1].grid(True, which="both", alpha=0.3)
    fig.suptitle("Co-simulation, field-2200m + field hammer" + (" (quick run)" if result["quick"] else ""))
    fig.tight_layout()
    return fig


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Run the co-simulation benchmark; write ``results/cosim.{json,png}``."""
    log = stage_logger("cosim", verbose)

    cfg = _config(quick)
    t0 = time.perf_counter()
    errors = measure_errors(cfg, log)
    long = measure_long_run(cfg, log)
    cmd = harness_command(NAME, quick)
    summary = []
    for o in errors["orders"]:
        sel = [r for r in errors["rows"] if r["scheme"] == o["scheme"] and r["extrapolation"] == o["extrapolation"]
               and abs(r["step_s"] - 1e-3) < 1e-12]
        at1 = sel[0] if sel else None
        summary.append(summary_row(
            f"coupling error, {o['scheme']}, extrapolation order {o['extrapolation']}: measured order "
            f"(max WOB error vs H); WOB amplitude error at H = 1 ms vs monolithic",
            f"order {o['measured_order']:.2f}; {at1['wob_amplitude_error_rel']:.2e}" if at1 else
            f"order {o['measured_order']:.2f}",
            goal="amplitude error <= 1e-3 (with extrapolation)" if o["extrapolation"] > 0 else None,
            met=(at1["wob_amplitude_error_rel"] <= 1e-3) if (at1 and o["extrapolation"] > 0) else None,
            command=cmd))
    n = long["nodal"]["macro_steps"]
    for label, desc in (("nodal", "440 nodal states"), ("modal_f_max_100hz", "modes <= 100 Hz")):
        w = long[label]["wall_time_s"]
        ratio = w / long["floor_s"]
        summary.append(summary_row(
            f"{cfg['long_stop']:g} s simulated at H = 1 ms ({n} macro steps) through HammerBitRock.fmu, "
            f"string {desc} ({long[label]['string_states']} states); peer = FMI call floor (trivial "
            f"pythonfmu FMU, same calls)",
            fmt_time(w), peer=fmt_time(long["floor_s"]), ratio=f"{ratio:.2f}x floor",
            goal="<= 2x floor", met=ratio <= 2.0, command=cmd))
    summary.append(summary_row(
        f"breakdown: HammerBitRock.fmu stepped alone {n} times (constant preload, same calls, no string) "
        f"vs the FMI call floor -- the FMU's own hybrid integration per step",
        fmt_time(long["fmu_alone_s"]), peer=fmt_time(long["floor_s"]),
        ratio=f"{long['fmu_alone_s'] / long['floor_s']:.2f}x floor", command=cmd))
    result = {"benchmark": NAME, "quick": quick, "command": cmd, "argv": sys.argv, "machine": machine_info(),
              "config": cfg, "errors": errors, "long_run": long, "summary": summary,
              "elapsed_s": time.perf_counter() - t0}
    save_result(NAME, result, _plot(result))
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
