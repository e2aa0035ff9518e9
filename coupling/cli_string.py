"""``hammerbit modes`` and ``hammerbit check`` sub-commands.

Wire them into the main parser with::

    sub = parser.add_subparsers(dest="command")
    cli_string.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)

Both handlers return an exit code: 0 on success (``check`` also returns 0
for a ``fail`` verdict unless ``--strict`` is given, then 1), 2 on bad input
(the message, naming file, section, key, value and range, goes to stderr).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from .drillstring import (
    DrillStringError,
    MASS_SCHEMES,
    DEFAULT_MASS,
    example_names,
    exact_frequencies,
    load_string,
    modes,
    parse_boundary,
)
from .modal_check import CheckConfig, check, plot_check

__all__ = ["register", "cmd_modes", "cmd_check"]

_BOUNDARY_HELP = ("fixed | free[:MASS] | spring:K[:C[:MASS]] | hammer:K[:C]  "
                  "(K [N/m], C [N s/m], MASS [kg])")


def register(subparsers: "argparse._SubParsersAction") -> tuple[argparse.ArgumentParser, argparse.ArgumentParser]:
    """Add the ``modes`` and ``check`` sub-commands; returns both parsers."""
    string_help = ("drillstring TOML file, or a built-in example name ("
                   + ", ".join(example_names()) + ")")

    pm = subparsers.add_parser(
        "modes", help="axial natural frequencies of a drillstring",
        description="Lowest axial natural frequencies of the lumped drillstring model.")
    pm.add_argument("--string", required=True, metavar="FILE", help=string_help)
    pm.add_argument("--top", default=None, metavar="SPEC", help=f"top boundary (default from file): {_BOUNDARY_HELP}")
    pm.add_argument("--bottom", default=None, metavar="SPEC",
                    help=f"bottom boundary (default from file): {_BOUNDARY_HELP}")
    pm.add_argument("--count", type=int, default=None, metavar="N", help="number of modes (default 6)")
    pm.add_argument("--fmax", type=float, default=None, metavar="HZ", help="only modes up to HZ")
    pm.add_argument("--mass", choices=MASS_SCHEMES, default=DEFAULT_MASS, help="mass matrix (default mixed)")
    pm.add_argument("--exact", action="store_true",
                    help="also give the exact (transfer-matrix) frequencies and relative errors")
    pm.add_argument("--hammer-on-bottom", action="store_true",
                    help="bit on bottom with the hammer of `hammerbit cosim` (the field hammer, "
                         "changed by --set, --interface-stiffness) as the bottom boundary; the "
                         "frequencies the co-simulation sweep resonates at")
    pm.add_argument("--json", action="store_true", help="JSON on stdout")
    from .cli_cosim import add_hammer_options
    add_hammer_options(pm)          # --hammer-on-bottom: the hammer of ``cosim`` (--set, interface)
    pm.set_defaults(func=cmd_modes)

    pc = subparsers.add_parser(
        "check", help="hammer/bit excitation frequency avoidance check",
        description="Check an excitation frequency (hammer, or rpm x factor) against the axial "
                    "modes with the bit on and off bottom; report verdict, rule, modes and safe windows.")
    pc.add_argument("--string", required=True, metavar="FILE", help=string_help)
    exc = pc.add_mutually_exclusive_group(required=True)
    exc.add_argument("--frequency", type=float, metavar="HZ", help="excitation frequency [Hz]")
    exc.add_argument("--rpm", type=float, metavar="RPM", help="rotary speed [rev/min]")
    pc.add_argument("--factor", type=float, default=None, metavar="K",
                    help="excitation per revolution with --rpm: 3 tricone, blade count PDC (default 1)")
    pc.add_argument("--margin", type=float, default=0.15, help="band half-width (default 0.15 = +-15 %%)")
    pc.add_argument("--top", default=None, metavar="SPEC", help=f"top boundary (default from file): {_BOUNDARY_HELP}")
    pc.add_argument("--on-bottom", default=None, metavar="SPEC", help="bit-on-bottom boundary (default from file)")
    pc.add_argument("--off-bottom", default=None, metavar="SPEC", help="bit-off-bottom boundary (default from file)")
    pc.add_argument("--range", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                    help="frequency range for safe windows [Hz] (default 0 .. 2x excitation)")
    pc.add_argument("--rpm-range", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                    help="rotary-speed range for safe windows [rpm] (with --rpm)")
    pc.add_argument("--resonance-limit", type=float, default=2 ** 0.5, metavar="R",
                    help="largest resonance factor accepted where modes crowd (default sqrt 2)")
    pc.add_argument("--mass", choices=MASS_SCHEMES, default=DEFAULT_MASS, help="mass matrix (default mixed)")
    pc.add_argument("--json", action="store_true", help="JSON on stdout")
    pc.add_argument("--plot", default=None, metavar="FILE", help="save Campbell + receptance figure (PNG/PDF/SVG)")
    pc.add_argument("--strict", action="store_true", help="exit code 1 when the verdict is fail")
    pc.set_defaults(func=cmd_check)
    return pm, pc


def _error(msg: str) -> int:
    print(f"hammerbit: error: {msg}", file=sys.stderr)
    return 2


def cmd_modes(args: argparse.Namespace) -> int:
    """Handler of ``hammerbit modes``."""
    if getattr(args, "hammer_on_bottom", False):
        return _cmd_hammer_modes(args)
    try:
        string = load_string(args.string)
        top = parse_boundary(args.top, where="--top") if args.top else None
        bottom = parse_boundary(args.bottom, where="--bottom") if args.bottom else None
        count = args.count if (args.count is not None or args.fmax is not None) else 6
        if count is not None and count < 1:
            raise ValueError(f"--count {count}: must be >= 1")
        res = modes(string, top, bottom, f_max=args.fmax, count=count, mass=args.mass)
        exact = None
        if args.exact:
            exact = exact_frequencies(string, res.top, res.bottom, count=len(res))
    except (DrillStringError, ValueError) as err:
        return _error(str(err))
    out: dict[str, Any] = {"string": string.name, **res.to_dict()}
    if exact is not None:
        out["exact_hz"] = [float(x) for x in exact]
        out["relative_error"] = [None if e == 0 else float(f / e - 1.0)
                                 for f, e in zip(res.frequencies_hz, exact)]
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{string.name}: {string.length:g} m, {res.n_elements} elements, {res.mass} mass; "
          f"top {res.top.spec()}, bottom {res.bottom.spec()}")
    head = f"{'mode':>4} {'f [Hz]':>12} {'period [s]':>11}"
    if exact is not None:
        head += f" {'exact [Hz]':>12} {'rel. error':>11}"
    print(head)
    for i, f in enumerate(res.frequencies_hz, start=1):
        line = f"{i:>4} {f:>12.6g} {(1.0 / f if f > 0 else float('inf')):>11.4g}"
        if exact is not None:
            e = exact[i - 1]
            line += f" {e:>12.6g} {(f / e - 1.0 if e > 0 else 0.0):>11.2e}"
        print(line)
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    """Handler of ``hammerbit check``."""
    try:
        if args.factor is not None and args.rpm is None:
            raise ValueError("--factor needs --rpm")
        if args.rpm_range is not None and args.rpm is None:
            raise ValueError("--rpm-range needs --rpm")
        string = load_string(args.string)
        cfg = CheckConfig(
            excitation_hz=args.frequency, rpm=args.rpm,
            factor=1.0 if args.factor is None else args.factor, margin=args.margin,
            top=parse_boundary(args.top, where="--top") if args.top else None,
            on_bottom=parse_boundary(args.on_bottom, where="--on-bottom") if args.on_bottom else None,
            off_bottom=parse_boundary(args.off_bottom, where="--off-bottom") if args.off_bottom else None,
            frequency_range_hz=tuple(args.range) if args.range else None,
            rpm_range=tuple(args.rpm_range) if args.rpm_range else None,
            resonance_limit=args.resonance_limit, mass=args.mass)
        res = check(string, cfg)
        if args.plot:
            plot_check(res, args.plot)
    except (DrillStringError, ValueError) as err:
        return _error(str(err))
    code = 1 if (args.strict and res.verdict == "fail") else 0
    if args.json:
        d = res.to_dict()
        if args.plot:
            d["plot"] = str(args.plot)
        print(json.dumps(d, indent=2))
        return code
    exc = (f"{res.excitation_hz:.4g} Hz" if cfg.rpm is None else
           f"{cfg.rpm:g} rpm x {cfg.factor:g} = {res.excitation_hz:.4g} Hz")
    print(f"{string.name}: excitation {exc}, margin +-{100 * cfg.margin:.0f} %")
    print(f"VERDICT: {res.verdict.upper()} ({res.rule} rule)")
    for c in res.configurations:
        print(f"\n[{c.name}] top {c.top.spec()}, bottom {c.bottom.spec()}: {c.verdict} -- {c.reason}")
        print(f"  bit receptance {abs(c.receptance):.3e} m/N, dynamic amplification "
              f"{c.dynamic_amplification:.3g}, resonance factor {c.resonance_factor:.3g}")
        print(f"  {'mode':>4} {'f [Hz]':>10} {'sep [%]':>9} {'band':>5} {'share':>7} {'rank':>5}")
        for m in c.modes:
            sep = "" if m.index == 0 else f"{m.separation_pct:+9.1f}"
            print(f"  {m.index:>4} {m.frequency_hz:>10.4g} {sep:>9} {'IN' if m.in_band else '':>5} "
                  f"{100 * m.share:>6.1f}% {m.rank:>5}")
    wins = ", ".join(f"{lo:.3g}-{hi:.3g}" for lo, hi in res.safe_windows_hz) or "none"
    print(f"\nsafe windows [Hz] in {res.range_hz[0]:.3g}-{res.range_hz[1]:.3g}: {wins}")
    if res.safe_windows_rpm is not None:
        print("safe windows [rpm]: " + (", ".join(f"{lo:.0f}-{hi:.0f}" for lo, hi in res.safe_windows_rpm)
                                         or "none"))
    if args.plot:
        print(f"figure: {args.plot}")
    return code


def _cmd_hammer_modes(args: argparse.Namespace) -> int:
    """``hammerbit modes --hammer-on-bottom``: the hammer as the bottom boundary.

    The hammer, interface and ``--set`` options and the config are those of
    ``hammerbit cosim`` (:func:`hammerbit.cli_cosim.config_from_args`), so the
    modes are those of the system a co-simulation or sweep with the same
    options runs."""
    from .cli_common import UsageError
    from .cli_cosim import config_from_args
    from .modal_check import hammer_on_bottom_frequencies
    if args.bottom:
        raise UsageError("--bottom cannot be combined with --hammer-on-bottom: the hammer is the bottom "
                         "boundary (change it with --set and --interface-stiffness)")
    string = load_string(args.string)
    top = parse_boundary(args.top, where="--top") if args.top else None
    cfg = config_from_args(args, estimate=False)
    rig = cfg.rig
    f_max = args.fmax or 100.0
    kw = dict(interface_stiffness=cfg.interface_stiffness, hammer_mass=rig.hammer_mass,
              hammer_stiffness=rig.stiffness, top=top, f_max=f_max)
    f = hammer_on_bottom_frequencies(string, mass=args.mass, **kw)
    exact = hammer_on_bottom_frequencies(string, exact=True, **kw) if args.exact else None
    if args.count:
        f = f[: args.count]
    out = {"string": string.name, "bottom": "hammer-on-bottom", "hammer_mass_kg": rig.hammer_mass,
           "hammer_stiffness_n_per_m": rig.stiffness, "interface_stiffness_n_per_m": cfg.interface_stiffness,
           "interface_damping_n_s_per_m": cfg.interface_damping, "wob_n": cfg.weight_on_bit,
           "mass": args.mass, "frequencies_hz": [float(x) for x in f]}
    if exact is not None:
        m = min(len(exact), len(f))
        out["exact_hz"] = [float(x) for x in exact[:len(f)]]
        out["relative_error"] = [float(f[i] / exact[i] - 1.0) for i in range(m)]
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"{string.name}, hammer on bottom (m1 = {rig.hammer_mass:g} kg, K = {rig.stiffness:.3g} N/m, "
              f"k_i = {cfg.interface_stiffness:.3g} N/m):")
        for i, x in enumerate(f, start=1):
            line = f"{i:>4} {x:>12.6g} Hz"
            if exact is not None and i <= len(exact):
                line += f"   exact {exact[i - 1]:>12.6g} Hz  ({x / exact[i - 1] - 1.0:+.2e})"
            print(line)
    return 0
