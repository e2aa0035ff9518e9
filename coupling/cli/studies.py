"""``hammerbit bifurcation | sweep | map | optimize``: studies over many scenes.

Every study runs on the one executor (:mod:`hammerbit.studies.executor`):
``--workers N`` local worker processes (default: one per CPU; ``--workers 1``
runs in this process without Dask), ``--scheduler ADDRESS`` (or
``$DASK_SCHEDULER_ADDRESS``) an existing Dask cluster.  A progress bar shows
on stderr when it is a terminal.

``hammerbit map --preset NAME --axis a=0.05:0.25:81 --axis eta=0.6:1.4:81
[--set ...] [--periods 300] [--out map.nc] [--plot map.png] [--json]``

``hammerbit optimize --preset lab --string FILE [--bounds frequency=LO:HI
amplitude=LO:HI ...] [--margin 0.15] [--max-contact-force N] [--confirm] [--json]``

``hammerbit bifurcation --param a --range LO HI --out FILE.png``

``hammerbit sweep --string FILE [--fmu FILE] --frequencies LO HI N``
"""
from __future__ import annotations

import json
import math
import sys
import time

from hammerbit.cli.common import (EXIT_INFEASIBLE, RunFailure, UsageError, add_set_argument, check_input_file,
                                   parse_settings)
from hammerbit.model.regime_codes import REGIME_BITS, REGIME_TRANSIENT, regime_names

__all__ = ["register", "cmd_bifurcation", "cmd_sweep", "cmd_map", "cmd_optimize"]


# ---------------------------------------------------------------------------
# shared options
# ---------------------------------------------------------------------------
def _add_executor_args(p) -> None:
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default: one per CPU); 1 runs in this process "
                        "without Dask")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on an existing Dask cluster (default $DASK_SCHEDULER_ADDRESS if set)")


def _executor_options(args, *, default_workers=None):
    from hammerbit.studies.executor import ExecutorOptions
    w = args.workers if args.workers is not None else default_workers
    if w is not None and w < 1:
        raise UsageError(f"--workers {w}: allowed 1 or more")
    return ExecutorOptions(workers=w, scheduler=args.scheduler)


def _add_scene_args(p, *, default_preset="paper-fig9") -> None:
    from hammerbit.model.presets import PRESETS
    p.add_argument("--preset", default=default_preset, choices=sorted(PRESETS),
                   help=f"parameter preset (default {default_preset})")
    add_set_argument(p)
    p.add_argument("--rtol", type=float, default=None, help="relative tolerance (default 1e-8)")


def _groups(args):
    from hammerbit.model.presets import preset
    from hammerbit.cli.preflight import apply_user_settings
    return apply_user_settings(preset(args.preset), parse_settings(args.set))


def _solver(args):
    from hammerbit.model.solver_options import SolverOptions
    if args.rtol is None:
        return SolverOptions()
    return SolverOptions(rtol=args.rtol, atol=args.rtol * 1e-2)


def _dump(obj) -> str:
    def clean(x):
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x
    return json.dumps(clean(obj))


# ---------------------------------------------------------------------------
# bifurcation
# ---------------------------------------------------------------------------
def cmd_bifurcation(args) -> int:
    import numpy as np
    from hammerbit.scene.plots import plot_bifurcation
    from hammerbit.studies.bifurcation import bifurcation
    g = _groups(args)
    lo, hi = args.range
    if args.num < 1:
        raise UsageError(f"--num {args.num}: allowed 1 or more")
    values = np.linspace(lo, hi, args.num)
    res = bifurcation(g, args.param, values, periods=args.periods, keep=args.keep, solver=_solver(args),
                      options=_executor_options(args))
    plot_bifurcation(res, args.out, preset=args.preset)
    if args.csv:
        res.to_csv(args.csv)
    summary = {"param": args.param, "num": args.num, "periods": args.periods,
               "wall_time_s": res.wall_time_s, "periods_per_second": res.periods_per_second,
               "workers": res.workers, "out": args.out, "csv": args.csv, "period_n": list(res.periods),
               "regime": [int(c) for c in res.regime], "regime_names": [regime_names(c) for c in res.regime]}
    _warn_flagged("bifurcation", summary["regime_names"], values)
    if args.json:
        print(_dump(summary))
    else:
        print(f"{args.num} values x {args.periods} periods in {res.wall_time_s:.2f} s "
              f"({res.periods_per_second:,.0f} periods/s, {res.workers} worker(s)); figure: {args.out}"
              + (f"; Poincaré points in SI (s, mm, m/s): {args.csv}" if args.csv else ""))
    return 0


def _warn_flagged(command: str, names: list, values, unit: str = "") -> None:
    """One stderr line per regime flag set somewhere in a study, with the values where it is."""
    for flag in REGIME_BITS:
        where = [float(v) for v, n in zip(values, names) if flag in n]
        if where:
            print(f"hammerbit {command}: warning: {flag} at {len(where)} value(s): "
                  + ", ".join(f"{v:g}{unit}" for v in where[:8]) + (" ..." if len(where) > 8 else ""),
                  file=sys.stderr)


# ---------------------------------------------------------------------------
# sweep
# ---------------------------------------------------------------------------
def cmd_sweep(args) -> int:
    from hammerbit.cli.cosim import config_from_args, fmu_arg, load_string_arg, portable_target_for_fmu
    portable_target_for_fmu(args)
    import numpy as np
    from hammerbit.cosim.linear_modes import coupled_modes
    from hammerbit.studies.sweep import plot_sweep, sweep, write_sweep_csv
    lo, hi, n = args.frequencies
    if not (0 < lo < hi) or n < 1 or n != int(n):
        raise UsageError(f"--frequencies {lo:g} {hi:g} {n:g}: need 0 < LO < HI and a whole N >= 1")
    n = int(n)
    freqs = np.linspace(lo, hi, n) if n > 1 else np.array([lo])
    # a fixed step (1 ms unless --step) without the error-estimate companion: one run per frequency
    cfg = config_from_args(args, stop=args.duration, progress=False, estimate=False,
                           **({} if args.step is not None else {"step": 1e-3}))
    string = load_string_arg(args)
    if args.step is None:
        # 1 ms, or the largest step that resolves this string and hammer
        from hammerbit.cosim.error import step_limits
        from hammerbit.cosim.string_side import StringSide
        H = min([cfg.step] + [lim.max_step_s for lim in step_limits(StringSide(string, cfg), cfg)])
        cfg = cfg.replace(step=H)
    t0 = time.perf_counter()
    res = sweep(string, freqs, cfg, fmu=fmu_arg(args), window_periods=args.window_periods,
                steady_tol=args.steady_tol, max_duration=args.max_duration,
                options=_executor_options(args))
    modes = coupled_modes(string, cfg, f_max=hi * 1.2)
    in_band = [float(f) for f in modes if lo <= f <= hi]
    i_pk = int(np.argmax(res["wob_amplitude_n"]))
    unsettled = [float(r["frequency_hz"]) for r in res if not r["steady"]]
    _warn_flagged("sweep", [regime_names(c & ~REGIME_TRANSIENT) for c in res["regime"]], freqs, unit=" Hz")
    out = {"string": string.name, "frequencies_hz": [float(f) for f in freqs],
           "duration_s": args.duration, "wall_time_s": time.perf_counter() - t0,
           "peak_frequency_hz": float(res["frequency_hz"][i_pk]),
           "peak_wob_amplitude_n": float(res["wob_amplitude_n"][i_pk]),
           "coupled_modes_hz": in_band, "not_settled_hz": unsettled,
           "rows": [{**{k: float(r[k]) for k in res.dtype.names}, "regime": int(r["regime"]),
                     "regime_names": regime_names(r["regime"])} for r in res]}
    if in_band:
        out["nearest_mode_to_peak_hz"] = min(in_band, key=lambda f: abs(f - out["peak_frequency_hz"]))
    if args.csv:
        write_sweep_csv(res, args.csv)
        out["csv"] = str(args.csv)
    if args.plot:
        plot_sweep(res, args.plot, modes=np.array(in_band),
                   title=f"{string.name}: hammer frequency sweep (A = {cfg.rig.amplitude:g} N)")
        out["plot"] = str(args.plot)
    if unsettled:
        print(f"hammerbit sweep: warning: the WOB amplitude did not settle within "
              f"{args.steady_tol:g} by {res['duration_s'].max():g} s at "
              + ", ".join(f"{f:g}" for f in unsettled) + " Hz (flag steady = 0)", file=sys.stderr)
    if args.json:
        print(_dump(out))
    else:
        for r in res:
            print(f"  {r['frequency_hz']:8.3f} Hz  WOB amplitude {r['wob_amplitude_n']:10.1f} N  "
                  f"bounce margin {r['bounce_margin']:7.3f}  ROP {r['rop_m_per_h']:8.4f} m/h  "
                  f"({r['duration_s']:g} s{'' if r['steady'] else ', not settled'})")
        print(f"peak dynamic WOB amplitude {out['peak_wob_amplitude_n']:.1f} N at "
              f"{out['peak_frequency_hz']:.3f} Hz; coupled natural frequencies (bit on bottom) in band: "
              + (", ".join(f"{f:.2f}" for f in in_band) or "none")
              + f"; {out['wall_time_s']:.1f} s")
    return 0


# ---------------------------------------------------------------------------
# map
# ---------------------------------------------------------------------------
def _overlay(args):
    """The curves of ``--overlay FILE`` (``hammerbit continue --json``), read before the map runs."""
    if not args.overlay:
        return None
    if not args.plot:
        raise UsageError("--overlay draws curves on the --plot figure: give --plot FILE too")
    check_input_file(args.overlay, "--overlay")
    from hammerbit.continuation.output import load_curves
    try:
        return load_curves(args.overlay)
    except ValueError as e:
        raise UsageError(f"--overlay {args.overlay}: {e}") from None


def cmd_map(args) -> int:
    from hammerbit.studies.map import FLAG_FIELDS, Axis, best_valid_cell, map_to_json, regime_map
    if not args.axis:
        raise UsageError("map needs at least one --axis NAME=LO:HI:N")
    if len(args.axis) > 3:
        raise UsageError(f"map takes 1 to 3 --axis options, got {len(args.axis)}")
    axes = [Axis.parse(a) for a in args.axis]
    overlay = _overlay(args)
    g = _groups(args)
    ds = regime_map(g, axes, periods=args.periods, solver=_solver(args), options=_executor_options(args),
                    attrs={"preset": args.preset, "settings": json.dumps(parse_settings(args.set))})
    if args.out:
        ds.to_netcdf(args.out, engine="scipy")
    if args.plot:
        from hammerbit.studies.plots import plot_map
        plot_map(ds, args.plot, overlay=overlay)
    failed = int(ds.attrs["failed_cells"])
    if failed:
        first = json.loads(ds.attrs["errors"])[:1]
        print(f"hammerbit map: warning: {failed} cell(s) did not run (status 1/2, NaN values): "
              + (first[0] if first else ""), file=sys.stderr)
    flagged = {f: int(ds[f].values.sum()) for f in FLAG_FIELDS if int(ds[f].values.sum())}
    if flagged:
        print("hammerbit map: warning: flagged cells (the regime verdict, docs/model.md): "
              + ", ".join(f"{f} {k}" for f, k in flagged.items()), file=sys.stderr)
    if args.json:
        d = map_to_json(ds)
        d.update({"preset": args.preset, "out": args.out, "plot": args.plot})
        print(_dump(d))
    else:
        import numpy as np
        per = ds["period"].values
        n = per.size
        counts = {}
        for v in per.ravel():
            key = "none" if not np.isfinite(v) else f"P{int(v)}"
            counts[key] = counts.get(key, 0) + 1
        order = sorted(counts, key=lambda k: (k == "none", int(k[1:]) if k != "none" else 0))
        counts["no period found"] = counts.pop("none", 0)
        order = ["no period found" if k == "none" else k for k in order]
        tp = ds.attrs["total_periods"]
        print(f"map of {args.preset} over " + " x ".join(f"{a.name} ({len(a.values)})" for a in axes)
              + f": {n} cells x {args.periods} periods in {ds.attrs['wall_time_s']:.2f} s "
              f"({tp / ds.attrs['wall_time_s']:,.0f} periods/s, {ds.attrs['workers']} worker(s))")
        print("period-n: " + ", ".join(f"{k} {counts[k]}" for k in order))
        best = best_valid_cell(ds)
        valid = int(ds["valid"].values.sum())
        if best is not None:
            where = ", ".join(f"{k}={v:g}" for k, v in best["values"].items())
            print(f"highest ROP of the {valid} valid cell(s) {best['rop_m_per_h']:.4g} m/h "
                  f"({best['rop_mm_per_period']:.4g} mm per period) at {where}")
        else:
            print("no valid cell (every cell runs away, bounces or did not run)")
        for f in FLAG_FIELDS:
            k = int(ds[f].values.sum())
            if k:
                print(f"flag {f}: {k} cell(s)")
        for f, rule in (("domain_a_ge_b", "a >= b"), ("domain_a_plus_b_gt_1", "a + b > 1"),
                        ("domain_b_gt_mu", "b > mu")):
            k = int(ds[f].values.sum())
            if k:
                print(f"outside the paper's domain ({rule}): {k} cell(s)")
        if args.out:
            print(f"wrote {args.out}")
        if args.plot:
            print(f"wrote {args.plot}")
    return 0


# ---------------------------------------------------------------------------
# optimize
# ---------------------------------------------------------------------------
def _default_bounds(g):
    from hammerbit.studies.optimize import Bound
    rig = g.to_rig()
    F0 = g.scales.friction_force
    return (Bound("frequency", 0.7 * rig.frequency, 1.3 * rig.frequency),
            Bound("amplitude", 0.05 * F0, 0.6 * F0))


def _confirm(groups, string, args) -> dict:
    """Co-simulate the optimum on the string with the auto-driller (:func:`hammerbit.studies.confirm.confirm`)."""
    from hammerbit.cli.cosim import fmu_arg
    from hammerbit.studies.confirm import confirm
    return confirm(groups, string, periods=args.confirm_periods, interface_stiffness=args.interface_stiffness,
                   interface_damping=args.interface_damping, fmu=fmu_arg(args))


def cmd_optimize(args) -> int:
    from hammerbit.drillstring import load_string
    from hammerbit.studies.optimize import Bound, OptimizeConfig, optimize
    g = _groups(args)
    bounds = tuple(Bound.parse(b) for b in args.bounds) if args.bounds else _default_bounds(g)
    string = load_string(args.string) if args.string else None
    cfg = OptimizeConfig(bounds=bounds, margin=args.margin,
                         max_contact_force=math.inf if args.max_contact_force is None
                         else args.max_contact_force,
                         periods=args.periods, grid=args.grid, solver=_solver(args))
    res = optimize(g, cfg, string=string, options=_executor_options(args))
    out = res.to_dict()
    out.update({"preset": args.preset, "string": None if string is None else string.name,
                "bounds": [{"name": b.name, "lo": b.lo, "hi": b.hi, "unit": b.unit} for b in bounds],
                "at_bounds": res.at_bounds(bounds)})
    if res.optimum is None:
        msg = (f"no feasible operating point on the {'x'.join(map(str, res.grid_shape))} grid within the "
               f"bounds (no bounce, a + b <= 1, no runaway in the scene's dynamics"
               + (", frequency check" if string is not None else "")
               + (", contact force" if args.max_contact_force is not None else "") + ")")
        if res.infeasible is not None:
            msg += f"; {res.infeasible.text()}"
        if args.json:
            print(_dump(out))
        raise RunFailure(msg, code=EXIT_INFEASIBLE)
    if out["optimum"].get("regime_names"):
        print("hammerbit optimize: warning: the optimum is flagged: " + ", ".join(out["optimum"]["regime_names"]),
              file=sys.stderr)
    if args.confirm:
        if string is None:
            raise UsageError("--confirm needs --string")
        out["confirm"] = _confirm(res.optimum.groups, string, args)
    if args.json:
        print(_dump(out))
        return 0
    o = out["optimum"]
    print(f"optimum of {args.preset}" + (f" on {string.name}" if string else "") + ": "
          f"frequency {o['frequency_hz']:.4g} Hz, amplitude {o['amplitude_n']:.4g} N, "
          f"preload {o['preload_n']:.4g} N (a={o['a']:.4g}, b={o['b']:.4g}, eta={o['eta']:.4g})")
    print(f"  period-{o['period'] if o['period'] else 'none'}, ROP {o['rop_m_per_h']:.4g} m/h "
          f"({o['rop_mm_per_period']:.4g} mm per period); best grid cell "
          f"{out['best_grid_cell']['rop_m_per_h']:.4g} m/h; {res.grid_feasible} feasible of "
          f"{'x'.join(map(str, res.grid_shape))} cells, {res.evaluations} evaluations")
    for name, side in out["at_bounds"].items():
        print(f"  {name} sits on its {side} bound: widen --bounds to look further")
    for k, m in o["margins"].items():
        if m["ok"] is None:
            print(f"  constraint {k}: not checked")
        elif m["margin"] is None:
            print(f"  constraint {k}: {'ok' if m['ok'] else 'VIOLATED'} (the scene's own dynamics)")
        else:
            unit = "" if m["unit"] == "relative" else f" {m['unit']}"
            if m["unit"] == "relative":
                val = (f"{100 * m['margin']:.3g} %" if math.isfinite(m["margin"])
                       else "no mode band within 0.25-4 x the frequency bounds")
            else:
                val = f"{m['margin']:.4g}{unit}"
            print(f"  constraint {k}: margin {val} ({'ok' if m['ok'] else 'VIOLATED'})")
    for r in out["runners_up"]:
        print(f"  runner-up period-{r['period'] if r['period'] else 'none'}: ROP {r['rop_m_per_h']:.4g} m/h "
              f"at frequency {r['frequency_hz']:.4g} Hz, amplitude {r['amplitude_n']:.4g} N, "
              f"preload {r['preload_n']:.4g} N")
    if "confirm" in out:
        cf = out["confirm"]
        print(f"  co-simulation on {string.name} ({cf['hammer']} hammer, hook on the auto-driller, "
              f"{cf['periods']} periods after {cf['settle_s']:.3g} s of settling): sustained ROP "
              f"{cf['rop_m_per_h']:.4g} m/h{'' if cf['rop_steady'] else ' (not steady)'} against the "
              f"optimizer's {o['rop_m_per_h']:.4g} m/h; dynamic WOB amplitude {cf['wob_amplitude_n']:.4g} N, "
              f"bounce margin {cf['bounce_margin']:.3g}")
    return 0


# ---------------------------------------------------------------------------
def register(subparsers) -> None:
    """Add ``bifurcation``, ``sweep``, ``map`` and ``optimize``."""
    p = subparsers.add_parser("bifurcation", help="bifurcation diagram over one parameter",
                              description="Poincaré points and period-n against one parameter "
                                          "(a group or an SI name).")
    _add_scene_args(p)
    p.add_argument("--param", default="a", help="parameter to sweep: a group or an SI name (default a)")
    p.add_argument("--range", nargs=2, type=float, required=True, metavar=("LO", "HI"),
                   help="first and last value of the parameter")
    p.add_argument("--num", type=int, default=100, help="number of values, evenly spaced over --range")
    p.add_argument("--periods", type=int, default=300, help="forcing periods per value")
    p.add_argument("--keep", type=int, default=64, help="Poincaré points kept per value")
    _add_executor_args(p)
    p.add_argument("--out", required=True, help="PNG file")
    p.add_argument("--csv", default=None, help="CSV of the Poincaré points")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=cmd_bifurcation)

    from hammerbit.cli.cosim import add_cosim_options
    p = subparsers.add_parser("sweep", help="frequency sweep of the co-simulated hammer on a string",
                              description="Steady dynamic WOB amplitude, bounce margin and rate of "
                                          "penetration against the hammer's excitation frequency.")
    add_cosim_options(p)
    p.add_argument("--frequencies", nargs=3, type=float, required=True, metavar=("LO", "HI", "N"),
                   help="LO HI [Hz] and the number of frequencies N")
    p.add_argument("--duration", type=float, default=1.5,
                   help="initial simulated time per frequency [s], doubled until the WOB amplitude "
                        "settles (default 1.5)")
    p.add_argument("--max-duration", type=float, default=12.0,
                   help="longest simulated time per frequency [s] (default 12)")
    p.add_argument("--window-periods", type=int, default=5,
                   help="forcing periods per steady-state window (default 5)")
    p.add_argument("--steady-tol", type=float, default=0.01,
                   help="allowed relative change of the WOB amplitude between the last two windows "
                        "(default 0.01)")
    _add_executor_args(p)
    p.add_argument("--plot", default=None, help="figure file (png, svg, pdf)")
    p.add_argument("--csv", default=None, help="CSV of the sweep")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=cmd_sweep)

    p = subparsers.add_parser("map", help="regime map: period-n, ROP and flags over 1-3 parameters",
                              description="One scene per cell of a grid over 1 to 3 parameters (groups "
                                          "or SI names): period-n, rate of penetration (x0 per period, "
                                          "mm per period, m/h), impacts per period, peak contact "
                                          "force, the scene's runaway/bounce/tension/transient flags and "
                                          "the paper's domain.")
    _add_scene_args(p)
    p.add_argument("--axis", action="append", default=[], metavar="NAME=LO:HI:N",
                   help="an axis (repeat for 2 or 3), e.g. a=0.05:0.25:81 or f=1.0:2.0:41")
    p.add_argument("--periods", type=int, default=300, help="forcing periods per cell (default 300)")
    _add_executor_args(p)
    p.add_argument("--out", default=None, help="netCDF file (xarray.open_dataset reads it)")
    p.add_argument("--plot", default=None, help="figure file: period map with ROP contours")
    p.add_argument("--overlay", default=None, metavar="CURVES.json",
                   help="draw the curves of `hammerbit continue --json` (--param2) over the --plot map")
    p.add_argument("--json", action="store_true", help="print the map as JSON")
    p.set_defaults(func=cmd_map)

    p = subparsers.add_parser("optimize", help="operating point of the highest ROP under the drilling "
                                               "constraints",
                              description="Maximise the ROP [m/h] over bounded parameters subject to no "
                                          "bounce and no runaway in the scene's dynamics, a + b <= 1, the "
                                          "string's frequency check and a limit on the peak contact force "
                                          "over the whole run: a grid, then a refinement that follows "
                                          "active constraints.")
    _add_scene_args(p, default_preset="lab")
    p.add_argument("--string", default=None, help="drillstring TOML file or example name (frequency check; "
                                                  "default: none, no frequency check)")
    p.add_argument("--bounds", nargs="+", default=None, metavar="NAME=LO:HI",
                   help="bounded variables, e.g. frequency=1.0:2.0 amplitude=3:30 (SI: Hz, N) or groups "
                        "(default: frequency 0.7-1.3 x the preset's, amplitude 0.05-0.6 F0)")
    p.add_argument("--margin", type=float, default=0.15,
                   help="frequency check: band half-width around each natural frequency (default 0.15)")
    p.add_argument("--max-contact-force", type=float, default=None, metavar="N",
                   help="largest allowed hammer-bit contact force [N] (default: no limit)")
    p.add_argument("--periods", type=int, default=200, help="forcing periods per evaluation (default 200)")
    p.add_argument("--grid", type=int, default=None,
                   help="grid points per variable (default 41 for one or two variables, 15 for three)")
    p.add_argument("--confirm", action="store_true",
                   help="co-simulate the optimum on the string with the hook on the auto-driller: the "
                        "sustained ROP beside the optimizer's, the dynamic WOB amplitude, the bounce margin")
    p.add_argument("--confirm-periods", type=int, default=20,
                   help="forcing periods of --confirm measured after the auto-driller settles (default 20)")
    p.add_argument("--fmu", default=None, help="--confirm with this hammer FMU (default: in process)")
    p.add_argument("--interface-stiffness", type=float, default=None,
                   help="--confirm: k_i between the string and the hammer [N/m] (default: the "
                        "co-simulation's)")
    p.add_argument("--interface-damping", type=float, default=None,
                   help="--confirm: c_i between the string and the hammer [N s/m] (default: the "
                        "co-simulation's, 2e3)")
    _add_executor_args(p)
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=cmd_optimize)
