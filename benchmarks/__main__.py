"""``python -m benchmarks``: run every benchmark, write results, print or refresh the README table.

Every module ``benchmarks/bench_*.py`` that exposes ``run(quick)`` is a
benchmark (conventions in :mod:`benchmarks`).  They run one after the other in
this process; each writes ``<name>.json`` (+ ``.png``) into the results
directory.  Nothing tracked is written unless asked:

* by default the results go to a scratch directory (``$HAMMERBIT_BENCH_OUT``
  or ``hammerbit-benchmarks`` in the system's temp dir), figures that the
  documentation shows too, and the performance table -- the tracked results
  with this run's results in place of the ones that ran -- is printed;
* ``--update`` writes ``benchmarks/results/`` and ``docs/figures/`` and
  regenerates the README's performance table (between
  ``<!-- perf-table:start -->`` and ``<!-- perf-table:end -->``), unless
  ``--no-readme``.

Options
-------
--quick        short runs (development, CI)
--only NAME    run only this benchmark (``solvers`` or ``bench_solvers``);
               repeat or comma-separate for several
--list         list the benchmarks found and exit
--update       write the tracked results, figures and README table
--no-readme    with --update: do not touch the README (print the table)

The exit status is 1 if a benchmark failed (the others still run).
"""
from __future__ import annotations

import argparse
import glob
import importlib
import os
import sys
import time
import traceback

import benchmarks
from benchmarks import BENCH_DIR, harness_command, machine_info, result_name, save_result
from benchmarks import readme_table


def discover() -> dict:
    """``{name: module_name}`` of every ``bench_*.py`` in the benchmarks folder, sorted."""
    out = {}
    for path in sorted(glob.glob(os.path.join(BENCH_DIR, "bench_*.py"))):
        mod = os.path.splitext(os.path.basename(path))[0]
        out[result_name(mod)] = f"benchmarks.{mod}"
    return out


def _select(found: dict, only) -> dict:
    if not only:
        return found
    wanted = []
    for item in only:
        wanted += [w.strip() for w in item.split(",") if w.strip()]
    sel = {}
    for w in wanted:
        key = result_name(w[:-3] if w.endswith(".py") else w)
        if key not in found:
            raise SystemExit(f"benchmarks: no benchmark {w!r}; found: {', '.join(found) or 'none'}")
        sel[key] = found[key]
    return sel


def run_one(name: str, modname: str, quick: bool) -> tuple:
    """Import and run one benchmark; make sure its JSON exists. Returns (ok, seconds, message)."""
    t0 = time.perf_counter()
    started = time.time()
    try:
        mod = importlib.import_module(modname)
    except Exception:
        return False, 0.0, "import failed:\n" + traceback.format_exc()
    run = getattr(mod, "run", None)
    if not callable(run):
        return None, 0.0, "no run(quick) function: skipped"
    try:
        result = run(quick=quick)
    except Exception:
        return False, time.perf_counter() - t0, "run failed:\n" + traceback.format_exc()
    dt = time.perf_counter() - t0
    path = os.path.join(benchmarks.results_dir(), f"{name}.json")
    fresh = os.path.exists(path) and os.path.getmtime(path) >= started - 1.0
    if isinstance(result, dict) and not fresh:
        # the module returned its result without saving it: fill the conventions and save
        result.setdefault("benchmark", name)
        result.setdefault("quick", quick)
        result.setdefault("command", harness_command(name, quick))
        result.setdefault("machine", machine_info())
        result.setdefault("summary", [])
        save_result(name, result)
    elif not fresh:
        return False, dt, f"run() returned {type(result).__name__} and wrote no {path}"
    msg = ""
    if isinstance(result, dict) and not result.get("summary"):
        msg = "warning: no summary rows"
    return True, dt, msg


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short runs")
    ap.add_argument("--only", action="append", metavar="NAME", help="run only these benchmarks")
    ap.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    ap.add_argument("--update", action="store_true",
                    help="write benchmarks/results, docs/figures and the README table (tracked files); "
                         "default: write into the scratch dir and print the table")
    ap.add_argument("--no-readme", action="store_true", help="with --update: print the table instead of "
                                                               "updating README.md")
    a = ap.parse_args(argv)

    found = discover()
    if a.list:
        for k, v in found.items():
            print(f"{k:20s} {v}")
        return 0
    selected = _select(found, a.only)
    out_dir = benchmarks.configure_output(a.update)
    os.makedirs(out_dir, exist_ok=True)
    print(f"benchmarks: results into {out_dir}" + ("" if a.update else " (scratch; --update writes the "
                                                   "tracked results)"), file=sys.stderr)
    failures, ran = [], []
    t_all = time.perf_counter()
    for name, modname in selected.items():
        print(f"benchmarks: {name} ({'quick' if a.quick else 'full'}) ...", file=sys.stderr, flush=True)
        ok, dt, msg = run_one(name, modname, a.quick)
        status = {True: "ok", False: "FAILED", None: "skipped"}[ok]
        print(f"benchmarks: {name}: {status} in {dt:.1f} s" + (f" — {msg}" if msg else ""),
              file=sys.stderr, flush=True)
        if ok is False:
            failures.append(name)
        elif ok:
            ran.append(name)
    print(f"benchmarks: done in {time.perf_counter() - t_all:.1f} s", file=sys.stderr)

    # with --update, out_dir is the tracked directory: its fresh results replace the rows of what ran
    results = readme_table.merge_results(readme_table.load_results(benchmarks.TRACKED_RESULTS_DIR),
                                         readme_table.load_results(out_dir), ran)
    table = readme_table.render_table(results)
    if not a.update or a.no_readme or not readme_table.update_readme(table):
        if a.update and not a.no_readme:
            print(f"benchmarks: README.md has no {readme_table.START} ... {readme_table.END} markers; "
                  f"the table:", file=sys.stderr)
        print(table)
    else:
        print("benchmarks: README.md performance table updated", file=sys.stderr)
    if failures:
        print(f"benchmarks: FAILED: {', '.join(failures)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
