"""The co-simulation tables of ``docs/cosim.md``, regenerated from ``benchmarks/results/cosim.json``.

Writes, between markers in ``docs/cosim.md``::

    <!-- cosim-estimate-table:start -->   estimate vs true error (stuck, drilling; H)
    <!-- cosim-estimate-table:end -->
    <!-- cosim-accuracy-table:start -->   drilling case: fixed H = 1, 0.5, 0.25 ms, orders, default run
    <!-- cosim-accuracy-table:end -->

Usage: ``python -m benchmarks.cosim_tables`` (rewrites docs/cosim.md), ``--print`` to only print.
"""
from __future__ import annotations

import json
import os
import re
import sys

from benchmarks import REPO_ROOT, RESULTS_DIR

__all__ = ["estimate_table", "accuracy_table", "update_docs", "main"]

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
    lines = ["| run | WOB amplitude error | penetration error | wall time [s] |", "|---|---|---|---|"]
    for r in acc["fixed"]:
        lines.append(f"| fixed H = {r['step_s'] * 1e3:g} ms (no estimate) | {_e(r['wob_amplitude_error_rel'])} | "
                     f"{_e(r['penetration_error_rel'])} | {r['wall_time_s']:.3f} |")
    d = acc["default"]
    lines.append(f"| default: adaptive, tol {d['tol']:g} ({d['macro_steps']} steps of "
                 f"{d['h_min_used_s'] * 1e3:g}..{d['h_max_used_s'] * 1e3:g} ms, {d['rejected']} rolled back, "
                 f"{d['passes']} pass(es), with the estimate) | {_e(d['wob_amplitude_error_rel'])} | "
                 f"{_e(d['penetration_error_rel'])} | {d['wall_time_s']:.3f} |")
    o = acc["orders"]
    return ("\n".join(lines) + f"\n\nMeasured orders over H = 1, 0.5, 0.25 ms: WOB amplitude "
            f"{o['wob_amplitude_error_rel']:.2f}, penetration {o['penetration_error_rel']:.2f}.\n")


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
    with open(path, "w") as fh:
        fh.write(text)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    with open(os.path.join(RESULTS_DIR, "cosim.json")) as fh:
        result = json.load(fh)
    if "--print" in argv:
        print(estimate_table(result))
        print(accuracy_table(result))
        return 0
    update_docs(result)
    print(f"wrote the co-simulation tables into {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
