"""``hammerbit continue``: the periodic orbits of a scene followed through one parameter (numerical continuation)."""
from __future__ import annotations

import argparse
import json
import sys

from hammerbit.cli.common import (EXIT_INACCURATE, NETCDF_SUFFIXES, RunFailure, UsageError, add_set_argument,
                                  check_output, output_errors, parse_settings)

__all__ = ["register", "cmd_continue", "MAX_SEEDS"]

#: runs from rest that seed branches, at most
MAX_SEEDS = 200
#: points of a curve in two parameters, at most
MAX_CURVE_POINTS = 2000


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``continue`` sub-command; returns its parser."""
    from hammerbit.model.presets import PRESETS
    p = subparsers.add_parser(
        "continue", help="periodic orbits followed through a parameter, their stability and bifurcations",
        description="Numerical continuation of the periodic orbits of the hammer-bit-rock model in one "
                    "parameter (docs/continuation.md): branches seeded by runs from rest, followed by "
                    "pseudo-arclength continuation with their Floquet multipliers; period-doubling, fold, "
                    "Neimark-Sacker, grazing and sliding bifurcations and the tension, bounce and runaway onsets "
                    "located; the period-doubled branch "
                    "followed; coexisting stable branches and the one a run from rest reaches. Exit 5 "
                    "when a branch cannot be followed, with the parameter value and the reason.")
    p.add_argument("--preset", default="paper-fig9", choices=sorted(PRESETS), help="parameter preset")
    add_set_argument(p)
    p.add_argument("--param", required=True, metavar="NAME",
                   help="the parameter followed, as --set names it (a group such as a, eta, b, or an SI "
                        "name such as A, f, B)")
    p.add_argument("--range", required=True, nargs=2, type=float, metavar=("START", "END"),
                   help="the parameter's range, in its units (SI names: SI units)")
    p.add_argument("--param2", default=None, metavar="NAME",
                   help="a second parameter: every period-doubling, fold, Neimark-Sacker, grazing, sliding, "
                        "tension, bounce and runaway point found along --param is followed over --range2 as a "
                        "curve (JSON 'curves')")
    p.add_argument("--range2", default=None, nargs=2, type=float, metavar=("START", "END"),
                   help="the range of --param2, in its units")
    p.add_argument("--curve-points", type=int, default=21, metavar="N",
                   help="points of each curve over --range2")
    p.add_argument("--seeds", type=int, default=9, metavar="N",
                   help="runs from rest, evenly spread over the range, that seed branches")
    p.add_argument("--json", action="store_true", help="the diagram as JSON on stdout (nondimensional)")
    p.add_argument("--csv", default=None, metavar="FILE", help="one row per branch point, SI units")
    p.add_argument("--out", default=None, metavar="FILE.nc", help="the branch points as netCDF")
    p.add_argument("--plot", default=None, metavar="FILE",
                   help="the bifurcation diagram (png, pdf, svg): stable solid, unstable dashed")
    p.set_defaults(func=cmd_continue)
    return p


def _check(args):
    """Every input checked before any work (exit 2 naming the option)."""
    from hammerbit.cli.preflight import apply_user_settings
    from hammerbit.continuation.parameter import Parameter
    from hammerbit.model.presets import preset
    from hammerbit.model.validation import ParameterError
    base = apply_user_settings(preset(args.preset), parse_settings(args.set))
    try:
        param = Parameter.on(args.param, base)
    except ParameterError as e:
        raise UsageError(f"--param {args.param}: {e}") from None
    start, end = args.range
    if start == end:
        raise UsageError(f"--range {start:g} {end:g}: the two ends must differ")
    for v in (start, end):
        try:
            param.at(base, v)
        except ParameterError as e:
            raise UsageError(f"--range {v:g}: {e}") from None
    if (args.param2 is None) != (args.range2 is None):
        raise UsageError("--param2 and --range2 go together: give both or neither")
    if args.param2 is not None:
        if args.param2 == args.param:
            raise UsageError(f"--param2 {args.param2}: the same parameter as --param")
        try:
            param2 = Parameter.on(args.param2, base)
        except ParameterError as e:
            raise UsageError(f"--param2 {args.param2}: {e}") from None
        if args.range2[0] == args.range2[1]:
            raise UsageError(f"--range2 {args.range2[0]:g} {args.range2[1]:g}: the two ends must differ")
        for v in args.range2:
            try:
                param2.at(base, v)
            except ParameterError as e:
                raise UsageError(f"--range2 {v:g}: {e}") from None
        if not (2 <= args.curve_points <= MAX_CURVE_POINTS):
            raise UsageError(f"--curve-points {args.curve_points}: allowed 2 to {MAX_CURVE_POINTS}")
    if not (2 <= args.seeds <= MAX_SEEDS):
        raise UsageError(f"--seeds {args.seeds}: allowed 2 to {MAX_SEEDS}")
    for opt, path, formats in (("--csv", args.csv, {"csv"}), ("--out", args.out, NETCDF_SUFFIXES),
                               ("--plot", args.plot, {"png", "pdf", "svg"})):
        if path:
            check_output(path, opt, formats=formats)
    return base


def _progress(name: str):
    """One status line on a terminal (stderr), nothing otherwise."""
    if not sys.stderr.isatty():
        return None
    count = [0]

    def show(point):
        count[0] += 1
        o = point.orbit
        sys.stderr.write(f"\r{name} = {point.value:<12.6g} period {o.period:<3d} "
                         f"{'stable  ' if o.stable else 'unstable'} points {count[0]:<6d}")
        sys.stderr.flush()
    return show


def cmd_continue(args) -> int:
    from hammerbit.continuation.diagram import continue_orbits
    from hammerbit.continuation.output import diagram_json, draw_diagram, write_csv, write_netcdf
    base = _check(args)
    show = _progress(args.param)
    d = continue_orbits(base, args.param, args.range[0], args.range[1], seeds=args.seeds, on_point=show)
    if show:
        sys.stderr.write("\n")
    curves = _curves(base, d, args) if args.param2 else []
    if args.csv:
        with output_errors("--csv", args.csv):
            write_csv(d, args.csv)
    if args.out:
        with output_errors("--out", args.out):
            write_netcdf(d, args.out)
    if args.plot:
        with output_errors("--plot", args.plot):
            draw_diagram(d, args.plot)
    if args.json:
        out = diagram_json(d)
        out["curves"] = [{"kind": c.kind, "branch": i, "points": [{c.param: float(v), c.param2: float(w)}
                                                                   for v, w in c.points], "stopped": c.stopped}
                         for i, c in curves]
        print(json.dumps(out))
    else:
        _print_text(d)
        for _, c in curves:
            span = (f" in [{min(w for _, w in c.points):.6g}, {max(w for _, w in c.points):.6g}]"
                    if c.points else "")
            print(f"{c.kind} curve: {len(c.points)} points over {c.param2}{span}"
                  + (f"; {c.stopped}" if c.stopped else ""))
    if d.stops:
        raise RunFailure(f"continuation could not go on: {d.stops[0]}"
                         + (f" (and {len(d.stops) - 1} more, see --json 'stops')" if len(d.stops) > 1 else ""),
                         code=EXIT_INACCURATE)
    return 0


def _curves(base, d, args) -> list:
    """Each smooth bifurcation, grazing, sliding, tension, bounce and runaway point of the diagram followed over
    --range2:
    [(branch index, Curve)]."""
    from hammerbit.continuation.bifurcation import SMOOTH_KINDS
    from hammerbit.continuation.boundary import follow_boundary
    from hammerbit.continuation.runaway import follow_runaway
    from hammerbit.continuation.touch import INDICATORS, follow_touch
    out = []
    for b in d.bifurcations:
        if b.kind in SMOOTH_KINDS:
            follow = follow_boundary
        elif b.kind in INDICATORS or b.kind == "sliding":
            follow = follow_touch
        elif b.kind == "runaway":
            follow = follow_runaway
        else:
            continue
        c = follow(base, b, args.param, args.param2, args.range2[0], args.range2[1], points=args.curve_points)
        if c.stopped:
            d.stops.append(f"{b.kind} curve from {args.param} = {b.value:.9g}: {c.stopped}")
        out.append((b.branch, c))
    return out


def _print_text(d) -> None:
    from hammerbit.continuation.diagram import stable_intervals
    name = d.parameter
    for i, br in enumerate(d.branches):
        v = [p.value for p in br.points]
        stable = stable_intervals(br)
        line = f"branch {i}: period {br.period}, {name} in [{min(v):.6g}, {max(v):.6g}], {len(v)} points"
        if stable:
            line += ", stable in " + ", ".join(f"[{lo:.6g}, {hi:.6g}]" for lo, hi, _, _ in stable)
        print(line + (f"; ends {br.ended}" if br.ended else ""))
    for b in d.bifurcations:
        print(f"{b.kind} at {name} = {b.value:.9g} on branch {b.branch} ({b.detail})")
    for c in d.coexistence:
        sw = c["from_rest_switch"]
        text = (f"; runs from rest switch from {_which(sw['below'])} to {_which(sw['above'])} at {name} = "
                f"{sw['value']:.9g}" + (f" (the state at rest crosses the stable manifold of the unstable orbit "
                                        f"of branch {sw['saddle']})" if sw["located_by"] == "stable manifold"
                                        else f" (bisection of runs from rest, +- {sw['uncertainty']:.2g})")
                if sw else "")
        print(f"stable branches {c['branches']} coexist for {name} in [{c['from']:.6g}, {c['to']:.6g}]; "
              f"a run from rest reaches {_which(c['from_rest'])} at the middle{text}")


def _which(branch) -> str:
    return "no followed branch" if branch is None else f"branch {branch}"
