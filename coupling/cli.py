"""The ``hammerbit`` command line.

Subcommands: ``simulate`` (this module); ``modes`` and ``check``
(drillstring, :mod:`hammerbit.cli_string`); ``cosim`` (co-simulation,
:mod:`hammerbit.cli_cosim`); ``bifurcation``, ``sweep``, ``map`` and
``optimize`` (studies, :mod:`hammerbit.cli_studies`).
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import sys

import numpy as np

from .cli_common import add_set_argument, parse_settings, run_command

__all__ = ["main"]


def _parse_settings(pairs):
    """Kept for the sub-command modules: the one parser of ``--set`` (:mod:`hammerbit.cli_common`)."""
    return parse_settings(pairs)


def _groups_from_args(args):
    from hammerbit.model.params import apply_settings, preset
    return apply_settings(preset(args.preset), _parse_settings(args.set))


def _solver_from_args(args):
    from hammerbit.model.stepping import SolverOptions
    kw = {"method": args.method}
    if args.rtol is not None:
        kw["rtol"] = args.rtol
        kw["atol"] = args.rtol * 1e-2
    if getattr(args, "steps_per_period", None):
        kw["steps_per_period"] = args.steps_per_period
    return SolverOptions(**kw)


def _add_scene_args(p):
    from hammerbit.model.params import PRESETS
    p.add_argument("--preset", default="paper-fig9", choices=sorted(PRESETS),
                   help="parameter preset (default paper-fig9)")
    add_set_argument(p)
    p.add_argument("--method", default="adaptive", choices=["adaptive", "dp54", "rk4"])
    p.add_argument("--rtol", type=float, default=None, help="relative tolerance (adaptive; default 1e-8)")
    p.add_argument("--steps-per-period", type=int, default=None, help="rk4: steps per forcing period (1000)")


def cmd_simulate(args) -> int:
    from .analysis import detect_period
    from .simulate import Record, simulate
    g = _groups_from_args(args)
    solver = _solver_from_args(args)
    res = simulate(g, args.periods, record=Record(poincare=True, events=False), solver=solver)
    period = detect_period(res.poincare) if res.poincare is not None and len(res.poincare) > 8 else None
    out = {
        "preset": args.preset,
        "groups": {k: (None if isinstance(v, float) and math.isinf(v) else v) for k, v in g.values().items()},
        "scales": g.scales.to_dict(),
        "periods": args.periods,
        "method": solver.method,
        "rtol": solver.rtol,
        "penetration": res.penetration,
        "penetration_m": res.penetration_m,
        "penetration_per_period": res.penetration / args.periods,
        "period": period,
        "events": res.counts,
        "steps": res.stats,
        "wall_time_s": res.wall_time_s,
    }
    if args.json:
        print(json.dumps(out))
    else:
        print(f"preset {args.preset}: a={g.a:g} b={g.b:g} eta={g.eta:g} r={g.r:g} mu={g.mu:g}")
        print(f"penetration after {args.periods} periods: {res.penetration:.6g} x0 = "
              f"{out['penetration_m'] * 1e3:.4g} mm")
        print(f"period-n of the bounded motion: {period if period else 'none up to 32'}")
        print("events: " + ", ".join(f"{k}={v}" for k, v in res.counts.items() if v))
        print(f"solver: {solver.method}, {res.stats['steps']} steps, {res.wall_time_s * 1e3:.2f} ms")
    if args.plot:
        from .plots import plot_scene
        plot_scene(g, args.periods, args.plot, solver=solver)
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="hammerbit", description="Resonance-hammer drilling model "
                                 "(Franca & Weber 2004): simulation, FMU co-simulation, drillstring checks")
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("simulate", help="simulate one scene")
    _add_scene_args(p)
    p.add_argument("--periods", type=int, default=100, help="forcing periods (default 100)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", default=None, help="save a figure (time history, phase portrait, Poincaré map)")
    p.set_defaults(func=cmd_simulate)

    for modname in ("hammerbit.cli_string", "hammerbit.cli_cosim", "hammerbit.cli_studies", "hammerbit.cli_fmu"):
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:
            if e.name != modname:
                raise
            continue
        mod.register(sub)
    return ap


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    return run_command(args.func, args)


if __name__ == "__main__":
    sys.exit(main())
