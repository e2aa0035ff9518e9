"""One ``drilling.ssp``, three runners, against the monolithic reference.

``python -m benchmarks --only ssp`` builds ``drilling.ssp`` of the drilling
case (field-2200m, the field hammer at 22.5 Hz, A = 15 kN, WOB 55 kN, 2 s,
H = 1 ms) with ``hammerbit ssp build`` and runs it

* in libcosimpy (``CosimExecution.from_ssp_file``, fixed step from the package),
* in FMPy (``fmpy.ssp.simulate_ssp``, fixed step),
* in ``hammerbit cosim --ssp`` at the same fixed step (with its error estimate),
  and with its default adaptive step,

and the monolithic reference of the same system (``--ssp --monolithic``).  On
the same package, a user's own fixed-step Jacobi loop over the two FMUs
(``hammerbit.ssp.runners.run_user_loop``) at H = 1, 0.5 and 0.25 ms, and at 1 ms
with the wrong wiring (``interface_force - wob`` into ``harmonic_force``): the
table of the master's step against the error.  And the native Drillstring's
cost of a step of a length it was not built for: the first step at a new h
(its exponentials computed) against a step at the built h.  It writes
``results/ssp.json`` and, with ``--update``, the tables between
``<!-- ssp-runner-table:start -->`` and ``<!-- ssp-runner-table:end -->`` and
between ``<!-- ssp-step-table:start -->`` and ``<!-- ssp-step-table:end -->`` in
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
STEP_TAG = "ssp-step-table"
#: the master steps of the step table [s]
LOOP_STEPS_S = (1e-3, 5e-4, 2.5e-4)
#: the native Drillstring's step-cost case: (string, top condition, a step it was not built for [s])
COST_CASES = (("field-2200m", 0, 7.3e-4), ("field-2200m", 2, 7.3e-4), ("lab", 2, 7.3e-4))
COST_REPEATS = 200


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


def step_table(result: dict) -> str:
    """Markdown: a user's Jacobi loop at each master step (and the wrong wiring) against the reference."""
    c = result["case"]
    lines = ["| master step H [ms] | wiring | penetration [mm] | error vs reference | WOB amplitude [kN] | "
             "error vs reference | wall time [s] |", "|---|---|---|---|---|---|---|"]
    for r in result["step_rows"]:
        lines.append(f"| {r['step_s'] * 1e3:g} | `{r['wiring']}` | {r['penetration_m'] * 1e3:.6f} | "
                     f"{r['penetration_error_rel']:.2e} | {r['wob_amplitude_n'] / 1e3:.4f} | "
                     f"{r['wob_amplitude_error_rel']:.2e} | {r['wall_time_s']:.2f} |")
    return ("\n".join(lines) + f"\n\nCase: {c['string']}, field hammer at {c['frequency_hz']:g} Hz, "
            f"{c['stop_s']:g} s; a fixed-step Jacobi loop over the package's two FMUs through fmpy "
            f"(`hammerbit.ssp.runners.run_user_loop`); errors relative to the monolithic reference of the "
            f"table above.  Load {result['machine'].get('load_average', '?')}.\n")


def _replace_between(text: str, tag: str, table_text: str) -> str:
    start, end = f"<!-- {tag}:start -->", f"<!-- {tag}:end -->"
    body = f"{start}\n{table_text}{end}"
    if start in text:
        return re.sub(re.escape(start) + ".*?" + re.escape(end), lambda _m: body, text, flags=re.S)
    return text.rstrip("\n") + "\n\n" + body + "\n"


def update_docs(result: dict) -> None:
    text = open(DOC, encoding="utf-8").read()
    text = _replace_between(text, TAG, table(result))
    text = _replace_between(text, STEP_TAG, step_table(result))
    with open(DOC, "w", encoding="utf-8") as fh:
        fh.write(text)


def step_rows(path: str, stop: float, ref, t_from: float) -> list:
    """A user's Jacobi loop at each step of :data:`LOOP_STEPS_S`, and at 1 ms wired wrong."""
    from hammerbit.ssp.runners import WIRINGS, run_user_loop
    rows = []
    for step, wiring in [(h, WIRINGS[0]) for h in LOOP_STEPS_S] + [(LOOP_STEPS_S[0], WIRINGS[1])]:
        r = run_user_loop(path, stop, step, wiring)
        row = _row(r.runner, r.penetration_m, r.wob_amplitude(t_from, FREQUENCY_HZ), r.wall_time_s, ref)
        rows.append({**row, "step_s": step, "wiring": wiring})
    return rows


def string_step_cost(work: str, quick: bool) -> list:
    """The native Drillstring's first step at a step length it was not built for (its exponentials
    computed in the binary) against a step at the built length (median of :data:`COST_REPEATS`)."""
    import statistics
    from hammerbit.fmu.host import FMUInstance
    from hammerbit.fmu.native_string import build_native_string_fmu
    out, built = [], {}
    for string, top, h_new in COST_CASES[:1] if quick else COST_CASES:
        if string not in built:
            built[string] = build_native_string_fmu(string, os.path.join(work, string, "Drillstring.fmu"),
                                                    log=lambda m: None)
        fmu = FMUInstance(built[string], "string", init=False)
        try:
            fmu.fmu.setInteger([fmu.vr["top_condition"]], [top])
            fmu.fmu.exitInitializationMode()
            times = []
            for _ in range(COST_REPEATS):
                t0 = time.perf_counter()
                fmu.step(STEP_S)
                times.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            fmu.step(h_new)
            first = time.perf_counter() - t0
            t0 = time.perf_counter()
            fmu.step(h_new)
            again = time.perf_counter() - t0
        finally:
            fmu.close()
        out.append({"string": string, "top_condition": top, "h_new_s": h_new, "first_step_s": first,
                    "second_step_s": again, "built_step_s": statistics.median(times)})
    return out


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
        loops = step_rows(path, stop, ref, t_from)
        cost = string_step_cost(tmp, quick)
    pens = [r["penetration_m"] for r in rows[:3]]
    spread = (max(pens) - min(pens)) / max(abs(fixed.penetration_m), 1e-12)
    result = {
        "benchmark": NAME, "quick": quick, "command": harness_command(NAME, quick), "machine": machine_info(),
        "case": {"string": "field-2200m", "frequency_hz": FREQUENCY_HZ, "stop_s": stop, "step_s": STEP_S},
        "build_s": build_s, "rows": rows,
        "reference": {"penetration_m": ref.penetration_m, "wob_amplitude_n": ref.wob_amplitude(),
                      "wall_time_s": ref_wall},
        "estimate_fixed": fixed.estimate.to_dict(), "estimate_adaptive": adaptive.estimate.to_dict(),
        "max_fixed_step_spread_rel": spread, "step_rows": loops, "string_step_cost": cost,
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
    forms = {("field-2200m", 0): "fixed hook, modal, 440 states", ("field-2200m", 2): "auto-driller, modal",
             ("lab", 2): "auto-driller, dense, 62 states"}
    for c in cost:
        result["summary"].append(summary_row(
            f"native Drillstring.fmu ({c['string']}, {forms[(c['string'], c['top_condition'])]}): first step at a "
            f"length it was not built for (h = {c['h_new_s'] * 1e3:g} ms, exponentials computed) vs a step at the "
            f"built 1 ms (median of {COST_REPEATS}), through fmpy",
            fmt_time(c["first_step_s"]), peer=fmt_time(c["built_step_s"]),
            ratio=fmt_ratio(c["first_step_s"] / c["built_step_s"]), command=harness_command(NAME, quick)))
    save_result(NAME, result)
    if benchmarks.UPDATE and not quick:
        update_docs(result)
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
