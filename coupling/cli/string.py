"""``hammerbit modes`` and ``hammerbit check`` sub-commands.

Both are registered by :func:`hammerbit.cli.main.build_parser`; errors are
exceptions that :func:`hammerbit.cli.common.run_command` turns into a one-line
message and an exit code: 2 for bad input (the message names the option or
the file, section, key, value and allowed range), 4 for ``check --strict``
when the verdict is FAIL.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path
from typing import Any

from hammerbit.cli.common import EXIT_CHECK_FAILED, EXIT_OK, UsageError, one_blas_thread, staged
from hammerbit.drillstring import (
    DEFAULT_MASS,
    DEFAULT_RTOL,
    MASS_SCHEMES,
    DrillStringError,
    example_names,
    load_string,
    parse_boundary,
)
from hammerbit.model.validation import ParameterError

__all__ = ["register", "cmd_modes", "cmd_check"]

_BOUNDARY_HELP = ("fixed | free[:MASS] | spring:K[:C[:MASS]] | hammer:K[:C]  "
                  "(K [N/m], C [N s/m], MASS [kg]; a bottom without MASS carries the file's bit mass)")

#: CheckConfig field -> the option a user typed.
_OPTION = {"excitation_hz": "--frequency", "rpm": "--rpm", "factor": "--factor", "margin": "--margin",
           "resonance_limit": "--resonance-limit", "rtol": "--rtol", "damping_range": "--damping-range",
           "damping_range low": "--damping-range LO", "damping_range high": "--damping-range HI",
           "frequency_range_hz": "--range", "frequency_range_hz low": "--range LO",
           "frequency_range_hz high": "--range HI", "rpm_range": "--rpm-range",
           "rpm_range low": "--rpm-range LO", "rpm_range high": "--rpm-range HI",
           "min_window": "--min-window"}


def register(subparsers: "argparse._SubParsersAction") -> tuple[argparse.ArgumentParser, argparse.ArgumentParser]:
    """Add the ``modes`` and ``check`` sub-commands; returns both parsers."""
    string_help = ("drillstring TOML file, or a built-in example name ("
                   + ", ".join(example_names()) + ")")

    pm = subparsers.add_parser(
        "modes", help="axial natural frequencies of a drillstring",
        description="Lowest axial natural frequencies of the drillstring (finite elements meshed for "
                    "the target accuracy --rtol, with an error estimate per mode).")
    pm.add_argument("--string", required=True, metavar="FILE", help=string_help)
    pm.add_argument("--top", default=None, metavar="SPEC", help=f"top boundary (default from file): {_BOUNDARY_HELP}")
    pm.add_argument("--bottom", default=None, metavar="SPEC",
                    help=f"bottom boundary (default from file): {_BOUNDARY_HELP}")
    pm.add_argument("--count", type=int, default=None, metavar="N", help="number of modes (default 6)")
    pm.add_argument("--fmax", type=float, default=None, metavar="HZ", help="only modes up to HZ")
    pm.add_argument("--mass", choices=MASS_SCHEMES, default=DEFAULT_MASS, help="mass matrix (default mixed)")
    pm.add_argument("--rtol", type=float, default=DEFAULT_RTOL, metavar="TOL",
                    help=f"target relative accuracy of every frequency (default {DEFAULT_RTOL:g}); "
                         "the mesh is refined until the error estimate meets it")
    pm.add_argument("--exact", action="store_true",
                    help="also give the exact (transfer-matrix) frequencies and relative errors")
    pm.add_argument("--hammer-on-bottom", action="store_true",
                    help="bit on bottom with the hammer of `hammerbit cosim` (the field hammer, "
                         "changed by --set, --interface-stiffness) as the bottom boundary; the "
                         "frequencies the co-simulation sweep resonates at")
    pm.add_argument("--csv", default=None, metavar="FILE", help="also write the table as CSV to FILE")
    pm.add_argument("--json", action="store_true", help="JSON on stdout")
    from hammerbit.cli.cosim import add_hammer_options
    add_hammer_options(pm)          # --hammer-on-bottom: the hammer of ``cosim`` (--set, interface)
    pm.set_defaults(func=cmd_modes)

    pc = subparsers.add_parser(
        "check", help="hammer/bit excitation frequency avoidance check",
        description="Check an excitation frequency (hammer, or rpm x factor) against the axial "
                    "modes with the bit on and off bottom, over a damping range; report the verdict "
                    "(robust pass, pass at nominal damping only, fail), the rule, the modes and the "
                    "safe windows with the rule that cleared each.")
    pc.add_argument("--string", required=True, metavar="FILE", help=string_help)
    exc = pc.add_mutually_exclusive_group(required=True)
    exc.add_argument("--frequency", type=float, metavar="HZ", help="excitation frequency [Hz], > 0")
    exc.add_argument("--rpm", type=float, metavar="RPM", help="rotary speed [rev/min], > 0")
    pc.add_argument("--factor", type=float, default=None, metavar="K",
                    help="excitation per revolution with --rpm: 3 tricone, blade count PDC (default 1)")
    pc.add_argument("--margin", type=float, default=0.15, help="band half-width as a fraction of each natural frequency (default 0.15, i.e. ±15 %%)")
    pc.add_argument("--top", default=None, metavar="SPEC", help=f"top boundary (default from file): {_BOUNDARY_HELP}")
    pc.add_argument("--on-bottom", default=None, metavar="SPEC",
                    help="bit-on-bottom boundary (default from file, else fixed)")
    pc.add_argument("--off-bottom", default=None, metavar="SPEC",
                    help="bit-off-bottom boundary (default from file, else free with the bit mass)")
    pc.add_argument("--range", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                    help="frequency range for safe windows [Hz] (default 0 .. 2x excitation)")
    pc.add_argument("--rpm-range", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                    help="rotary-speed range for safe windows [rpm] (with --rpm)")
    pc.add_argument("--resonance-limit", type=float, default=2 ** 0.5, metavar="R",
                    help="largest resonance factor accepted where only crowded modes are in band "
                         "(default sqrt 2)")
    pc.add_argument("--damping-range", type=float, nargs=2, default=(0.5, 2.0), metavar=("LO", "HI"),
                    help="factors on the file's damping at which the receptance rule must pass "
                         "(default 0.5 2)")
    pc.add_argument("--rtol", type=float, default=DEFAULT_RTOL, metavar="TOL",
                    help=f"target relative accuracy of the natural frequencies (default {DEFAULT_RTOL:g})")
    pc.add_argument("--mass", choices=MASS_SCHEMES, default=DEFAULT_MASS, help="mass matrix (default mixed)")
    pc.add_argument("--json", action="store_true", help="JSON on stdout")
    pc.add_argument("--plot", default=None, metavar="FILE", help="save Campbell + receptance figure (PNG/PDF/SVG)")
    pc.add_argument("--strict", action="store_true",
                    help=f"exit code {EXIT_CHECK_FAILED} when the verdict is FAIL")
    pc.set_defaults(func=cmd_check)
    return pm, pc


def _error(msg: str) -> int:
    print(f"hammerbit: error: {msg}", file=sys.stderr)
    return 2


def _boundary(spec: str | None, option: str):
    return parse_boundary(spec, where=option) if spec else None


def _positive(value: float | None, option: str) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ParameterError(option, value, "a finite number > 0")


def _writable(path: str | None, option: str, suffixes: tuple[str, ...] | None = None) -> None:
    if path is None:
        return
    p = Path(path)
    if not p.parent.resolve().is_dir():
        raise UsageError(f"{option} {path}: directory {p.parent} does not exist")
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise UsageError(f"{option} {path}: allowed formats {', '.join(suffixes)}")


@one_blas_thread
def cmd_modes(args: argparse.Namespace) -> int:
    """Handler of ``hammerbit modes``."""
    from hammerbit.drillstring import exact_frequencies, modes

    if getattr(args, "hammer_on_bottom", False):
        return _cmd_hammer_modes(args)
    from hammerbit.cli.options import refuse_unless
    for dest in ("wob", "interface_stiffness", "interface_damping"):
        refuse_unless(args, dest, False, "an option of --hammer-on-bottom (the hammer as the bottom "
                                         "boundary): give --hammer-on-bottom too")
    if args.set:
        raise UsageError(f"--set {args.set[0]}: changes the hammer of --hammer-on-bottom (the hammer as the "
                         f"bottom boundary): give --hammer-on-bottom too")
    _positive(args.fmax, "--fmax")
    if args.count is not None and args.count < 1:
        raise UsageError(f"--count {args.count}: must be >= 1")
    if not (math.isfinite(args.rtol) and 1e-12 <= args.rtol <= 0.1):
        raise ParameterError("--rtol", args.rtol, "[1e-12, 0.1]")
    _writable(args.csv, "--csv")
    string = load_string(args.string)
    top = _boundary(args.top, "--top")
    bottom = _boundary(args.bottom, "--bottom")
    count = args.count if (args.count is not None or args.fmax is not None) else 6
    res = modes(string, top, bottom, f_max=args.fmax, count=count, mass=args.mass, rtol=args.rtol)
    exact = exact_frequencies(string, res.top, res.bottom, count=len(res)) if args.exact else None
    rows = []
    for i, f in enumerate(res.frequencies_hz):
        row: dict[str, Any] = {"mode": i + 1, "frequency_hz": float(f),
                               "period_s": (1.0 / f) if f > 0 else None,
                               "error_estimate": None if res.error_estimate is None else float(res.error_estimate[i])}
        if exact is not None:
            e = float(exact[i])
            row["exact_hz"] = e
            row["relative_error"] = (float(f) / e - 1.0) if e > 0 else 0.0
        rows.append(row)
    if args.csv:
        with open(staged(args.csv), "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["mode", "frequency_hz"])
            w.writeheader()
            for r in rows:
                w.writerow({k: ("" if v is None else v) for k, v in r.items()})
    out: dict[str, Any] = {"string": string.name, **res.to_dict()}
    if exact is not None:
        out["exact_hz"] = [r["exact_hz"] for r in rows]
        out["relative_error"] = [r["relative_error"] for r in rows]
    if args.csv:
        out["csv"] = str(args.csv)
    if args.json:
        print(json.dumps(out, indent=2))
        return EXIT_OK
    est = "" if res.error_estimate is None else f", estimated error <= {float(res.error_estimate.max(initial=0)):.1e}"
    print(f"{string.name}: {string.length:g} m, {res.n_elements} elements {res.elements_per_section}, "
          f"{res.mass} mass, target {res.rtol:g}{est}; top {res.top.spec()}, bottom {res.bottom.spec()}")
    head = f"{'mode':>4} {'f [Hz]':>12} {'period [s]':>11} {'est. error':>10}"
    if exact is not None:
        head += f" {'exact [Hz]':>12} {'rel. error':>11}"
    print(head)
    for r in rows:
        per = r["period_s"]
        est_s = "" if r["error_estimate"] is None else f"{r['error_estimate']:.1e}"
        line = f"{r['mode']:>4} {r['frequency_hz']:>12.7g} {(per if per else float('inf')):>11.4g} {est_s:>10}"
        if exact is not None:
            line += f" {r['exact_hz']:>12.7g} {r['relative_error']:>11.2e}"
        print(line)
    if args.csv:
        print(f"csv: {args.csv}")
    return EXIT_OK


def _check_config(args: argparse.Namespace) -> CheckConfig:
    from hammerbit.check.frequency import CheckConfig

    if args.factor is not None and args.rpm is None:
        raise UsageError("--factor needs --rpm")
    if args.rpm_range is not None and args.rpm is None:
        raise UsageError("--rpm-range needs --rpm")
    _positive(args.frequency, "--frequency")
    _positive(args.rpm, "--rpm")
    try:
        return CheckConfig(
            excitation_hz=args.frequency, rpm=args.rpm,
            factor=1.0 if args.factor is None else args.factor, margin=args.margin,
            top=_boundary(args.top, "--top"), on_bottom=_boundary(args.on_bottom, "--on-bottom"),
            off_bottom=_boundary(args.off_bottom, "--off-bottom"),
            frequency_range_hz=tuple(args.range) if args.range else None,
            rpm_range=tuple(args.rpm_range) if args.rpm_range else None,
            resonance_limit=args.resonance_limit, damping_range=tuple(args.damping_range),
            rtol=args.rtol, mass=args.mass)
    except ParameterError as err:
        raise err.renamed(_OPTION.get(err.name, err.name)) from None


@one_blas_thread
def cmd_check(args: argparse.Namespace) -> int:
    """Handler of ``hammerbit check``."""
    from hammerbit.check.frequency import check, plot_check

    cfg = _check_config(args)
    _writable(args.plot, "--plot", (".png", ".pdf", ".svg"))
    string = load_string(args.string)
    res = check(string, cfg)
    if args.plot:
        plot_check(res, staged(args.plot))
    code = EXIT_CHECK_FAILED if (args.strict and res.verdict == "fail") else EXIT_OK
    if args.json:
        d = res.to_dict()
        if args.plot:
            d["plot"] = str(args.plot)
        print(json.dumps(d, indent=2))
        return code
    exc = (f"{res.excitation_hz:.6g} Hz" if cfg.rpm is None else
           f"{cfg.rpm:g} rpm x {cfg.factor:g} = {res.excitation_hz:.6g} Hz")
    z = res.damping_ratio_range
    print(f"{string.name}: excitation {exc}, margin +-{100 * cfg.margin:.0f} %, damping ratio "
          f"{z[1]:.3g} (range {z[0]:.3g} .. {z[2]:.3g})")
    print(f"VERDICT: {res.verdict_label.upper()} ({res.rule} rule)")
    for c in res.configurations:
        print(f"\n[{c.name}] top {c.top.spec()}, bottom {c.bottom.spec()}: {c.verdict}"
              f"{'' if c.verdict == 'fail' or c.robust else ' (nominal damping only)'} -- {c.reason}")
        print(f"  bit receptance {abs(c.receptance):.3e} m/N, dynamic amplification "
              f"{c.dynamic_amplification:.3g}, resonance factor {c.resonance_factor:.3g}; "
              f"{c.n_elements} elements, frequencies to {c.max_error_estimate or 0:.1e}")
        print(f"  {'mode':>4} {'f [Hz]':>10} {'sep [%]':>9} {'band':>5} {'kind':>8} {'share':>7} {'rank':>5}")
        for m in c.modes:
            sep = "" if m.index == 0 else f"{m.separation_pct:+9.2f}"
            kind = "" if m.index == 0 else ("isolated" if m.isolated else "crowded")
            print(f"  {m.index:>4} {m.frequency_hz:>10.5g} {sep:>9} {'IN' if m.in_band else '':>5} {kind:>8} "
                  f"{100 * m.share:>6.1f}% {m.rank:>5}")
    print(f"\nsafe windows [Hz] in {res.range_hz[0]:.4g}-{res.range_hz[1]:.4g}:")
    if not res.windows:
        print("  none")
    k = None if cfg.rpm is None else 60.0 / cfg.factor
    for w in res.windows:
        rng = "" if w.damping_ratio_range is None else \
            f", damping ratio {w.damping_ratio_range[0]:.3g}..{w.damping_ratio_range[1]:.3g}"
        rpm = "" if k is None else f"  ({w.lo_hz * k:.0f}-{w.hi_hz * k:.0f} rpm)"
        print(f"  {w.lo_hz:8.4g} - {w.hi_hz:<8.4g}{rpm}  {w.label}{rng}")
    if args.plot:
        print(f"figure: {args.plot}")
    return code


#: Highest frequency [Hz] ``modes --hammer-on-bottom --count N`` searches up to for N modes.
MODES_F_CEILING = 1e6


def _cmd_hammer_modes(args: argparse.Namespace) -> int:
    """``hammerbit modes --hammer-on-bottom``: the hammer as the bottom boundary.

    The hammer, interface and ``--set`` options and the config are those of
    ``hammerbit cosim`` (:func:`hammerbit.cli.cosim.config_from_args`), so the
    modes are those of the system a co-simulation or sweep with the same
    options runs."""
    from hammerbit.cli.common import UsageError
    from hammerbit.cli.cosim import config_from_args
    from hammerbit.check.frequency import hammer_on_bottom_frequencies
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
    while args.count and not args.fmax and len(f) < args.count and kw["f_max"] < MODES_F_CEILING:
        # --count without --fmax: as many modes as asked, however high they lie
        kw["f_max"] *= 4.0
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
    if args.csv:
        _write_rows(args.csv, [{"mode": i + 1, "frequency_hz": float(x),
                                **({"exact_hz": out["exact_hz"][i], "relative_error": out["relative_error"][i]}
                                   if exact is not None and i < len(out["relative_error"]) else {})}
                               for i, x in enumerate(f)])
    worst = max((abs(e) for e in out.get("relative_error", [])), default=0.0)
    if worst > args.rtol:
        k = [abs(e) for e in out["relative_error"]].index(worst) + 1
        print(f"hammerbit modes: warning: with --hammer-on-bottom the finite-element frequencies miss "
              f"--rtol {args.rtol:g}: relative error up to {worst:.2e} (mode {k}); the mesh follows --fmax, "
              f"so use the exact column", file=sys.stderr)
    return 0


def _write_rows(path, rows) -> None:
    """The rows (dicts) as CSV; a failed write names ``--csv``."""
    from hammerbit.cli.common import output_errors
    names = list(rows[0]) if rows else ["mode", "frequency_hz"]
    with output_errors("--csv", path), open(staged(path), "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=names)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})
