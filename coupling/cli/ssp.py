"""``hammerbit ssp build`` and ``hammerbit cosim --ssp``: the drilling system as an SSP package.

``hammerbit ssp build --string FILE [--hammer FMU] [--out drilling.ssp] [--stop T] [--step H] [--wob W]``
writes ``drilling.ssp`` (both FMUs, their connections and parameter values, a
default experiment, libcosim's step annotation).  ``hammerbit cosim --ssp
drilling.ssp [--step H] [--stop T] [--tol TOL]`` runs it with the project's
master: adaptive with its error estimate by default; with ``--step`` the
fixed-step Jacobi run that libcosim and FMPy's SSP runner make.
"""
from __future__ import annotations

import math
import sys
import time
import warnings
from pathlib import Path

from hammerbit.cli.common import EXIT_INACCURATE, EXIT_OK, UsageError, add_set_argument, parse_settings, staged

__all__ = ["register", "cmd_ssp_build", "cosim_ssp", "check_positive", "SSP_EXCLUSIVE"]

#: ``hammerbit cosim`` options the system of an SSP package fixes (refused with ``--ssp``)
SSP_EXCLUSIVE = ("string", "fmu", "wob", "interface_stiffness", "interface_damping", "f_max", "set")
#: ``hammerbit cosim`` options that must keep their default with ``--ssp`` (the package fixes them)
SSP_DEFAULTS = {"ramp": 0.0, "harmonic_source": "fmu", "extrapolation": 2, "top_condition": "fixed"}


def check_positive(option: str, value, *, upper: float = math.inf, unit: str = "s") -> None:
    """``value`` is a finite number in (0, upper], else a UsageError naming ``option``."""
    if value is None:
        return
    if not (math.isfinite(value) and 0.0 < value <= upper):
        rng = f"(0, {upper:g}] {unit}" if math.isfinite(upper) else f"a finite number > 0 {unit}"
        raise UsageError(f"{option} = {value!r}: allowed {rng}")


def cmd_ssp_build(args) -> int:
    from hammerbit.cosim.hammer_fmu import check_fmu_file
    from hammerbit.drillstring import DrillStringError, load_string
    from hammerbit.ssp.package import SSPOptions, build_ssp
    check_positive("--stop", args.stop)
    check_positive("--step", args.step, upper=args.stop)
    if args.hammer is not None:
        try:
            check_fmu_file(args.hammer)
        except (OSError, ValueError) as e:
            raise UsageError(f"--hammer {args.hammer}: {e}") from None
    try:
        string = load_string(args.string)
    except DrillStringError:
        raise
    except (OSError, ValueError) as e:
        raise UsageError(f"--string {args.string}: {e}") from None
    weight = string.buoyed_weight
    if args.wob is not None and not (math.isfinite(args.wob) and 0.0 <= args.wob <= weight):
        raise UsageError(f"--wob = {args.wob!r} N: allowed [0, {weight:.6g}] N (the buoyed weight of "
                         f"{string.name!r})")
    rig = None
    settings = parse_settings(args.set)
    if settings:                          # as hammerbit cosim --set: changes of the field hammer
        from hammerbit.cosim.config import field_hammer
        from hammerbit.model.settings import apply_settings
        rig = apply_settings(field_hammer().to_groups(), settings).to_rig()
    from hammerbit.drillstring.top import TopCondition
    try:
        top = TopCondition.parse(args.top, where="--top")
    except ValueError as e:
        raise UsageError(str(e)) from None
    out = Path(args.out)
    if out.is_dir():
        out = out / "drilling.ssp"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            build_ssp(args.string, staged(out), SSPOptions(hammer=args.hammer, stop=args.stop, step=args.step,
                                                          wob=args.wob, rig=rig, top=top,
                                                          runtime=args.runtime))
        except ValueError as e:          # the string cannot carry the hammer's WOB, ...
            raise UsageError(f"--string {args.string}: {e}") from None
    for w in caught:
        print(f"hammerbit ssp build: warning: {w.message}", file=sys.stderr)
    print(out.resolve())
    return EXIT_OK


def _refuse_fixed_options(args) -> None:
    for name in SSP_EXCLUSIVE:
        value = getattr(args, name, None)
        if value not in (None, [], ()):
            opt = "--" + name.replace("_", "-")
            raise UsageError(f"{opt} = {value!r}: not allowed with --ssp (the package fixes the system; "
                             f"rebuild it with `hammerbit ssp build`)")
    for name, default in SSP_DEFAULTS.items():
        value = getattr(args, name, default)
        if value != default:
            opt = "--top" if name == "top_condition" else "--" + name.replace("_", "-")
            raise UsageError(f"{opt} = {value!r}: not allowed with --ssp (allowed only {default!r}; the "
                             f"package sets it: rebuild it with `hammerbit ssp build`)")


def _warn_capacity_before(ssp, overrides: dict) -> None:
    """The package's WOB set point against the rock's sliding capacity, before the run (unpacks it once more)."""
    from hammerbit.cosim.config import capacity_warning
    from hammerbit.ssp.run import load_ssp
    system = load_ssp(ssp, **overrides)
    try:
        msg = capacity_warning(system.config)
    finally:
        system.close()
    if msg:
        print(f"hammerbit cosim: warning: {msg}", file=sys.stderr)


def cosim_ssp(args) -> int:
    """``hammerbit cosim --ssp PACKAGE``: the master on the package's system."""
    from hammerbit.cosim.error import StepResolutionError
    from hammerbit.cosim.config import cosim_warnings
    from hammerbit.ssp.run import cosimulate_ssp, monolithic_ssp
    _refuse_fixed_options(args)
    if not Path(args.ssp).is_file():
        raise UsageError(f"--ssp {args.ssp}: no such file")
    check_positive("--stop", args.stop)
    check_positive("--tol", args.tol, upper=1.0, unit="(relative)")
    check_positive("--step", args.step, upper=args.stop if args.stop is not None else math.inf)
    from hammerbit.cli.cosim_report import recorded, write_and_report
    overrides = {"record": recorded(monolithic=args.monolithic, ssp=True),
                 "progress": None if not args.json else False, "tol": args.tol, "scheme": args.scheme}
    if args.stop is not None:
        overrides["stop"] = args.stop
    if args.step is not None:
        overrides["step"] = args.step
    overrides["adaptive"] = (args.step is None or args.adaptive) and not args.monolithic
    if getattr(args, "output_derivatives", False):
        overrides["output_derivatives"] = True
    t0 = time.perf_counter()
    try:
        _warn_capacity_before(args.ssp, overrides)
        if args.monolithic:
            res = monolithic_ssp(args.ssp, **overrides)
        else:
            res = cosimulate_ssp(args.ssp, **overrides)
    except StepResolutionError as e:
        raise UsageError(str(e)) from None
    except ValueError as e:
        raise UsageError(str(e)) from None
    out = res.summary()
    out["total_time_s"] = time.perf_counter() - t0
    out["ssp"] = str(args.ssp)
    for msg in cosim_warnings(out):
        print(f"hammerbit cosim: warning: {msg}", file=sys.stderr)
    est = res.estimate

    def print_text(out):
        c = out["counts"]
        print(f"{args.ssp}: {res.method}, {res.macro_steps} macro steps to t = {out['stop_s']:g} s")
        print(f"  penetration {out['penetration_m'] * 1e3:.6g} mm; WOB mean {out['wob_mean_n'] / 1e3:.5g} kN, "
              f"dynamic amplitude {out['wob_amplitude_n'] / 1e3:.5g} kN; slips {c.get('slips', 0)}")
        if est is not None:
            print(f"  {est.text()}")
        print(f"  wall time {out['wall_time_s']:.3f} s (+ set-up {out['setup_time_s']:.3f} s)")

    write_and_report(res, out, args, print_text)
    if est is not None and not est.meets_tolerance:
        print(f"hammerbit cosim: warning: the answer is not within the tolerance: {est.text()}",
              file=sys.stderr)
        return EXIT_INACCURATE
    return EXIT_OK


def register(sub) -> None:
    """Add ``ssp`` to the ``hammerbit`` command."""
    p = sub.add_parser("ssp", help="the drilling system as an SSP package (both FMUs, wired)")
    ssub = p.add_subparsers(dest="ssp_command", required=True)
    b = ssub.add_parser("build", help="build drilling.ssp (Drillstring.fmu + HammerBitRock.fmu, SSP 1.0)",
                        description="Build an SSP 1.0 package of the drilling system: the string FMU, the "
                                    "hammer FMU, their connections and parameter values, a default "
                                    "experiment and libcosim's fixed-step annotation.  Runs in libcosimpy "
                                    "(CosimExecution.from_ssp_file), FMPy (fmpy.ssp.simulate_ssp) and "
                                    "hammerbit cosim --ssp.")
    b.add_argument("--string", required=True, help="drillstring TOML file or example name (field-2200m, lab)")
    b.add_argument("--hammer", default=None, metavar="FMU",
                   help="a HammerBitRock.fmu to pack (default: built with the system's start values)")
    b.add_argument("--out", default="drilling.ssp", metavar="PATH", help="the package (default drilling.ssp)")
    b.add_argument("--stop", type=float, default=2.0, help="stop time of the default experiment [s] (default 2)")
    b.add_argument("--step", type=float, default=1e-3,
                   help="fixed communication step of the package [s] (default 1e-3)")
    b.add_argument("--wob", type=float, default=None,
                   help="weight on bit [N] (default: the hammer's preload, 55 kN for field strings)")
    b.add_argument("--top", default="fixed", metavar="CONDITION",
                   help="the string's top, the Drillstring FMU's start value: fixed (default), feed:RATE "
                        "(m/h, downward) or auto-driller[:kp=..,ki=..] (a PI controller on the hook load "
                        "holding the WOB; default gains from the string's stiffness)")
    b.add_argument("--runtime", choices=("pythonfmu", "native"), default="pythonfmu",
                   help="flavour of both FMUs: pythonfmu (default; the host needs Python, numpy, numba) "
                        "or native (compiled binaries for linux64 and win64, no Python on the target; the "
                        "string FMU carries the package's --step and its build's damping and gains)")
    add_set_argument(b)
    b.set_defaults(func=cmd_ssp_build)
