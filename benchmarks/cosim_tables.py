"""The co-simulation tables of ``docs/cosim.md``, regenerated from ``benchmarks/results/cosim.json``.

Writes, between markers in ``docs/cosim.md``::

    <!-- cosim-estimate-table:start -->   estimate vs true error (stuck, drilling; H)
    <!-- cosim-estimate-table:end -->
    <!-- cosim-accuracy-table:start -->   drilling case: fixed H = 1, 0.5, 0.25 ms, orders, default run
    <!-- cosim-accuracy-table:end -->
    <!-- cosim-scheme-table:start -->     error and order per scheme and extrapolation order
    <!-- cosim-scheme-table:end -->
    <!-- cosim-cost-table:start -->       long run through the FMU against the FMI call floor
    <!-- cosim-cost-table:end -->

Usage: ``python -m benchmarks.cosim_tables`` (rewrites docs/cosim.md), ``--print`` to only print.
"""
from __future__ import annotations

import json
import math
import os
import re
import sys

from benchmarks import REPO_ROOT, TRACKED_RESULTS_DIR

__all__ = ["estimate_table", "accuracy_table", "scheme_table", "cost_table", "update_docs", "main"]

DOC = os.path.join(REPO_ROOT, "docs", "cosim.md")


def _e(x) -> str:
    return "—" if x is None else f"{x:.2e}"


def _r(x) -> str:
    return "—" if x is None else f"{x:.2f}"


def estimate_table(result: dict) -> str:
    """Markdown: estimate vs true error per case and step."""
    est = result["estimate"]
    lines = ["| case | H [ms] | slips | WOB amplitude error | estimate | ratio | penetration error | "
             "estimate | ratio |", "|---|---|---|---|---|---|---|---|---|"]
    for r in est["rows"]:
        drilling = r["case"] == "drilling"
        lines.append(
            f"| {r['case']} | {r['step_s'] * 1e3:g} | {r['slips']} | {_e(r['wob_amplitude_error_rel'])} | "
            f"{_e(r['wob_amplitude_estimate_rel'])} | {_r(r['wob_amplitude_ratio'])} | "
            f"{_e(r['penetration_error_rel']) if drilling else '0 (stuck)'} | "
            f"{_e(r['penetration_estimate_rel'])} | {_r(r['penetration_ratio'])} |")
    cases = est["cases"]
    notes = "; ".join(f"{k}: A = {v['amplitude_n'] / 1e3:g} kN at {v['frequency_hz']:g} Hz, "
                      f"{v['stop_s']:g} s, reference penetration {v['reference_penetration_m'] * 1e3:.4g} mm, "
                      f"{v['reference_counts']['slips']} slips" for k, v in cases.items())
    return "\n".join(lines) + f"\n\nCases ({notes}).\n"


def accuracy_table(result: dict) -> str:
    """Markdown: the drilling case at fixed H and at the default tolerance."""
    acc = result["estimate"]["accuracy"]
    lines = ["| run | WOB amplitude error | penetration error | hammer steps (run + companion) | wall time [s] |",
             "|---|---|---|---|---|"]
    for r in acc["fixed"]:
        lines.append(f"| fixed H = {r['step_s'] * 1e3:g} ms (no estimate) | {_e(r['wob_amplitude_error_rel'])} | "
                     f"{_e(r['penetration_error_rel'])} | {r['macro_steps']} | {r['wall_time_s']:.3f} |")
    d = acc["default"]
    steps = f"{d['hammer_steps']} + {d['companion_steps']}"
    lines.append(f"| default: adaptive, tol {d['tol']:g} ({d['macro_steps']} steps of "
                 f"{d['h_min_used_s'] * 1e3:g}..{d['h_max_used_s'] * 1e3:g} ms, {d['rejected']} rolled back, "
                 f"{d['passes']} pass(es), with the estimate) | {_e(d['wob_amplitude_error_rel'])} | "
                 f"{_e(d['penetration_error_rel'])} | {steps} | {d['wall_time_s']:.3f} |")
    ratio = d["wall_time_s"] / acc["fixed_1ms_wall_time_s"]
    return ("\n".join(lines) + f"\n\n{_orders_text(acc['fixed'])} "
            f"The default run takes {ratio:.1f} times the wall time of the fixed 1 ms run without the "
            f"estimate, measured in the same benchmark run{_then_now_text()}. Hammer steps count "
            f"every doStep of the run (rolled-back ones included) and of its companion, over all passes"
            f"{_step_ratio(d, acc['fixed'][0])}. "
            f"Wall times are the stepping loops; the set-up (string model, modes, the exact steps "
            f"of every step length the run may take) is {_setup(d)} for the default run and "
            f"{_setup(acc['fixed'][0])} for the fixed 1 ms run.\n")


def _orders_text(fixed: list) -> str:
    """The orders between consecutive fixed steps, where the error still falls; the floor where not."""
    parts = []
    for key, label in (("penetration_error_rel", "penetration"), ("wob_amplitude_error_rel", "WOB amplitude")):
        rows = sorted(fixed, key=lambda r: -r["step_s"])
        pairs = list(zip(rows, rows[1:]))
        falls = [r1[key] < r0[key] for r0, r1 in pairs]
        seg = []
        for i, (r0, r1) in enumerate(pairs):
            e0, e1 = r0[key], r1[key]
            h = f"{r0['step_s'] * 1e3:g} to {r1['step_s'] * 1e3:g} ms"
            if falls[i]:
                p = math.log(e0 / e1) / math.log(r0['step_s'] / r1['step_s'])
                # the next pair at the floor: this one's smaller error is already at it
                floor_next = i + 1 < len(pairs) and not falls[i + 1]
                seg.append(f"{h}: order {p:.1f}" + (" (the smaller error is already at the floor: not an "
                                                    "asymptotic order)" if floor_next else ""))
            else:
                seg.append(f"{h}: no decrease ({_e(e0)} to {_e(e1)}), the floor of the comparison")
        parts.append(f"{label} " + "; ".join(seg))
    return ("Measured orders, " + "; ".join(parts) + ". The floor is set by the runs and the reference "
            "slipping on different cycles near the threshold, not by the coupling error.")


def _then_now_text() -> str:
    path = os.path.join(TRACKED_RESULTS_DIR, "cosim_then.json")
    if not os.path.exists(path):
        return ""
    with open(path) as fh:
        tn = json.load(fh)
    return (f"; through the CLI (`python -m benchmarks --only cosim_then`), the default run's loop takes "
            f"{tn['ratio_now_default_to_now_fixed_loop']:.2f} times today's fixed 1 ms run (which records "
            f"every CLI output) and {tn['ratio_now_default_to_then_fixed_loop']:.2f} times the fixed 1 ms "
            f"run of the code before the estimate (commit {tn['then_commit']}: "
            f"{tn['then_fixed_1ms']['loop_s_median'] * 1e3:.0f} ms against "
            f"{tn['now_default']['loop_s_median'] * 1e3:.0f} ms; whole commands "
            f"{tn['then_fixed_1ms']['total_s_median']:.2f} s and {tn['now_default']['total_s_median']:.2f} s)")


def _step_ratio(d: dict, fixed: dict) -> str:
    return (f": {(d['hammer_steps'] + d['companion_steps']) / fixed['macro_steps']:.1f} times those of the "
            f"fixed 1 ms run, the measure that does not depend on the machine's load")


def _setup(row: dict) -> str:
    return f"{row['setup_time_s']:.2f} s"


def scheme_table(result: dict) -> str:
    """Markdown: errors at H = 1 ms and measured orders per scheme and extrapolation order."""
    err = result["errors"]
    lines = ["| scheme, order | WOB amplitude error at H = 1 ms | max WOB error at 1 ms | measured order |",
             "|---|---|---|---|"]
    for o in err["orders"]:
        at1 = [r for r in err["rows"] if r["scheme"] == o["scheme"] and r["extrapolation"] == o["extrapolation"]
               and abs(r["step_s"] - 1e-3) < 1e-12]
        a = f"{at1[0]['wob_amplitude_error_rel']:.1e}" if at1 else "—"
        m = f"{at1[0]['max_wob_error_rel']:.1e}" if at1 else "—"
        lines.append(f"| {o['scheme']}, {o['extrapolation']} | {a} | {m} | {o['measured_order']:.2f} |")
    ref = err["reference"]
    return ("\n".join(lines) + f"\n\nReference WOB amplitude {ref['wob_amplitude_n'] / 1e3:.1f} kN "
            f"({ref['stop_s']:g} s, amplitude over the second half).\n")


def cost_table(result: dict) -> str:
    """Markdown: the long run through the FMU against the FMI call floor."""
    lr = result["long_run"]
    floor = lr["floor_s"]
    lines = ["| run | wall | floor | ratio |", "|---|---|---|---|"]
    for key, label in (("nodal", "string, all nodal states"), ("modal_f_max_100hz", "string modes <= 100 Hz")):
        r = lr[key]
        lines.append(f"| {label} ({r['string_states']} states) | {r['wall_time_s']:.3f} s | {floor:.3f} s | "
                     f"{r['wall_time_s'] / floor:.2f}x |")
    lines.append(f"| HammerBitRock.fmu alone, no string | {lr['fmu_alone_s']:.3f} s | {floor:.3f} s | "
                 f"{lr['fmu_alone_s'] / floor:.2f}x |")
    n, m = lr["nodal"], lr["modal_f_max_100hz"]
    return ("\n".join(lines) + f"\n\nThe master's share per step: "
            f"{(n['wall_time_s'] - lr['fmu_alone_s']) / n['macro_steps'] * 1e6:.1f} µs (full string). "
            f"The truncation at 100 Hz moves the WOB amplitude of the run by "
            f"{100 * abs(m['wob_amplitude_n'] / n['wob_amplitude_n'] - 1):.2f} % "
            f"({m['wob_amplitude_n'] / 1e3:.2f} kN against {n['wob_amplitude_n'] / 1e3:.2f} kN).\n")


def _replace(text: str, tag: str, body: str) -> str:
    start, end = f"<!-- {tag}:start -->", f"<!-- {tag}:end -->"
    pat = re.compile(re.escape(start) + ".*?" + re.escape(end), re.S)
    if not pat.search(text):
        raise SystemExit(f"cosim_tables: {DOC} has no {start} ... {end} markers")
    return pat.sub(lambda m: f"{start}\n{body}{end}", text)


def update_docs(result: dict, path: str = DOC) -> None:
    with open(path) as fh:
        text = fh.read()
    text = _replace(text, "cosim-estimate-table", estimate_table(result))
    text = _replace(text, "cosim-accuracy-table", accuracy_table(result))
    text = _replace(text, "cosim-scheme-table", scheme_table(result))
    text = _replace(text, "cosim-cost-table", cost_table(result))
    with open(path, "w") as fh:
        fh.write(text)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    # the docs are tracked: their tables come from the tracked results (``--update`` runs)
    with open(os.path.join(TRACKED_RESULTS_DIR, "cosim.json")) as fh:
        result = json.load(fh)
    if "--print" in argv:
        print(estimate_table(result))
        print(accuracy_table(result))
        print(scheme_table(result))
        print(cost_table(result))
        return 0
    update_docs(result)
    print(f"wrote the co-simulation tables into {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
