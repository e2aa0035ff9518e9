"""One ``drilling.ssp``, three runners, against the monolithic reference.

``python -m benchmarks --only ssp`` builds ``drilling.ssp`` of the drilling
case (field-2200m, the field hammer at 22.5 Hz, A = 15 kN, WOB 55 kN, 2 s,
H = 1 ms) with ``hammerbit ssp build`` and runs it

* in libcosimpy (``CosimExecution.from_ssp_file``, fixed step from the package),
* in FMPy (``fmpy.ssp.simulate_ssp``, fixed step),
* in ``hammerbit cosim --ssp`` at the same fixed step (with its error estimate),
  and with its default adaptive step,

and the monolithic reference of the same system (``--ssp --monolithic``).  It
writes ``results/ssp.json`` and, with ``--update``, the table between
``<!-- ssp-runner-table:start -->`` and ``<!-- ssp-runner-table:end -->`` in
``docs/cosim.md``.  Wall times include each runner's set-up (extracting and
instantiating the FMUs); they follow the machine's load, recorded with the
result.
"""
from __future__ import annotations

import os
import re
import tempfile
import time

from benchmarks import REPO_ROOT, fmt_ratio, fmt_time, harness_command, machine_info, save_result, summary_row

NAME = "ssp"
DOC = os.path.join(REPO_ROOT, "docs", "cosim.md")
TAG = "ssp-runner-table"
#: the drilling case of docs/cosim.md
FREQUENCY_HZ = 22.5
STOP_S, STEP_S = 2.0, 1e-3
QUICK_STOP_S = 0.4


def _row(name: str, pen: float, amp: float, wall: float, ref) -> dict:
    return {"runner": name, "penetration_m": pen, "wob_amplitude_n": amp, "wall_time_s": wall,
            "penetration_error_rel": abs(pen - ref.penetration_m) / max(abs(ref.penetration_m), 1e-12),
            "wob_amplitude_error_rel": abs(amp - ref.wob_amplitude()) / ref.wob_amplitude()}


def table(result: dict) -> str:
    """Markdown: penetration, WOB amplitude and wall time per runner against the reference."""
    ref = result["reference"]
    lines = ["| runner | penetration [mm] | error vs reference | WOB amplitude [kN] | error vs reference | "
             "wall time [s] |", "|---|---|---|---|---|---|"]
    for r in result["rows"]:
        lines.append(f"| {r['runner']} | {r['penetration_m'] * 1e3:.6f} | {r['penetration_error_rel']:.2e} | "
                     f"{r['wob_amplitude_n'] / 1e3:.4f} | {r['wob_amplitude_error_rel']:.2e} | "
                     f"{r['wall_time_s']:.2f} |")
    lines.append(f"| monolithic reference | {ref['penetration_m'] * 1e3:.6f} | — | "
                 f"{ref['wob_amplitude_n'] / 1e3:.4f} | — | {ref['wall_time_s']:.2f} |")
    est = result["estimate_fixed"]
    c = result["case"]
    return ("\n".join(lines) + f"\n\nCase: {c['string']}, field hammer at {c['frequency_hz']:g} Hz, "
            f"{c['stop_s']:g} s at H = {c['step_s'] * 1e3:g} ms (the adaptive run from H); the same "
            f"`drilling.ssp` in every runner.  The fixed-step runs agree to "
            f"{result['max_fixed_step_spread_rel']:.1e} (relative) in penetration; `hammerbit cosim --ssp "
            f"--step 0.001` estimates its own error at {est['penetration_rel']:.2e} (penetration) and "
            f"{est['wob_amplitude_rel']:.2e} (WOB amplitude).  WOB amplitude: the fundamental harmonic "
            f"of the rock force at the forcing frequency over the second half.  Wall times include each runner's set-up; load "
            f"{result['machine'].get('load_average', '?')}.\n")


def update_docs(result: dict) -> None:
    text = open(DOC, encoding="utf-8").read()
    start, end = f"<!-- {TAG}:start -->", f"<!-- {TAG}:end -->"
    body = f"{start}\n{table(result)}{end}"
    if start in text:
        text = re.sub(re.escape(start) + ".*?" + re.escape(end), lambda _m: body, text, flags=re.S)
    else:
        text = text.rstrip("\n") + "\n\n" + body + "\n"
    with open(DOC, "w", encoding="utf-8") as fh:
        fh.write(text)


def run(quick: bool = False) -> dict:
    import benchmarks
    from hammerbit.cosim.config import field_hammer, steady_start
    from hammerbit.ssp.package import SSPOptions, build_ssp
    from hammerbit.ssp.run import cosimulate_ssp, monolithic_ssp
    from hammerbit.ssp.runners import run_fmpy, run_libcosim
    stop = QUICK_STOP_S if quick else STOP_S
    with tempfile.TemporaryDirectory(prefix="bench_ssp_") as tmp:
        t0 = time.perf_counter()
        path = build_ssp("field-2200m", os.path.join(tmp, "drilling.ssp"),
                         SSPOptions(stop=stop, step=STEP_S, rig=field_hammer().replace(frequency=FREQUENCY_HZ)))
        build_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        ref = monolithic_ssp(path)
        ref_wall = time.perf_counter() - t0
        t_from = steady_start(ref.config)
        rows = []
        lib = run_libcosim(path, stop)
        rows.append(_row("libcosimpy (fixed step)", lib.penetration_m, lib.wob_amplitude(t_from, FREQUENCY_HZ),
                         lib.wall_time_s, ref))
        fm = run_fmpy(path, stop, STEP_S)
        rows.append(_row("FMPy simulate_ssp (fixed step)", fm.penetration_m, fm.wob_amplitude(t_from, FREQUENCY_HZ),
                         fm.wall_time_s, ref))
        t0 = time.perf_counter()
        fixed = cosimulate_ssp(path, adaptive=False)
        rows.append(_row("hammerbit cosim --ssp --step 0.001 (with its estimate)", fixed.penetration_m,
                         fixed.wob_amplitude(), time.perf_counter() - t0, ref))
        t0 = time.perf_counter()
        adaptive = cosimulate_ssp(path, adaptive=True)
        rows.append(_row("hammerbit cosim --ssp (adaptive, tol 1e-3)", adaptive.penetration_m,
                         adaptive.wob_amplitude(), time.perf_counter() - t0, ref))
    pens = [r["penetration_m"] for r in rows[:3]]
    spread = (max(pens) - min(pens)) / max(abs(fixed.penetration_m), 1e-12)
    result = {
        "benchmark": NAME, "quick": quick, "command": harness_command(NAME, quick), "machine": machine_info(),
        "case": {"string": "field-2200m", "frequency_hz": FREQUENCY_HZ, "stop_s": stop, "step_s": STEP_S},
        "build_s": build_s, "rows": rows,
        "reference": {"penetration_m": ref.penetration_m, "wob_amplitude_n": ref.wob_amplitude(),
                      "wall_time_s": ref_wall},
        "estimate_fixed": fixed.estimate.to_dict(), "estimate_adaptive": adaptive.estimate.to_dict(),
        "max_fixed_step_spread_rel": spread,
    }
    result["summary"] = [
        summary_row("drilling.ssp 2 s, H = 1 ms: libcosimpy wall time vs hammerbit cosim --ssp --step",
                    fmt_time(rows[2]["wall_time_s"]), peer=fmt_time(rows[0]["wall_time_s"]),
                    ratio=fmt_ratio(rows[0]["wall_time_s"] / rows[2]["wall_time_s"]),
                    command=harness_command(NAME, quick)),
        summary_row("drilling.ssp 2 s, H = 1 ms: FMPy simulate_ssp wall time vs hammerbit cosim --ssp --step",
                    fmt_time(rows[2]["wall_time_s"]), peer=fmt_time(rows[1]["wall_time_s"]),
                    ratio=fmt_ratio(rows[1]["wall_time_s"] / rows[2]["wall_time_s"]),
                    command=harness_command(NAME, quick)),
    ]
    save_result(NAME, result)
    if benchmarks.UPDATE and not quick:
        update_docs(result)
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
