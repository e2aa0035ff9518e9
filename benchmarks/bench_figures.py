"""Regenerate every figure the README shows, and time it.

``python -m benchmarks --only figures`` runs:

* ``examples/paper_figures.py`` -- Figs. 9/10 and 12/13 (bifurcation), 14
  (penetration), 15 (strange attractor) and two scene figures;
* ``docs/make_string_figures.py`` -- the drillstring check figures;
* the co-simulation frequency sweeps of ``docs/cosim.md`` (``hammerbit sweep``).

The summary rows list each figure with the time it took.  The figures land
in ``docs/figures/`` with ``python -m benchmarks --update``, otherwise in the
scratch directory (:func:`benchmarks.figures_dir`).
"""
from __future__ import annotations

import importlib.util
import pathlib
import time

import benchmarks
from benchmarks import REPO_ROOT, harness_command, save_result, summary_row

ROOT = pathlib.Path(REPO_ROOT)


def _load(path: pathlib.Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run(quick: bool = False) -> dict:
    from hammerbit.cli.main import main as cli
    cmd = harness_command("figures", quick)
    rows, timings = [], {}
    FIG = pathlib.Path(benchmarks.figures_dir())

    t0 = time.perf_counter()
    _load(ROOT / "examples" / "paper_figures.py").main(["--num", "40" if quick else "120", "--out", str(FIG)])
    timings["paper"] = time.perf_counter() - t0
    rows.append(summary_row("paper figures (Figs. 9/10, 12/13, 14, 15, scenes): "
                            "examples/paper_figures.py", f"{timings['paper']:.1f} s", command=cmd))

    t0 = time.perf_counter()
    _load(ROOT / "docs" / "make_string_figures.py").main(["--out", str(FIG)])
    timings["string"] = time.perf_counter() - t0
    rows.append(summary_row("drillstring check figures: docs/make_string_figures.py",
                            f"{timings['string']:.1f} s", command=cmd))

    sweeps = [
        ["sweep", "--string", "field-2200m", "--frequencies", "10", "30", "21" if quick else "41",
         "--plot", str(FIG / "cosim_sweep.png"), "--csv", str(FIG / "cosim_sweep.csv")],
        ["sweep", "--string", "field-2200m", "--frequencies", "5", "35", "31" if quick else "61",
         "--set", "amplitude=2000", "--plot", str(FIG / "cosim_sweep_linear.png"),
         "--csv", str(FIG / "cosim_sweep_linear.csv")],
    ]
    t0 = time.perf_counter()
    for argv in sweeps:
        if cli(argv) != 0:
            raise RuntimeError(f"hammerbit {' '.join(argv)} failed")
    timings["sweeps"] = time.perf_counter() - t0
    rows.append(summary_row("co-simulation frequency sweeps (docs/cosim.md): hammerbit sweep x 2",
                            f"{timings['sweeps']:.1f} s", command=cmd))
    result = {"benchmark": "figures", "quick": quick, "command": cmd, "timings_s": timings,
              "figures": sorted(p.name for p in FIG.glob("*.png")), "summary": rows}
    save_result("figures", result)
    return result


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
