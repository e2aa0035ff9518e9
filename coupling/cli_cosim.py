"""``hammerbit cosim``: the co-simulation from the command line (``sweep``: :mod:`hammerbit.cli_studies`).

``hammerbit cosim --string FILE --fmu dist/HammerBitRock.fmu --stop T --step H
[--scheme jacobi|gauss-seidel] [--extrapolation 0|1|2] [--json] [--out results.csv]``

``--string`` takes a TOML file or a built-in example name (``field-2200m``).
Without ``--fmu`` the hammer runs in process (the FMU's own kernels,
:class:`hammerbit.cosim.StepperHammer`).  The hammer is the field hammer
(:func:`hammerbit.cosim.field_hammer`) unless ``--set`` changes it.
"""
from __future__ import annotations

import json
import sys
import time

__all__ = ["register", "cmd_cosim"]


def _common(p):
    p.add_argument("--string", required=True, help="drillstring TOML file or example name (field-2200m)")
    p.add_argument("--fmu", default=None, help="HammerBitRock.fmu (default: the same model in process)")
    p.add_argument("--step", type=float, default=1e-3, help="macro step H [s] (default 1e-3)")
    p.add_argument("--scheme", default="jacobi", choices=["jacobi", "gauss-seidel"])
    p.add_argument("--extrapolation", type=int, default=2, choices=[0, 1, 2],
                   help="polynomial order of the exchanged signals (default 2)")
    p.add_argument("--wob", type=float, default=None, help="weight on bit of the static equilibrium [N] "
                                                            "(default: the hammer's preload, 55 kN)")
    p.add_argument("--interface-stiffness", type=float, default=None, help="k_i [N/m] (default 2e6)")
    p.add_argument("--interface-damping", type=float, default=None, help="c_i [N s/m] (default 2e3)")
    p.add_argument("--f-max", type=float, default=None, help="modal truncation of the string [Hz]")
    p.add_argument("--harmonic-source", default="fmu", choices=["fmu", "master"],
                   help="harmonic force from the FMU's internal source (default) or computed by the "
                        "master and fed to the FMU's harmonic_force input (step mean, zero-order hold)")
    p.add_argument("--set", action="append", metavar="FIELD=VALUE",
                   help="change a field of the hammer's RigParameters (SI), e.g. amplitude=5000")


def _config(args, **extra):
    from .cosim import CosimConfig, field_hammer
    from .cli import _parse_settings
    rig = field_hammer()
    changes = _parse_settings(args.set)
    if changes:
        try:
            rig = rig.replace(**changes)
        except TypeError as e:
            raise SystemExit(f"hammerbit: --set: {e}") from None
    kw = dict(step=args.step, scheme=args.scheme, extrapolation=args.extrapolation, rig=rig,
              wob=args.wob, f_max=args.f_max, harmonic_source=getattr(args, "harmonic_source", "fmu"))
    if args.interface_stiffness is not None:
        kw["interface_stiffness"] = args.interface_stiffness
    if args.interface_damping is not None:
        kw["interface_damping"] = args.interface_damping
    kw.update(extra)
    try:
        return CosimConfig(**kw)
    except ValueError as e:
        raise SystemExit(f"hammerbit: {e}") from None


def _string(args):
    from .drillstring import DrillStringError, load_string
    try:
        return load_string(args.string)
    except (DrillStringError, FileNotFoundError, OSError, ValueError) as e:
        raise SystemExit(f"hammerbit: --string {args.string}: {e}") from None


def _fmu(args):
    if args.fmu is None:
        return None
    from pathlib import Path
    if not Path(args.fmu).is_file():
        raise SystemExit(f"hammerbit: --fmu {args.fmu}: no such file (build it with python build_fmu.py)")
    return args.fmu


def cmd_cosim(args) -> int:
    from .cosim import CouplingInstabilityError, cosimulate, cosimulate_adaptive
    cfg = _config(args, stop=args.stop, record=("wob", "interface_force", "hammer_position",
                                                "hammer_velocity", "bit_position", "bit_velocity",
                                                "hook_load"),
                  progress=None if not args.json else False)
    string = _string(args)
    t0 = time.perf_counter()
    try:
        if args.adaptive:
            res = cosimulate_adaptive(string, cfg, fmu=_fmu(args), tol=args.tol)
        else:
            res = cosimulate(string, cfg, fmu=_fmu(args))
    except CouplingInstabilityError as e:
        print(f"hammerbit cosim: {e}", file=sys.stderr)
        return 3
    except ValueError as e:
        print(f"hammerbit cosim: error: {e}", file=sys.stderr)
        return 2
    total = time.perf_counter() - t0
    out = res.summary()
    out["total_time_s"] = total
    out["hammer"] = "fmu" if args.fmu else "in-process"
    if args.adaptive:
        out["scheme"] = "gauss-seidel (hammer first), adaptive step"
        out["adaptive"] = res.stats
    out["string"] = string.name
    out["wob_static_n"] = cfg.weight_on_bit
    if args.out:
        res.to_csv(args.out)
        out["csv"] = str(args.out)
    if args.json:
        print(json.dumps(out, indent=2, default=float))
    else:
        print(f"{string.name}: {res.macro_steps} macro steps of {cfg.step:g} s ({cfg.scheme}, "
              f"extrapolation order {cfg.extrapolation}, hammer {out['hammer']})")
        print(f"  WOB mean {out['wob_mean_n']:.1f} N, dynamic amplitude {out['wob_amplitude_n']:.1f} N "
              f"(second half of the run)")
        print(f"  penetration {out['penetration_m']:.6g} m, wall time {out['wall_time_s']:.3f} s "
              f"(+ set-up {out['setup_time_s']:.3f} s)")
        if args.out:
            print(f"  wrote {args.out}")
    return 0


def register(subparsers) -> None:
    """Add ``cosim`` to the ``hammerbit`` command."""
    p = subparsers.add_parser("cosim", help="co-simulate the drillstring with the hammer FMU",
                              description="Co-simulation: the drillstring stepped exactly by the master, "
                                          "the hammer as an FMU, from static equilibrium.")
    _common(p)
    p.add_argument("--stop", type=float, required=True, help="simulated time [s]")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--out", default=None, help="CSV of the recorded variables")
    p.add_argument("--adaptive", action="store_true",
                   help="adaptive macro step with rollback through the FMU state (Gauss-Seidel, "
                        "hammer first); --step is the initial step")
    p.add_argument("--tol", type=float, default=1e-3,
                   help="--adaptive: allowed interface force defect relative to the WOB (default 1e-3)")
    p.set_defaults(func=cmd_cosim)
