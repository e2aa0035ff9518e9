"""The paper's figures (Figs. 9/10, 12/13, 14, 15) and two scene figures.

    python examples/paper_figures.py [--num 120] [--periods 300] [--workers N] [--out DIR]
    python examples/paper_figures.py --update      # into docs/figures/ (tracked)

Without ``--update`` or ``--out`` the figures go to a new scratch directory
(``hammerbit-figures-*`` in the system's temp dir), which the script prints;
nothing tracked changes unless asked.  It prints one line per figure, in SI.
"""
import argparse
import json
import pathlib
import tempfile
import time

import numpy as np

from hammerbit.studies.bifurcation import bifurcation, penetration_sweep
from hammerbit.studies.executor import ExecutorOptions
from hammerbit.model.presets import preset
from hammerbit.scene.plots import plot_bifurcation, plot_penetration, plot_scene

TRACKED = pathlib.Path(__file__).resolve().parent.parent / "docs" / "figures"


def main(argv=None):
    ap = argparse.ArgumentParser(description="The paper's figures (bifurcation diagrams, penetration, "
                                             "strange attractor, scenes).")
    ap.add_argument("--num", type=int, default=120, help="values of a per bifurcation diagram")
    ap.add_argument("--periods", type=int, default=300, help="forcing periods per value")
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: one per CPU)")
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--out", type=pathlib.Path, default=None,
                       help="output directory (default: a new scratch directory in the system's temp "
                            "dir, printed)")
    where.add_argument("--update", action="store_true", help=f"write into {TRACKED} (tracked files)")
    args = ap.parse_args(argv)
    if args.update:
        OUT = TRACKED
    elif args.out is not None:
        OUT = args.out
    else:
        OUT = pathlib.Path(tempfile.mkdtemp(prefix="hammerbit-figures-"))
    OUT.mkdir(parents=True, exist_ok=True)
    print(f"writing the figures into {OUT}", flush=True)
    summary = {}
    options = ExecutorOptions(workers=args.workers)
    for name, lo, hi in (("paper-fig9", 0.0, 0.25), ("paper-fig12", 0.0, 0.25)):
        t0 = time.perf_counter()
        res = bifurcation(preset(name), "a", np.linspace(lo, hi, args.num), periods=args.periods, keep=48,
                          options=options)
        path = plot_bifurcation(res, OUT / f"bifurcation_{name}.png", scales=preset(name).scales, preset=name)
        summary[name] = {"periods_per_second": res.periods_per_second, "wall_s": time.perf_counter() - t0,
                         "period_n": dict(zip([round(v, 4) for v in res.values.tolist()], res.periods))}
        found = sorted({n for n in res.periods if n})
        print(f"  {path.name}: {name}, bifurcation over a = {lo:g}..{hi:g} ({args.num} values x "
              f"{args.periods} periods, {summary[name]['wall_s']:.1f} s); periods found: "
              + (", ".join(f"P{n}" for n in found) or "no period found"), flush=True)
    a = np.linspace(0.0, 0.25, 51)     # the range of the paper's Fig. 14
    p9 = penetration_sweep(preset("paper-fig9"), a, periods=100, options=options)
    p12 = penetration_sweep(preset("paper-fig12"), a, periods=100, options=options)
    plot_penetration(a, {"no impact (paper-fig9)": p9, "impact r=0.84 (paper-fig12)": p12},
                     OUT / "penetration_fig14.png", periods=100, scales=preset("paper-fig9").scales)
    mm = preset("paper-fig9").scales.length * 1e3
    print(f"  penetration_fig14.png: penetration after 100 periods against a = {a[0]:g}..{a[-1]:g}; at "
          f"a = {a[-1]:g} "
          f"{p9[-1] * mm:.4g} mm without impact, {p12[-1] * mm:.4g} mm with impact", flush=True)
    plot_scene(preset("paper-fig9").replace(a=0.083), 300, OUT / "scene_fig9_a0.083.png", preset="paper-fig9")
    plot_scene(preset("paper-fig12").replace(a=0.06), 300, OUT / "scene_fig12_a0.06.png", preset="paper-fig12")
    print("  scene_fig9_a0.083.png, scene_fig12_a0.06.png: two scenes of 300 periods (mm against s)", flush=True)
    from hammerbit.scene.analysis import largest_lyapunov
    from hammerbit.scene.plots import plot_attractor
    from hammerbit.scene.simulate import Record, simulate
    g = preset("chaos")
    lam = largest_lyapunov(g, windows=100)
    r = simulate(g, 5000, record=Record(poincare=True))
    plot_attractor(r.poincare[200:], OUT / "chaos_fig15.png", scales=g.scales,
                   title=f"strange attractor: eta=0.8, b=0.3, r=0.84, mu=0.6, a=0.1967\n"
                         f"lambda_max = {lam['lambda_per_period']:.3f}/period")
    summary["chaos"] = {"lambda_per_period": lam["lambda_per_period"]}
    print(f"  chaos_fig15.png: the strange attractor of the preset chaos, largest Lyapunov exponent "
          f"{lam['lambda_per_period']:+.3f} per forcing period", flush=True)
    (OUT / "paper_figures.json").write_text(json.dumps(summary, indent=1))
    print(f"done: the figures and paper_figures.json (timings, period-n per value) are in {OUT}")


if __name__ == "__main__":
    main()
