"""``hammerbit cosim``: the co-simulation from the command line (``sweep``: :mod:`hammerbit.cli.studies`).

``hammerbit cosim --string FILE [--fmu dist/HammerBitRock.fmu] --stop T [--step H | --tol TOL]
[--scheme jacobi|gauss-seidel] [--extrapolation 0|1|2] [--ramp S] [--top fixed|feed:RATE|auto-driller]
[--monolithic] [--json] [--out results.csv]``

``--string`` takes a TOML file or a built-in example name (``field-2200m``).
Without ``--fmu`` the hammer runs in process (the FMU's own kernels,
:class:`hammerbit.cosim.hammer_inprocess.StepperHammer`).  The hammer is the field hammer
(:func:`hammerbit.cosim.config.field_hammer`) unless ``--set`` changes it.

By default the macro step is adaptive (rollback through the FMU state) and
the run's coupling-error estimate is held against ``--tol`` (1e-3, relative
on the WOB amplitude and the penetration).  ``--step H`` gives a fixed step;
a run whose estimate exceeds the tolerance prints the estimate and exits
with code 5 (``EXIT_INACCURATE``).  A step that cannot resolve the forcing,
the slip dynamics or the string modes in the exchange is refused (code 2).

:func:`add_hammer_options` and :func:`config_from_args` are the one option
set and the one config builder of every command that needs the hammer on the
string (``cosim``, ``sweep``, ``modes --hammer-on-bottom``).
"""
from __future__ import annotations

import sys
import time

from hammerbit.cli.common import (EXIT_INACCURATE, EXIT_OK, UsageError, add_set_argument, interrupt_or_exit,
                                  parse_settings)
from hammerbit.cli.cosim_report import recorded, write_and_report
from hammerbit.cli.options import refuse_unless

__all__ = ["register", "cmd_cosim", "add_hammer_options", "add_cosim_options", "config_from_args", "top_from_args",
           "load_string_arg", "fmu_arg"]

def add_hammer_options(p) -> None:
    """The hammer, interface and ``--set`` options (``cosim``, ``sweep``, ``modes --hammer-on-bottom``)."""
    p.add_argument("--wob", type=float, default=None, help="weight on bit of the static equilibrium [N] "
                                                            "(default: the hammer's preload, 55 kN)")
    p.add_argument("--interface-stiffness", type=float, default=None, help="k_i [N/m] (default 2e6)")
    p.add_argument("--interface-damping", type=float, default=None, help="c_i [N s/m] (default 2e3)")
    add_set_argument(p)


def add_cosim_options(p, *, string_required: bool = True) -> None:
    """``--string``, ``--fmu``, the exchange options and :func:`add_hammer_options`."""
    p.add_argument("--string", required=string_required,
                   help="drillstring TOML file or example name (field-2200m)")
    p.add_argument("--fmu", default=None, help="HammerBitRock.fmu (default: the same model in process)")
    p.add_argument("--step", type=float, default=None,
                   help="fixed macro step H [s] (default: adaptive, see --tol)")
    p.add_argument("--scheme", default="jacobi", choices=["jacobi", "gauss-seidel"],
                   help="coupling scheme: jacobi (both sides step from the data at t_n) or gauss-seidel "
                        "(the hammer steps first, the string interpolates its new motion)")
    p.add_argument("--extrapolation", type=int, default=2, choices=[0, 1, 2],
                   help="polynomial order of the exchanged signals (default 2)")
    p.add_argument("--f-max", type=float, default=None, help="modal truncation of the string [Hz] (default: none, every nodal degree of freedom)")
    p.add_argument("--ramp", type=float, default=0.0, metavar="SECONDS",
                   help="raise the harmonic force linearly from 0 over SECONDS (default 0: full at once)")
    p.add_argument("--harmonic-source", default="fmu", choices=["fmu", "master"],
                   help="harmonic force from the FMU's internal source (default) or computed by the "
                        "master and fed to the FMU's harmonic_force input (step mean, zero-order hold)")
    p.add_argument("--top", dest="top_condition", default="fixed", metavar="CONDITION",
                   help="how the hook moves: fixed (default), feed:RATE (the block lowered at RATE m/h) or "
                        "auto-driller[:kp=KP,ki=KI] (a PI controller on the hook load that holds the WOB "
                        "of --wob; gains in m/s per N and m/s per N s, default tuned from the string's "
                        "stiffness)")
    add_hammer_options(p)


def top_from_args(args):
    """The :class:`~hammerbit.drillstring.top.TopCondition` of ``--top`` (errors exit 2)."""
    from hammerbit.drillstring.top import TopCondition
    text = getattr(args, "top_condition", None)
    if text is None:
        return TopCondition.fixed()
    try:
        return TopCondition.parse(text, where="--top")
    except ValueError as e:
        raise UsageError(str(e)) from None


def rig_from_args(args, string=None):
    """The string's default hammer (:func:`~hammerbit.cosim.config.default_hammer`: the field hammer,
    or the paper's rig on a string too light for it; the field hammer without a string) with
    ``--set`` applied (groups, SI symbols, RigParameters/FMU names)."""
    from hammerbit.cli.preflight import apply_user_settings
    from hammerbit.cosim.config import default_hammer, field_hammer
    rig = field_hammer() if string is None else default_hammer(string)
    settings = parse_settings(getattr(args, "set", None))
    if settings:
        rig = apply_user_settings(rig.to_groups(), settings).to_rig()
    return rig


def config_from_args(args, **extra):
    """The one :class:`~hammerbit.cosim.config.CosimConfig` builder of the CLI.

    Bad values raise :class:`~hammerbit.model.validation.ParameterError` or
    :class:`~hammerbit.cli.common.UsageError` (exit code 2)."""
    from hammerbit.model.validation import ParameterError
    from hammerbit.cosim.config import CosimConfig
    string = load_string_arg(args) if getattr(args, "string", None) else None
    rig = rig_from_args(args, string)
    kw = {"rig": rig, "wob": getattr(args, "wob", None), "top": top_from_args(args)}
    for name in ("scheme", "extrapolation", "f_max", "harmonic_source", "ramp"):
        if getattr(args, name, None) is not None:
            kw[name] = getattr(args, name)
    step = getattr(args, "step", None)
    if step is not None:
        kw["step"] = step
    if getattr(args, "interface_stiffness", None) is not None:
        kw["interface_stiffness"] = args.interface_stiffness
    if getattr(args, "interface_damping", None) is not None:
        kw["interface_damping"] = args.interface_damping
    kw.update(extra)
    try:
        cfg = CosimConfig(**kw)
    except ParameterError:
        raise
    except (ValueError, TypeError) as e:
        raise UsageError(str(e)) from None
    if string is not None:
        _check_wob(string, cfg, given=getattr(args, "wob", None) is not None)
    return cfg


def _check_wob(string, cfg, *, given: bool) -> None:
    """The WOB must hang from the string: 0 < WOB <= its buoyed weight (exit 2 otherwise)."""
    from hammerbit.drillstring.statics import static_equilibrium
    weight = static_equilibrium(string).buoyed_weight
    W = cfg.weight_on_bit
    if not 0.0 < W <= weight:
        what = f"--wob {W:g}" if given else f"the hammer's preload (WOB) {W:g} N"
        raise UsageError(f"{what}: allowed range 0 < WOB <= the buoyed weight of {string.name}, {weight:.6g} N "
                         f"(give --wob, or --set preload=...)")


def load_string_arg(args):
    """The drillstring of ``--string`` (errors exit 2)."""
    from hammerbit.drillstring import DrillStringError, load_string
    try:
        return load_string(args.string)
    except DrillStringError:
        raise
    except (FileNotFoundError, OSError, ValueError) as e:
        raise UsageError(f"--string {args.string}: {e}") from None


def portable_target_for_fmu(args) -> None:
    """With ``--fmu``: this process's numba runs the FMU's portable CPU target.

    The FMU then loads the kernels it ships instead of compiling its own copy
    in this process (:mod:`hammerbit.model.numba_target`); the master's own
    kernels compile once for that target into the user cache.  Called before
    anything imports numba; without ``--fmu`` (or with ``--monolithic``) it
    does nothing.
    """
    if getattr(args, "fmu", None) is not None and not getattr(args, "monolithic", False):
        from hammerbit.model.numba_target import select_portable
        select_portable()


def fmu_arg(args):
    """The ``--fmu`` path after a check that it is an FMU (errors exit 2), or None."""
    if args.fmu is None:
        return None
    from hammerbit.cosim.hammer_fmu import check_fmu_file
    try:
        check_fmu_file(args.fmu)
    except (OSError, ValueError) as e:
        raise UsageError(f"--fmu {args.fmu}: {e}") from None
    return args.fmu


# names kept for callers of the old private helpers
_common = add_cosim_options
_config = config_from_args
_string = load_string_arg
_fmu = fmu_arg


def _print_text(out: dict, res, cfg, string) -> None:
    if res.method == "monolithic":
        head = f"{string.name}: monolithic reference (rtol {cfg.rtol:g})"
    elif cfg.adaptive:
        st = res.stats
        head = (f"{string.name}: {res.macro_steps} adaptive macro steps of {st['h_min_used'] * 1e3:.4g}"
                f"..{st['h_max_used'] * 1e3:.4g} ms ({st['rejected']} rolled back; {cfg.scheme}, "
                f"extrapolation order {cfg.extrapolation}, hammer {out['hammer']})")
    else:
        head = (f"{string.name}: {res.macro_steps} macro steps of {cfg.step * 1e3:g} ms ({cfg.scheme}, "
                f"extrapolation order {cfg.extrapolation}, hammer {out['hammer']})")
    print(head)
    print(f"  to t = {out['stop_s']:g} s; WOB mean {out['wob_mean_n'] / 1e3:.4g} kN, dynamic amplitude "
          f"{out['wob_amplitude_n'] / 1e3:.4g} kN (fundamental, from t = {out['steady_window_start_s']:g} s); "
          f"max {out['wob_max_n'] / 1e3:.4g} kN, min {out['wob_min_n'] / 1e3:.4g} kN")
    c = out["counts"]
    print(f"  penetration {out['penetration_m'] * 1e3:.5g} mm; slips {c.get('slips', 0)}, impacts "
          f"{c.get('impacts', 0)}, bounce violations {c.get('bounce_violations', 0)}")
    if res.estimate is not None:
        print(f"  {res.estimate.text()}")
    if "hammer_steps" in out:
        print(f"  hammer doSteps {out['hammer_steps']} (+ companion {out['companion_steps']}), "
              f"{out['state_saves']} state saves, {out['rollbacks']} rolled back"
              + (f", {out['passes']} pass(es)" if cfg.adaptive else ""))
    print(f"  wall time {out['wall_time_s']:.3f} s (+ set-up {out['setup_time_s']:.3f} s)")
    if out.get("csv"):
        print(f"  wrote {out['csv']}")


def warn_capacity(cfg) -> None:
    """Before the run: a held WOB the rock cannot carry, on stderr (:func:`hammerbit.cosim.config.capacity_warning`)."""
    from hammerbit.cosim.config import capacity_warning
    msg = capacity_warning(cfg)
    if msg:
        print(f"hammerbit cosim: warning: {msg}", file=sys.stderr)


def warn_regime(out: dict) -> None:
    """After the run: the flags of the regime verdict on stderr (they are in the JSON too)."""
    from hammerbit.cosim.config import cosim_warnings
    for msg in cosim_warnings(out):
        print(f"hammerbit cosim: warning: {msg}", file=sys.stderr)


#: ``cosim`` options the monolithic reference has no use for (it couples nothing and estimates nothing).
NOT_FOR_MONOLITHIC = ("scheme", "extrapolation", "harmonic_source", "tol", "adaptive", "fmu")


def refuse_idle_options(args) -> None:
    """``cosim`` options given where they change nothing (exit 2, before any work)."""
    for dest in NOT_FOR_MONOLITHIC:
        refuse_unless(args, dest, not args.monolithic,
                      "--monolithic runs the reference (string, interface and hammer as one system, in "
                      "process): it has no coupling scheme, extrapolation, harmonic source, macro-step "
                      "control or FMU, and no coupling-error estimate to hold against --tol")
    refuse_unless(args, "output_derivatives",
                  args.ssp is not None and args.step is not None and not args.adaptive and not args.monolithic
                  and args.scheme == "jacobi",
                  "the hammer's output derivatives feed the string in the fixed-step Jacobi run of an SSP "
                  "package: allowed only with --ssp and --step (no --adaptive, --monolithic or "
                  "--scheme gauss-seidel)")
    refuse_unless(args, "adaptive", args.step is not None,
                  "without --step the macro step is adaptive already; --adaptive makes --step the first "
                  "step of an adaptive run")


def cmd_cosim(args) -> int:
    refuse_idle_options(args)
    if args.ssp is not None:
        from hammerbit.cli.ssp import cosim_ssp
        return cosim_ssp(args)
    for name in ("string", "stop"):
        if getattr(args, name) is None:
            raise UsageError(f"--{name} is required (or --ssp PACKAGE)")
    portable_target_for_fmu(args)
    from hammerbit.cosim.master import cosimulate
    from hammerbit.cosim.reference import monolithic
    from hammerbit.cosim.error import SAFETY_FACTOR, StepResolutionError
    adaptive = args.step is None or args.adaptive
    extra = {"stop": args.stop,
             "record": recorded(monolithic=args.monolithic),
             "progress": None if not args.json else False, "adaptive": adaptive and not args.monolithic,
             "tol": args.tol}
    if args.monolithic and args.step is None:
        extra["step"] = 1e-3                        # the sampling interval of the reference
    cfg = config_from_args(args, **extra)
    string = load_string_arg(args)
    fmu = fmu_arg(args)
    warn_capacity(cfg)
    t0 = time.perf_counter()
    try:
        if args.monolithic:
            if fmu is not None:
                raise UsageError("--monolithic runs the reference in process; it takes no --fmu")
            res = monolithic(string, cfg)
        else:
            with interrupt_or_exit():           # the FMU's host may swallow the Ctrl-C
                res = cosimulate(string, cfg, fmu=fmu)
    except StepResolutionError as e:
        raise UsageError(str(e)) from None
    total = time.perf_counter() - t0
    out = res.summary()
    out["total_time_s"] = total
    out["hammer"] = "fmu" if fmu else "in-process"
    if cfg.adaptive:
        out["adaptive"] = {k: v for k, v in res.stats.items()
                           if k in ("accepted", "rejected", "at_min_step", "defect_tol", "passes",
                                    "h_min_used", "h_max_used")}
    out["string"] = string.name
    out["wob_static_n"] = cfg.weight_on_bit
    out["tol"] = cfg.tol
    write_and_report(res, out, args, lambda o: _print_text(o, res, cfg, string))
    est = res.estimate
    if out["top"].get("retuned"):
        print(f"hammerbit cosim: note: {out['top']['retune_note']}", file=sys.stderr)
    warn_regime(out)
    bounce = out["bounce"]["violations"]
    if bounce:
        print(f"hammerbit cosim: warning: {bounce} bounce violation(s): the rock would have to pull the bit "
              f"back (lowest WOB {out['wob_min_n']:.4g} N, mean {out['wob_mean_n']:.4g} N); the model "
              f"leaves its range of validity", file=sys.stderr)
    if est is not None and not est.claimed:
        print(f"hammerbit cosim: warning: {est.text()}", file=sys.stderr)
        return EXIT_INACCURATE
    if est is not None and not est.meets_tolerance:
        how = ("a smaller --step, or the adaptive step (omit --step)" if not cfg.adaptive else
               "a tighter --tol or a smaller first --step")
        print(f"hammerbit cosim: warning: the answer is not shown to be within the tolerance (the estimate "
              f"must be within tol / {SAFETY_FACTOR:g}, its margin): {est.text()}; use {how}", file=sys.stderr)
        return EXIT_INACCURATE
    return EXIT_OK


def register(subparsers) -> None:
    """Add ``cosim`` to the ``hammerbit`` command."""
    p = subparsers.add_parser("cosim", help="co-simulate the drillstring with the hammer FMU",
                              description="Co-simulation: the drillstring stepped exactly by the master, "
                                          "the hammer as an FMU, from static equilibrium; every run "
                                          "estimates its own coupling error (exit code 5 when above --tol).")
    add_cosim_options(p, string_required=False)
    p.add_argument("--stop", type=float, default=None,
                   help="simulated time [s] (required; with --ssp default the package's stop time)")
    p.add_argument("--ssp", default=None, metavar="PACKAGE",
                   help="run the system of an SSP package from `hammerbit ssp build` (drilling.ssp): "
                        "its FMUs and parameter values; --step H gives the fixed-step Jacobi run of "
                        "libcosim and FMPy, without it the adaptive step and the error estimate")
    p.add_argument("--tol", type=float, default=1e-3,
                   help="relative tolerance of the coupling error on the WOB amplitude and the "
                        "penetration (default 1e-3); drives the adaptive step, checked for --step")
    p.add_argument("--adaptive", action="store_true",
                   help="adaptive macro step even with --step (then the first step); the default "
                        "without --step")
    p.add_argument("--monolithic", action="store_true",
                   help="run the monolithic reference (string, interface and hammer as one hybrid "
                        "system) instead; samples every --step (default 1 ms); its --out has no hook_load "
                        "column (the reference does not compute the hook load)")
    p.add_argument("--output-derivatives", action="store_true",
                   help="with --ssp and --step: the hammer FMU's output derivatives (orders 1 and 2 of its "
                        "position and velocity) are the string's input derivatives, so the string takes the "
                        "hammer motion over a step as their polynomial instead of extrapolating it (needs "
                        "the native flavour: `hammerbit ssp build --runtime native`)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--out", default=None, help="CSV of the recorded variables")
    p.set_defaults(func=cmd_cosim)


