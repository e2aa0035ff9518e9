"""``hammerbit fmu build``: build HammerBitRock.fmu from the installed package."""
from __future__ import annotations

import math
import sys
import time

from hammerbit.cli.common import UsageError, add_set_argument, parse_settings, staged

__all__ = ["register", "cmd_fmu_build", "cmd_fmu_build_string", "cmd_fmu_build_system"]


def cmd_fmu_build(args) -> int:
    from hammerbit.cli.options import refuse_unless
    for dest in ("no_portable_cache", "no_native_front"):
        refuse_unless(args, dest, args.runtime == "pythonfmu", "an option of --runtime pythonfmu: the native "
                                                               "runtime ships compiled binaries and no Python front")
    from hammerbit.fmu.build import MODEL_NAME, BuildOptions, UnknownVariableError, build_fmu, default_output
    if args.fmi_version == 3 and args.runtime != "native":
        raise UsageError("--fmi-version 3 is an option of --runtime native")
    try:
        start = parse_settings(args.set)
        opts = BuildOptions(start_values=start, portable_cache=not args.no_portable_cache,
                            native_front=not args.no_native_front, runtime=args.runtime,
                            fmi_version=args.fmi_version)
        # the build compiles the kernels and the native front: tens of seconds with nothing to show
        work = [w for w, on in (("compiling the kernels for the portable CPU target", opts.portable_cache),
                                ("building the native front", opts.native_front)) if on]
        print(f"hammerbit fmu build: building HammerBitRock.fmu ({args.runtime} runtime)"
              + (f" ({', '.join(work)}; about a minute)" if work else "") + " ...",
              file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        path = _fmu_file(args.out, default_output(), MODEL_NAME)
        build_fmu(staged(path), options=opts)
    except UnknownVariableError as e:
        raise UsageError(f"--set {e}") from None
    print(f"hammerbit fmu build: done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    print(path)
    return 0


def _fmu_file(out, default, model_name: str):
    """The absolute ``.fmu`` file of ``--out``: the file itself, or ``model_name.fmu`` in a directory."""
    from pathlib import Path
    out = Path(out) if out is not None else Path(default)
    if out.suffix != ".fmu":
        out = out / f"{model_name}.fmu"
    out = out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


def cmd_fmu_build_string(args) -> int:
    from hammerbit.drillstring import DrillStringError
    from hammerbit.drillstring.top import TopCondition
    from hammerbit.fmu.build_string import build_string_fmu, string_fmu_path
    try:
        top = TopCondition.parse(args.top, where="--top")
    except ValueError as e:
        raise UsageError(str(e)) from None
    steps = args.step or None
    for h in steps or ():
        if not (0.0 < h < math.inf):
            raise UsageError(f"--step {h!r} is out of range: allowed a finite step size > 0 s")
    if steps and args.runtime != "native":
        raise UsageError("--step is an option of --runtime native (the pythonfmu flavour takes any step)")
    if args.fmi_version == 3 and args.runtime != "native":
        raise UsageError("--fmi-version 3 is an option of --runtime native")
    try:
        path = string_fmu_path(args.out)
        if args.runtime == "native":
            from hammerbit.fmu.native_string import build_native_string_fmu
            print("hammerbit fmu build-string: building Drillstring.fmu (native runtime; compiling the "
                  "string's kernels) ...", file=sys.stderr, flush=True)
            build_native_string_fmu(args.string, staged(path), top=top, steps=steps,
                                           fmi_version=args.fmi_version,
                                           log=lambda m: print(m, file=sys.stderr))
        else:
            build_string_fmu(args.string, staged(path), top=top)
    except DrillStringError:
        raise
    except (OSError, ValueError) as e:
        raise UsageError(f"--string {args.string}: {e}") from None
    print(path)
    return 0


def add_build_string(fsub) -> None:
    """``hammerbit fmu build-string``: the Drillstring FMU of a string."""
    b = fsub.add_parser("build-string", help="build Drillstring.fmu of a drillstring (pythonfmu or native)",
                        description="Build Drillstring.fmu: the string of a TOML file and its hammer "
                                    "interface, stepped exactly over any communication step (inputs: "
                                    "hammer position and velocity; outputs: the interface force, the "
                                    "force to hold, the hook load).")
    b.add_argument("--string", required=True, help="drillstring TOML file or example name (field-2200m, lab)")
    b.add_argument("--out", default=None, metavar="PATH",
                   help="the .fmu file to write, or a directory (default dist/Drillstring.fmu)")
    b.add_argument("--top", default="fixed", metavar="CONDITION",
                   help="start value of the top condition (a parameter of the FMU): fixed (default), "
                        "feed:RATE (m/h, downward) or auto-driller[:kp=..,ki=..]")
    b.add_argument("--runtime", choices=("pythonfmu", "native"), default="pythonfmu",
                   help="pythonfmu (default): the string runs in Python in the host, any step size, all "
                        "parameters tunable; native: the binaries (linux64, and win64 with "
                        "x86_64-w64-mingw32-gcc) hold the compiled step and need no Python; they take any "
                        "step size (those of --step with the build's exponentials) and carry the build's "
                        "damping ratio and auto-driller gains")
    b.add_argument("--step", type=float, action="append", default=None, metavar="SECONDS",
                   help="--runtime native: a communication step size [s] whose exponentials the FMU carries "
                        "(repeatable; default 0.001, the default experiment's; any other step gets "
                        "its own at its first use)")
    b.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="2 (default): FMI 2.0; 3: FMI 3.0 (--runtime native)")
    b.set_defaults(func=cmd_fmu_build_string)


def cmd_fmu_build_system(args) -> int:
    from hammerbit.cli.cosim import config_from_args, load_string_arg
    from hammerbit.fmu.build_system import build_system_fmu
    from hammerbit.model.fmu_description import SYSTEM_VARIABLES
    tol = next(v for v in SYSTEM_VARIABLES if v.name == "tolerance")
    if not (tol.min <= args.tolerance <= tol.max):
        raise UsageError(f"--tolerance {args.tolerance!r} is out of range: allowed [{tol.min:g}, {tol.max:g}]")
    string = load_string_arg(args)
    cfg = config_from_args(args)
    print("hammerbit fmu build-system: building DrillingSystem.fmu (native runtime; compiling the "
          "solver's kernels) ...", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    path = build_system_fmu(string, cfg, args.out, tolerance=args.tolerance, fmi_version=args.fmi_version,
                            log=lambda m: print(m, file=sys.stderr))
    print(f"hammerbit fmu build-system: done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    print(path)
    return 0


def add_build_system(fsub) -> None:
    """``hammerbit fmu build-system``: hammer, bit, string and top condition in one FMU."""
    from hammerbit.cli.cosim import add_hammer_options
    b = fsub.add_parser("build-system", help="build DrillingSystem.fmu: hammer, bit, string and top condition "
                                             "integrated as one system (native)",
                        description="Build DrillingSystem.fmu (FMI 2.0 or 3.0 co-simulation, native binaries): the "
                                    "hammer-bit-rock model, the string and its top condition integrated as one "
                                    "hybrid system by the library's adaptive event-located solver; the master's "
                                    "step is only where it reads and writes.")
    b.add_argument("--string", required=True, help="drillstring TOML file or example name (field-2200m, lab)")
    b.add_argument("--top", dest="top_condition", default="fixed", metavar="CONDITION",
                   help="fixed (default), feed:RATE (m/h, downward) or auto-driller[:kp=KP,ki=KI]")
    b.add_argument("--f-max", type=float, default=None,
                   help="modal truncation of the string [Hz] (default: none, every nodal degree of freedom)")
    b.add_argument("--tolerance", type=float, default=1e-3,
                   help="start value of the FMU's tolerance parameter (default 1e-3)")
    b.add_argument("--out", default=None, metavar="PATH",
                   help="the .fmu file to write, or a directory (default dist/DrillingSystem.fmu)")
    b.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="2 (default): FMI 2.0; 3: FMI 3.0 Co-Simulation (binaries x86_64-linux, "
                        "x86_64-windows and aarch64-linux; no early return or Event Mode: the solver's "
                        "events stay inside the step)")
    add_hammer_options(b)
    b.set_defaults(func=cmd_fmu_build_system)


def register(sub) -> None:
    p = sub.add_parser("fmu", help="the HammerBitRock FMU (FMI 2.0 co-simulation)")
    fsub = p.add_subparsers(dest="fmu_command", required=True)
    b = fsub.add_parser("build", help="build HammerBitRock.fmu (needs a C compiler for its native front)",
                        description="Build HammerBitRock.fmu: the runtime of this install, its kernels "
                                    "compiled once for the portable CPU target, the native front library.")
    b.add_argument("--out", default=None, metavar="PATH",
                   help="the .fmu file to write (ending in .fmu), or an existing directory to write "
                        "HammerBitRock.fmu into (default dist/HammerBitRock.fmu)")
    b.set_defaults(func=cmd_fmu_build)
    add_set_argument(b)
    b._actions[-1].help = ("start value of an FMU parameter or input, NAME=VALUE with the FMU variable "
                           "name and SI units (repeatable), e.g. --set hammer_mass=30 --set preload=35")
    b.add_argument("--no-portable-cache", action="store_true",
                   help="do not ship compiled kernels (the FMU compiles them on first use)")
    b.add_argument("--no-native-front", action="store_true",
                   help="keep pythonfmu's binary only (runs only in a Python host)")
    b.add_argument("--runtime", choices=("pythonfmu", "native"), default="pythonfmu",
                   help="pythonfmu (default): the model runs in Python in the host; native: the "
                        "binaries (linux64, and win64 with x86_64-w64-mingw32-gcc) hold the compiled "
                        "kernels and need no Python")
    b.add_argument("--fmi-version", type=int, choices=(2, 3), default=2,
                   help="2 (default): FMI 2.0; 3: FMI 3.0 (--runtime native; binaries x86_64-linux, "
                        "x86_64-windows and aarch64-linux; Co-Simulation with early return at events and Event "
                        "Mode, Model Exchange)")
    add_build_string(fsub)
    add_build_system(fsub)
