"""``hammerbit fmu build``: build HammerBitRock.fmu from the installed package."""
from __future__ import annotations

import sys
import time

from hammerbit.cli.common import UsageError, add_set_argument, parse_settings

__all__ = ["register", "cmd_fmu_build"]


def cmd_fmu_build(args) -> int:
    from hammerbit.fmu.build import BuildOptions, UnknownVariableError, build_fmu
    try:
        start = parse_settings(args.set)
        opts = BuildOptions(start_values=start, portable_cache=not args.no_portable_cache,
                            native_front=not args.no_native_front)
        # the build compiles the kernels and the native front: tens of seconds with nothing to show
        work = [w for w, on in (("compiling the kernels for the portable CPU target", opts.portable_cache),
                                ("building the native front", opts.native_front)) if on]
        print("hammerbit fmu build: building HammerBitRock.fmu" + (f" ({', '.join(work)}; about a minute)"
                                                                    if work else "") + " ...",
              file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        path = build_fmu(args.out, options=opts)
    except UnknownVariableError as e:
        raise UsageError(f"--set {e}") from None
    print(f"hammerbit fmu build: done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    print(path)
    return 0


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
