"""The ``hammerbit`` command line (also ``python -m hammerbit``).

Subcommands: ``simulate`` (this module) and those that the modules in
:data:`COMMAND_MODULES` register (drillstring, co-simulation, studies, FMU).
Every command shares the ``--set`` parser, the exit codes and the error
handling of :mod:`hammerbit.cli.common`; ``docs/cli.md`` documents them.
"""
from __future__ import annotations

import argparse
import gc
import importlib
import json
import math
import sys
import warnings

import numpy as np

from hammerbit.cli.common import (EXIT_INTERRUPTED, UsageError, add_set_argument, check_output, interruptible,
                                  output_errors, parse_settings, run_command)
from hammerbit.cli.preflight import apply_user_settings, in_user_words, preflight

__all__ = ["main", "console", "build_parser", "COMMAND_MODULES", "HelpFormatter", "version"]

#: Modules that add sub-commands through ``register(subparsers)``; a module
#: that is not installed is skipped.
COMMAND_MODULES = [
    "hammerbit.cli.string",
    "hammerbit.cli.cosim",
    "hammerbit.cli.studies",
    "hammerbit.cli.fmu",
    "hammerbit.cli.ssp",
    "hammerbit.cli.continuation",
]

#: Most samples ``simulate --csv`` writes (about 1 GB of text).
MAX_CSV_SAMPLES = 10_000_000


def version() -> str:
    """The installed hammerbit version ("unknown" when run from a source tree without metadata)."""
    try:
        from importlib.metadata import PackageNotFoundError, version as _v
        try:
            return _v("hammerbit")
        except PackageNotFoundError:
            return "unknown"
    except ImportError:  # pragma: no cover
        return "unknown"


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows each option's default, unless it is None/False/empty or the help already gives it."""

    def _get_help_string(self, action):
        text = action.help or ""
        if "default" in text.lower() or action.default in (None, False, argparse.SUPPRESS) \
                or action.default == []:
            return text
        if action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE):
            return (text + " " if text else "") + "(default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose sub-commands show defaults in their help."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)


def _parse_settings(pairs):
    """Kept for the sub-command modules: the one parser of ``--set`` (:mod:`hammerbit.cli.common`)."""
    return parse_settings(pairs)


def _groups_from_args(args):
    from hammerbit.model.presets import preset
    return apply_user_settings(preset(args.preset), _parse_settings(args.set))


def _solver_from_args(args):
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.model.validation import ParameterError
    kw = {"method": args.method}
    if args.rtol is not None:
        kw["rtol"] = args.rtol
        kw["atol"] = args.rtol * 1e-2
    if getattr(args, "steps_per_period", None) is not None:
        kw["steps_per_period"] = args.steps_per_period
    try:
        return SolverOptions(**kw)
    except ParameterError as e:
        raise e.renamed("--" + e.name.replace("_", "-")) from None


def _add_scene_args(p):
    from hammerbit.model.presets import PRESETS
    p.add_argument("--preset", default="paper-fig9", choices=sorted(PRESETS),
                   help="parameter preset (docs/model.md, 'Presets')")
    add_set_argument(p)
    p.add_argument("--method", default="adaptive", choices=["adaptive", "dp54", "rk4"],
                   help="integration method: adaptive (DOP853), dp54 (Dormand-Prince 5(4)) or rk4 "
                        "(the paper's fixed step)")
    p.add_argument("--rtol", type=float, default=None, metavar="RTOL",
                   help="relative tolerance of adaptive and dp54 (default 1e-8; atol = rtol/100)")
    p.add_argument("--steps-per-period", type=int, default=None, metavar="N",
                   help="rk4: steps per forcing period (default 1000)")


def regime_warnings(g, flags) -> list:
    """Plain-language warnings from a scene's own flags and the paper's domain (SI figures).

    ``flags`` is the run's :class:`hammerbit.scene.flags.SceneFlags`.
    """
    from hammerbit.model.regime import STALL_PERIODS

    F0 = g.scales.friction_force
    out = []
    if flags.runaway:
        how = (f"from period {flags.certified_at} on it provably cannot stick again" if flags.certified_at is not None
               else "it has not stuck since and its drift keeps accelerating")
        out.append(f"runaway: {how} (preload {g.b * F0:.4g} N above the kinetic friction at high speed "
                   f"{g.mu * F0:.4g} N); the penetration is not a rate of penetration")
    if flags.bounce:
        out.append(f"bounce: the drive on the bit fell below -F_s = {-F0:.4g} N while the bit was stuck, "
                   f"{flags.bounces} time(s): the rock would have to pull the bit back; the model held it")
    if flags.tension:
        out.append(f"tension: the drive on the bit fell below zero (lowest {flags.min_drive * F0:.4g} N)")
    if flags.stall:
        out.append(f"stall: the bit has not slipped for the last {STALL_PERIODS} forcing periods or more, "
                   f"with the preload {g.b * F0:.4g} N held: it no longer drills")
    if flags.transient:
        more = (f"; the last quarter repeats period-{flags.settling_period} from period {flags.settled_after}"
                if flags.settling_period and flags.settled_after is not None else "")
        out.append(f"transient: the period-n has not settled within the horizon{more}")
    if not flags.domain["inside"]:
        out.append("outside the paper's domain (" + ", ".join(flags.domain["outside"]) + ")")
    return out


def _finite_or_none(v):
    return None if isinstance(v, float) and not math.isfinite(v) else v


def cmd_simulate(args) -> int:
    from hammerbit.scene.figure_worker import start as start_figure_worker

    # the figure's process imports matplotlib while this one loads the solver
    worker = start_figure_worker() if args.plot else None
    try:
        return _simulate(args, worker)
    finally:
        if worker is not None:
            worker.close()


def _simulate(args, worker) -> int:
    from hammerbit.model.stepping import Stepper
    from hammerbit.model.validation import check

    from hammerbit.scene.analysis import detect_period
    from hammerbit.model.regime_codes import regime_json
    from hammerbit.scene.simulate import BounceWarning, Record, simulate, write_samples_csv

    g = _groups_from_args(args)
    solver = _solver_from_args(args)
    check("simulate.periods", args.periods, label="--periods")
    # every output path is checked before the run, so a typo does not cost the run (the directory
    # and writability by the preflight; the figure format here, from the worker's matplotlib)
    if args.plot:
        if worker is not None:  # load the kernels while the worker imports matplotlib
            Stepper(g, solver=solver).load()
        formats = worker.formats() if worker is not None else None
        if formats is None:
            from hammerbit.scene.figure_worker import figure_formats
            formats = figure_formats()
        check_output(args.plot, "--plot", formats=formats)
    times = None
    if args.sample_dt is not None and not args.csv:
        raise UsageError("--sample-dt sets the spacing of the --csv samples: give --csv FILE too")
    if args.csv:
        dt = g.period_s / 100.0 if args.sample_dt is None else \
            check("simulate.sample_dt", args.sample_dt, label="--sample-dt")
        horizon_s = args.periods * g.period_s
        n = int(math.floor(horizon_s / dt * (1 + 1e-12))) + 1
        if n > MAX_CSV_SAMPLES:
            raise UsageError(f"--sample-dt {dt:g}: {n:,} samples over {horizon_s:.4g} s; at most "
                             f"{MAX_CSV_SAMPLES:,}: use a larger --sample-dt or fewer --periods")
        times = np.minimum(np.arange(n) * (dt / g.scales.time), args.periods * g.period)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", BounceWarning)
        # in a thread: a Ctrl-C interrupts a long run at once (the kernel releases the GIL)
        res = interruptible(simulate, g, args.periods,
                            record=Record(poincare=True, events=g.has_gap, times=times), solver=solver)
    for w in caught:
        if not issubclass(w.category, BounceWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    period = detect_period(res.poincare) if res.poincare is not None and len(res.poincare) > 8 else None
    reg = res.flags
    rop = res.rop()
    peak = res.peak_contact_force_n() if g.has_gap else None
    per_period = res.penetration / args.periods
    out = {
        "preset": args.preset,
        "groups": {k: _finite_or_none(v) for k, v in g.values().items()},
        "scales": g.scales.to_dict(),
        "periods": args.periods,
        "time_s": res.time_s,
        "forcing_period_s": g.period_s,
        "preload_n": g.b * g.scales.friction_force,
        "amplitude_n": g.a * g.scales.friction_force,
        "frequency_hz": 1.0 / g.period_s,
        "method": solver.method,
        "rtol": solver.rtol,
        "penetration_x0": res.penetration,
        "penetration_m": res.penetration_m,
        "penetration_mm": res.penetration_m * 1e3,
        "penetration_per_period_x0": per_period,
        "penetration_per_period_mm": g.length_m(per_period) * 1e3,
        "rop": rop,
        "period": period,
        **(regime_json(reg.code) if reg else {"regime": None, "regime_names": None}),
        "scene_flags": reg.to_dict(g.scales.friction_force) if reg else None,
        "flags": reg.flags if reg else None,
        "paper_domain": reg.domain if reg else None,
        "events": res.counts,
        "peak_contact_force_n": peak,
        "steps": res.stats,
        "wall_time_s": res.wall_time_s,
        "csv": args.csv,
        "plot": args.plot,
    }
    for msg in regime_warnings(g, reg) if reg else []:
        print(f"hammerbit: warning: {msg}", file=sys.stderr)
    if args.csv:
        with output_errors("--csv", args.csv):
            write_samples_csv(res, args.csv)
    if args.json:
        print(json.dumps(out))
    else:
        sc = g.scales
        print(f"preset {args.preset}: a={g.a:g} b={g.b:g} eta={g.eta:g} r={g.r:g} mu={g.mu:g}")
        print(f"rig: x0 = {sc.length * 1e3:.4g} mm, forcing {1.0 / g.period_s:.4g} Hz "
              f"(period {g.period_s:.4g} s), preload {out['preload_n']:.4g} N, "
              f"amplitude {out['amplitude_n']:.4g} N")
        print(f"penetration after {args.periods} periods ({res.time_s:.4g} s): "
              f"{out['penetration_mm']:.4g} mm")
        if rop is not None:
            print(f"rate of penetration (second half): {rop['mm_per_period']:.4g} mm/period = "
                  f"{rop['m_per_h']:.4g} m/h")
        print(f"period-n of the bounded motion: {period if period else 'no period found (up to 32)'}")
        print("events: " + (", ".join(f"{k}={v}" for k, v in res.counts.items() if v) or "none"))
        if peak is not None:
            print(f"peak contact force: {peak:.4g} N")
        print(f"solver: {solver.method}, {res.stats['steps']} steps, {res.wall_time_s * 1e3:.3g} ms")
        if reg:
            print(f"regime: {reg.code}" + (" (" + ", ".join(reg.flags) + ")" if reg.flags else " (drilling)"))
        if reg and reg.flags:
            print("flags: " + ", ".join(reg.flags) + (" (not a drilling point; see stderr)" if reg.unusable
                                                       else " (see stderr)"))
        if reg and not reg.domain["inside"]:
            print("outside the paper's domain: " + ", ".join(reg.domain["outside"]))
        if args.csv:
            print(f"time series: {args.csv}")
    if args.plot:
        from hammerbit.scene.plots import scene_figure
        from hammerbit.scene.figure import draw_scene
        data = scene_figure(g, args.periods, solver=solver, preset=args.preset, period=period)
        if worker is None or not worker.draw(draw_scene, data, args.plot) or worker.result() is None:
            draw_scene(data, args.plot)
        if not args.json:
            print(f"figure: {args.plot}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The ``hammerbit`` parser with every registered sub-command."""
    ap = _Parser(prog="hammerbit", description="Resonance-hammer drilling model "
                 "(Franca & Weber 2004): simulation, FMU co-simulation, drillstring checks. "
                 "Exit codes: docs/cli.md.")
    ap.add_argument("--version", action="version", version=f"hammerbit {version()}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("simulate", help="simulate one scene and report it in SI",
                       description="Simulate one scene from rest and report penetration [mm], rate of "
                                   "penetration [mm/period, m/h], forces [N] and times [s]; the JSON "
                                   "adds the nondimensional values (named *_x0).")
    _add_scene_args(p)
    p.add_argument("--periods", type=int, default=100, metavar="N", help="horizon in forcing periods")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--plot", default=None, metavar="FILE",
                   help="save the scene figure (positions [mm] against time [s], relative motion, "
                        "Poincaré section); the format follows the extension (png, pdf, svg, ...)")
    p.add_argument("--csv", default=None, metavar="FILE",
                   help="write the time series in SI (time first, header with units)")
    p.add_argument("--sample-dt", type=float, default=None, metavar="SECONDS",
                   help="spacing of the --csv samples [s] (default: 1/100 of the forcing period)")
    p.set_defaults(func=cmd_simulate)

    for modname in COMMAND_MODULES:
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:
            if e.name != modname:
                raise
            continue
        mod.register(sub)
    return ap


def main(argv=None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    return run_command(args.func, args, before=preflight, rephrase=in_user_words)


def console(argv=None) -> None:
    """The ``hammerbit`` executable: :func:`main`, then exit with its code.

    Before exiting, the objects alive are moved out of the garbage
    collector's reach (:func:`gc.freeze`): the interpreter's shutdown then
    does not walk numba's and matplotlib's object graphs, a large share of a
    short command's exit.  Everything else of the shutdown runs as usual
    (exit handlers, files flushed and closed).
    """
    try:
        code = main(argv)
    except KeyboardInterrupt:       # before or after the command ran (imports, argument parsing)
        print("hammerbit: interrupted", file=sys.stderr)
        code = EXIT_INTERRUPTED
    gc.freeze()
    sys.exit(code)


if __name__ == "__main__":
    console()
