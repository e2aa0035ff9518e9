"""The derivation of the paper-figure calibration: the (xi, mu) band where Figs. 9 and 12 both reproduce.

    python docs/make_calibration.py                       # coarse grid, 300/500/1000 periods
    python docs/make_calibration.py --periods 300 --xi 0.068:0.074:25 --mu 0.77:0.83:25

For every cell of a grid over the damping ratio ``xi`` and the kinetic
friction ratio ``mu`` it runs the regime map (:func:`hammerbit.studies.map.regime_map`,
one worker by default) at the paper's four amplitudes of each figure, and
keeps the cells where

* Fig. 9 (no gap) gives P5, P3, P2, P1 at a = 0.069, 0.083, 0.11, 0.2, and
* Fig. 12 (r = 0.84) gives P4, P3, P2, P1 at a = 0.044, 0.05, 0.06, 0.11,

at every horizon asked for.  It prints that band, where the presets'
calibration lies in it, the sequences of the identified model (xi = 0.074,
mu = 0.85) for contrast, and what +/- 1 % in the gap r does to Fig. 12.
docs/model.md ("The paper-figure calibration") quotes its output.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from hammerbit.model.presets import preset
from hammerbit.model.validation import ParameterError
from hammerbit.scene.analysis import detect_period
from hammerbit.scene.simulate import Record, simulate
from hammerbit.studies.executor import ExecutorOptions
from hammerbit.studies.map import Axis, regime_map

#: The paper's period sequences: (a, period-n) of Figs. 9/10 and 12/13.
FIG9 = ((0.069, 5), (0.083, 3), (0.11, 2), (0.2, 1))
FIG12 = ((0.044, 4), (0.05, 3), (0.06, 2), (0.11, 1))
#: The model before this calibration: the rig's damping ratio and the earlier mu = 0.85.
UNCALIBRATED = {"xi": 0.074, "mu": 0.85}
#: Relative change of the gap r tried for robustness (Fig. 12 is narrow in r).
R_STEPS = (-0.01, -0.005, 0.005, 0.01)


def _axis(name: str, text: str) -> Axis:
    return Axis.parse(f"{name}={text}")


def figure_hits(base, sequence, xi: Axis, mu: Axis, periods: int, workers: int) -> np.ndarray:
    """Boolean (xi, mu) array: True where every amplitude of ``sequence`` gives its period."""
    amplitudes = Axis("a", tuple(a for a, _ in sequence))
    ds = regime_map(base, [xi, mu, amplitudes], periods=periods,
                    options=ExecutorOptions(workers=workers, progress=False))
    want = np.array([n for _, n in sequence], dtype=float)
    return np.all(np.nan_to_num(ds["period"].values) == want, axis=-1)


def sequence_of(groups, sequence, periods: int) -> list:
    """Period-n at each amplitude of ``sequence`` (None: no period up to 32)."""
    return [detect_period(simulate(groups.replace(a=a), periods, record=Record(poincare=True)).poincare)
            for a, _ in sequence]


def _surroundings(band, xi: Axis, mu: Axis, point: dict) -> str:
    """Whether the grid cells that enclose ``point`` are all in the band."""
    xs, ms = np.asarray(xi.values), np.asarray(mu.values)
    if not (xs[0] <= point["xi"] <= xs[-1] and ms[0] <= point["mu"] <= ms[-1]):
        return "outside the grid"
    i = slice(max(0, np.searchsorted(xs, point["xi"], "right") - 1), np.searchsorted(xs, point["xi"], "left") + 1)
    j = slice(max(0, np.searchsorted(ms, point["mu"], "right") - 1), np.searchsorted(ms, point["mu"], "left") + 1)
    inside = band[i, j]
    return f"{int(inside.sum())} of the {inside.size} grid cells around it in the band"


def _label(periods) -> str:
    return "/".join("-" if n is None else f"P{n}" for n in periods)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--xi", default="0.066:0.076:11", help="xi axis LO:HI:N (default 0.066:0.076:11)")
    ap.add_argument("--mu", default="0.76:0.84:17", help="mu axis LO:HI:N (default 0.76:0.84:17)")
    ap.add_argument("--periods", type=int, nargs="+", default=[300, 500, 1000],
                    help="horizons from rest [forcing periods] (default 300 500 1000)")
    ap.add_argument("--workers", type=int, default=1, help="map workers (default 1)")
    args = ap.parse_args(argv)
    try:
        xi, mu = _axis("xi", args.xi), _axis("mu", args.mu)
    except ParameterError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    fig9, fig12 = preset("paper-fig9"), preset("paper-fig12")
    band = np.ones((len(xi.values), len(mu.values)), dtype=bool)
    for periods in args.periods:
        for base, seq in ((fig9, FIG9), (fig12, FIG12)):
            band &= figure_hits(base, seq, xi, mu, periods, args.workers)
    horizons = ", ".join(map(str, args.periods))
    print(f"Band: cells where Fig. 9 gives {_label([n for _, n in FIG9])} at a = "
          f"{', '.join(str(a) for a, _ in FIG9)} (no gap) and Fig. 12 gives {_label([n for _, n in FIG12])} "
          f"at a = {', '.join(str(a) for a, _ in FIG12)} (r = {fig12.r:g}), after {horizons} periods from rest")
    print("  xi       mu in the band")
    for i, x in enumerate(xi.values):
        inside = [m for m, ok in zip(mu.values, band[i]) if ok]
        print(f"  {x:.4f}   " + (f"{min(inside):.4f} .. {max(inside):.4f} ({len(inside)} of {len(mu.values)})"
                                  if inside else "-"))
    print(f"  {int(band.sum())} of {band.size} cells")
    cal = {"xi": fig12.xi, "mu": fig12.mu}
    print(f"\nThe presets' calibration: xi = {cal['xi']:g} ({cal['xi'] / UNCALIBRATED['xi'] - 1:+.1%}), "
          f"mu = {cal['mu']:g} ({cal['mu'] / UNCALIBRATED['mu'] - 1:+.1%}); " + _surroundings(band, xi, mu, cal))
    old9, old12 = fig9.replace(**UNCALIBRATED), fig12.replace(**UNCALIBRATED)
    for periods in args.periods:
        print(f"  {periods:5d} periods: Fig. 9 {_label(sequence_of(fig9, FIG9, periods))}, "
              f"Fig. 12 {_label(sequence_of(fig12, FIG12, periods))}; "
              f"uncalibrated (xi = {UNCALIBRATED['xi']}, mu = {UNCALIBRATED['mu']}): "
              f"Fig. 9 {_label(sequence_of(old9, FIG9, periods))}, "
              f"Fig. 12 {_label(sequence_of(old12, FIG12, periods))}")
    print(f"\nFig. 12 with the gap changed (paper: r = {fig12.r:g}):")
    for step in R_STEPS:
        g = fig12.replace(r=fig12.r * (1 + step))
        print(f"  r = {g.r:.4f} ({step:+.1%}): " + ", ".join(
            f"{periods} periods {_label(sequence_of(g, FIG12, periods))}" for periods in args.periods))
    return 0


if __name__ == "__main__":
    sys.exit(main())
