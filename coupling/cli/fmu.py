"""``hammerbit fmu build``: build HammerBitRock.fmu from the installed package."""
from __future__ import annotations

from hammerbit.cli.common import UsageError, add_set_argument, parse_settings

__all__ = ["register", "cmd_fmu_build"]


def cmd_fmu_build(args) -> int:
    from hammerbit.fmu.build import BuildOptions, UnknownVariableError, build_fmu
    try:
        start = parse_settings(args.set)
        opts = BuildOptions(start_values=start, portable_cache=not args.no_portable_cache,
                            native_front=not args.no_native_front, runtime=args.runtime)
        path = build_fmu(args.out, options=opts)
    except UnknownVariableError as e:
        raise UsageError(f"--set {e}") from None
    print(path)
    return 0


def register(sub) -> None:
    p = sub.add_parser("fmu", help="the HammerBitRock FMU (FMI 2.0 co-simulation)")
    fsub = p.add_subparsers(dest="fmu_command", required=True)
    b = fsub.add_parser("build", help="build HammerBitRock.fmu (needs a C compiler for its native front)",
                        description="Build HammerBitRock.fmu: the runtime of this install, its kernels "
                                    "compiled once for the portable CPU target, the native front library.")
    b.add_argument("--out", default=None, metavar="PATH",
                   help="the .fmu file to write, or a directory (default dist/HammerBitRock.fmu)")
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
