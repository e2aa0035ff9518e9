"""The fixed-step Jacobi master with and without the hammer's output derivatives.

``python -m benchmarks --only output_derivatives`` builds the native ``drilling.ssp`` of the
drilling case of ``docs/cosim.md`` (field-2200m, the field hammer at 22.5 Hz, 2 s; ``hammerbit ssp
build --runtime native``), whose HammerBitRock.fmu gives output derivatives of orders 1 and 2
and whose Drillstring.fmu takes input derivatives, and runs

* a user's fixed-step Jacobi loop over the two FMUs (``hammerbit.ssp.runners.run_user_loop``) at
  H = 1 and 0.5 ms, without and with ``output_derivatives`` (the hammer's position and velocity
  derivatives into the string's input derivatives: the string takes the hammer motion over a
  step as their polynomial instead of extrapolating it through the last inputs);
* ``hammerbit cosim --ssp --step 0.001`` without and with ``--output-derivatives`` (the
  project's master on the same package, no error estimate);

against the monolithic reference of the same system.  It writes ``results/output_derivatives.json``
and, with ``--update``, the table between ``<!-- ssp-derivatives-table:start -->`` and
``<!-- ssp-derivatives-table:end -->`` in ``docs/cosim.md``.  Wall times include each run's set-up.
"""
from __future__ import annotations

import os
import tempfile
import time

from benchmarks import REPO_ROOT, fmt_ratio, fmt_time, harness_command, machine_info, save_result, summary_row
from benchmarks.bench_ssp import FREQUENCY_HZ, QUICK_STOP_S, STOP_S, _replace_between, _row

NAME = "output_derivatives"
DOC = os.path.join(REPO_ROOT, "docs", "cosim.md")
TAG = "ssp-derivatives-table"
#: the master steps of the table [s]
STEPS_S = (1e-3, 5e-4)


def table(result: dict) -> str:
    """Markdown: each run's error against the reference, and its wall time."""
    c = result["case"]
    lines = ["| master | H [ms] | output derivatives | penetration [mm] | error vs reference | "
             "WOB amplitude [kN] | error vs reference | wall time [s] |", "|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        lines.append(f"| {r['master']} | {r['step_s'] * 1e3:g} | {'yes' if r['output_derivatives'] else 'no'} | "
                     f"{r['penetration_m'] * 1e3:.6f} | {r['penetration_error_rel']:.2e} | "
                     f"{r['wob_amplitude_n'] / 1e3:.4f} | {r['wob_amplitude_error_rel']:.2e} | "
                     f"{r['wall_time_s']:.2f} |")
    ref = result["reference"]
    lines.append(f"| monolithic reference | — | — | {ref['penetration_m'] * 1e3:.6f} | — | "
                 f"{ref['wob_amplitude_n'] / 1e3:.4f} | — | {ref['wall_time_s']:.2f} |")
    return ("\n".join(lines) + f"\n\nCase: {c['string']}, field hammer at {c['frequency_hz']:g} Hz, "
            f"{c['stop_s']:g} s; the native `drilling.ssp` (`hammerbit ssp build --runtime native`); `user "
            f"loop`: `hammerbit.ssp.runners.run_user_loop` over its two FMUs through fmpy; `cosim --ssp`: "
            f"`hammerbit cosim --ssp --step` without its estimate (after a short run of each that loads its kernels).  Load "
            f"{result['machine'].get('load_average', '?')}.\n")


def update_docs(result: dict) -> None:
    text = open(DOC, encoding="utf-8").read()
    with open(DOC, "w", encoding="utf-8") as fh:
        fh.write(_replace_between(text, TAG, table(result)))


def _rows(path: str, stop: float, ref, t_from: float) -> list:
    from hammerbit.ssp.run import cosimulate_ssp
    from hammerbit.ssp.runners import run_user_loop
    rows = []
    for step in STEPS_S:
        for given in (False, True):
            r = run_user_loop(path, stop, step, output_derivatives=given)
            row = _row(r.runner, r.penetration_m, r.wob_amplitude(t_from, FREQUENCY_HZ), r.wall_time_s, ref)
            rows.append({**row, "master": "user loop", "step_s": step, "output_derivatives": given})
    for given in (False, True):   # a short run of each first: the in-process kernels loaded, not timed
        cosimulate_ssp(path, stop=10 * STEPS_S[0], step=STEPS_S[0], adaptive=False, estimate=False,
                       output_derivatives=given)
    for given in (False, True):
        t0 = time.perf_counter()
        res = cosimulate_ssp(path, stop=stop, step=STEPS_S[0], adaptive=False, estimate=False,
                             output_derivatives=given)
        row = _row("cosim --ssp", res.penetration_m, res.wob_amplitude(), time.perf_counter() - t0, ref)
        rows.append({**row, "master": "cosim --ssp", "step_s": STEPS_S[0], "output_derivatives": given})
    return rows


def run(quick: bool = False) -> dict:
    import benchmarks
    from hammerbit.cosim.config import field_hammer, steady_start
    from hammerbit.ssp.package import SSPOptions, build_ssp
    from hammerbit.ssp.run import monolithic_ssp
    stop = QUICK_STOP_S if quick else STOP_S
    with tempfile.TemporaryDirectory(prefix="bench_derivatives_") as tmp:
        path = build_ssp("field-2200m", os.path.join(tmp, "drilling.ssp"),
                         SSPOptions(stop=stop, step=STEPS_S[0], rig=field_hammer().replace(frequency=FREQUENCY_HZ),
                                    runtime="native"))
        t0 = time.perf_counter()
        ref = monolithic_ssp(path)
        ref_wall = time.perf_counter() - t0
        rows = _rows(path, stop, ref, steady_start(ref.config))
    result = {
        "benchmark": NAME, "quick": quick, "command": harness_command(NAME, quick), "machine": machine_info(),
        "case": {"string": "field-2200m", "frequency_hz": FREQUENCY_HZ, "stop_s": stop},
        "rows": rows,
        "reference": {"penetration_m": ref.penetration_m, "wob_amplitude_n": ref.wob_amplitude(),
                      "wall_time_s": ref_wall},
    }
    result["summary"] = []
    for master, step in [("user loop", h) for h in STEPS_S] + [("cosim --ssp", STEPS_S[0])]:
        off, on = (next(r for r in rows if r["master"] == master and r["step_s"] == step
                        and r["output_derivatives"] == g) for g in (False, True))
        result["summary"].append(summary_row(
            f"drilling.ssp (native) {stop:g} s, fixed-step Jacobi ({master}) at H = {step * 1e3:g} ms: penetration "
            f"error {on['penetration_error_rel']:.2e} with the hammer's output derivatives vs "
            f"{off['penetration_error_rel']:.2e} without; wall time with vs without",
            fmt_time(on["wall_time_s"]), peer=fmt_time(off["wall_time_s"]),
            ratio=fmt_ratio(off["wall_time_s"] / on["wall_time_s"]), command=harness_command(NAME, quick)))
    save_result(NAME, result)
    if benchmarks.UPDATE and not quick:
        update_docs(result)
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
