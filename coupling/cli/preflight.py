"""What every ``hammerbit`` command checks before its run, and errors put in the user's words.

:func:`preflight` runs before each command (:func:`hammerbit.cli.common.run_command`):
the input files (a directory or a file that is not UTF-8 is refused), every
output file (:data:`OUTPUTS`: format, directory, writability), ``--workers``,
the names of ``--param`` and ``--bounds``, and the size of the request
(``map`` cells, ``simulate --periods``, ``cosim --stop``): a request that
cannot fit is refused with exit code 2 before anything is allocated.

:func:`apply_user_settings` applies ``--set`` and, when a value the user typed
in SI pushes a derived group out of its range, names the SI parameter as typed
with its allowed range in SI.  :func:`in_user_words` turns errors raised deep
in a run (a mesh too fine for the limit) into the option that caused them.
"""
from __future__ import annotations

import math
import os

from hammerbit.cli.common import (NETCDF_SUFFIXES, UsageError, check_fits, check_input_file,
                                  check_output, check_workers)

__all__ = ["OUTPUTS", "FIGURE_FORMATS", "preflight", "apply_user_settings", "in_user_words", "known_name",
           "BYTES_PER_MAP_CELL", "CPU_SECONDS_PER_PERIOD", "BYTES_PER_POINCARE_POINT",
           "BYTES_PER_COSIM_SAMPLE", "CPU_SECONDS_PER_MACRO_STEP"]

#: Stands for the figure formats of this install's matplotlib (imported only when a figure is asked for).
FIGURE_FORMATS = "figure"

#: (command, dest) -> (option as typed, allowed extensions, :data:`FIGURE_FORMATS`, or None for any).
OUTPUTS = {
    ("simulate", "plot"): ("--plot", FIGURE_FORMATS),
    ("simulate", "csv"): ("--csv", None),
    ("bifurcation", "out"): ("--out", FIGURE_FORMATS),
    ("bifurcation", "csv"): ("--csv", None),
    ("map", "out"): ("--out", NETCDF_SUFFIXES),
    ("map", "plot"): ("--plot", FIGURE_FORMATS),
    ("sweep", "plot"): ("--plot", FIGURE_FORMATS),
    ("sweep", "csv"): ("--csv", None),
    ("check", "plot"): ("--plot", FIGURE_FORMATS),
    ("modes", "csv"): ("--csv", None),
    ("cosim", "out"): ("--out", None),
}

#: Memory of one ``map`` cell: the result variables and the task's Python objects (generous).
BYTES_PER_MAP_CELL = 4096
#: CPU time of one forcing period of a scene (the adaptive solver, a generous mean).
CPU_SECONDS_PER_PERIOD = 2e-4
#: Memory of one Poincaré point of ``simulate`` (5 float64) and its share of the analysis.
BYTES_PER_POINCARE_POINT = 80
#: Memory of one recorded co-simulation sample (time + 9 variables, float64, run and companion).
BYTES_PER_COSIM_SAMPLE = 2 * 10 * 8
#: CPU time of one co-simulation macro step (hammer and string, with the error companion).
CPU_SECONDS_PER_MACRO_STEP = 1e-4
#: How :func:`hammerbit.model.params.setting_target` starts the list of the names it takes.
_UNKNOWN = "a known name: "
#: The sampling interval of ``cosim`` when --step is not given [s] (its first step, 1 ms).
DEFAULT_COSIM_STEP = 1e-3


def _string_names() -> tuple:
    from hammerbit.drillstring import example_names
    return tuple(example_names())


def known_name(name: str, option: str) -> None:
    """Refuse a parameter name ``--set`` would not take, listing the ones it takes (exit 2)."""
    from hammerbit.model.settings import setting_target
    from hammerbit.model.validation import ParameterError
    try:
        setting_target(name)
    except ParameterError as e:
        raise UsageError(f"{option} {name}: unknown name; allowed: {e.allowed[len(_UNKNOWN):]}") from None


def preflight(args) -> None:
    """Check the request ``args`` of any command before its run (see the module docs)."""
    cmd = getattr(args, "command", None)
    if cmd in ("fmu", "ssp"):
        _build_cache_switch()
    if cmd == "fmu":
        _fmu_out(getattr(args, "out", None))
        return
    if getattr(args, "string", None) is not None:
        check_input_file(args.string, "--string", names=_string_names())
    fmu = getattr(args, "fmu", None)
    if isinstance(fmu, str) and os.path.isdir(os.path.expanduser(fmu)):
        raise UsageError(f"--fmu {fmu}: is a directory, not an FMU file (build one with `hammerbit fmu build`)")
    for (command, dest), (option, formats) in OUTPUTS.items():
        value = getattr(args, dest, None)
        if command == cmd and value is not None:
            check_output(value, option, formats=_formats(formats, cmd))
    check_workers(getattr(args, "workers", None))
    check = _CHECKS.get(cmd)
    if check is not None:
        check(args)


def _build_cache_switch() -> None:
    """The commands that build FMUs refuse a bad ``HAMMERBIT_BUILD_CACHE`` as a usage error."""
    from hammerbit.fmu.compile_cache import cache_enabled
    try:
        cache_enabled()
    except ValueError as e:
        raise UsageError(str(e)) from None


def _formats(formats, cmd):
    """The allowed extensions; figures: matplotlib's, except for ``simulate``, whose figure
    process reports them while this one loads the solver (it checks them itself before the run)."""
    if formats != FIGURE_FORMATS:
        return formats
    if cmd == "simulate":
        return None
    from hammerbit.scene.figure_worker import figure_formats
    return frozenset(figure_formats())


def _fmu_out(out) -> None:
    """``fmu build --out``: an existing directory (the FMU goes in it) or a file ending in .fmu."""
    if out is None or os.path.isdir(os.path.expanduser(str(out))):
        return
    check_output(out, "--out", formats=frozenset({"fmu"}))


def _simulate(args) -> None:
    periods = args.periods
    if periods is None or not (isinstance(periods, int) and periods > 0):
        return                                  # the command's own check names the range
    check_fits(f"--periods {periods}", bytes_needed=periods * BYTES_PER_POINCARE_POINT,
               cpu_seconds=periods * CPU_SECONDS_PER_PERIOD, hint="use fewer --periods")


def _map(args) -> None:
    cells, counts = 1, []
    for text in args.axis or []:
        spec = text.split("=", 1)[-1].split(":")
        if len(spec) == 3 and spec[2].strip().isdigit():
            counts.append(int(spec[2]))
            cells *= max(1, int(spec[2]))
    for text in args.axis or []:
        if "=" in text:
            known_name(text.split("=", 1)[0].strip(), "--axis")
    if not counts:
        return
    typed = " ".join(f"--axis {a}" for a in args.axis)
    check_fits(f"{typed} ({cells:,} cells)", bytes_needed=cells * BYTES_PER_MAP_CELL,
               cpu_seconds=cells * max(args.periods, 1) * CPU_SECONDS_PER_PERIOD,
               hint="use fewer values per --axis")


def _cosim(args) -> None:
    stop, step = args.stop, args.step or DEFAULT_COSIM_STEP
    if not (isinstance(stop, float) and math.isfinite(stop) and stop > 0 and step > 0):
        return                                  # CosimConfig names the range
    n = stop / step
    check_fits(f"--stop {stop:g}" + (f" --step {args.step:g}" if args.step else ""),
               bytes_needed=n * BYTES_PER_COSIM_SAMPLE, cpu_seconds=n * CPU_SECONDS_PER_MACRO_STEP,
               hint="simulate less time (--stop) or sample more coarsely (--step)")


def _bifurcation(args) -> None:
    from hammerbit.cli.common import parse_settings
    from hammerbit.model.presets import preset
    from hammerbit.model.validation import ParameterError
    known_name(args.param, "--param")
    if args.num > 0 and args.periods > 0 and args.keep > 0:
        check_fits(f"--num {args.num} --periods {args.periods} --keep {args.keep}",
                   bytes_needed=args.num * (args.keep * BYTES_PER_POINCARE_POINT + BYTES_PER_MAP_CELL),
                   cpu_seconds=args.num * args.periods * CPU_SECONDS_PER_PERIOD,
                   hint="use fewer values (--num), periods or kept points (--keep)")
    base = apply_user_settings(preset(args.preset), parse_settings(args.set))
    for v in args.range:
        try:
            apply_user_settings(base, {args.param: v})
        except ParameterError as e:
            raise ParameterError(f"--param {args.param} --range", v, e.allowed) from None


def _optimize(args) -> None:
    from hammerbit.cli.common import parse_settings
    from hammerbit.model.presets import preset
    from hammerbit.model.validation import ParameterError
    from hammerbit.studies.optimize import DEFAULT_GRID
    n_vars = min(max(1, len(args.bounds or ()) or 2), max(DEFAULT_GRID))
    grid = DEFAULT_GRID[n_vars] if args.grid is None else args.grid
    if grid > 0 and args.periods > 0:
        cells = grid ** n_vars
        check_fits(f"--grid {grid} ({cells:,} cells over the bounded variables)",
                   bytes_needed=cells * BYTES_PER_MAP_CELL,
                   cpu_seconds=cells * args.periods * CPU_SECONDS_PER_PERIOD,
                   hint="use a coarser --grid (the local refinement finds the optimum between cells)")
    base = None
    for text in args.bounds or []:
        if "=" not in text:
            continue
        name, spec = (s.strip() for s in text.split("=", 1))
        known_name(name, "--bounds")
        try:
            ends = [float(v) for v in spec.split(":")]
        except ValueError:
            continue                            # the command's own parser names the format
        if base is None:
            base = apply_user_settings(preset(args.preset), parse_settings(args.set))
        for v in ends:
            try:
                apply_user_settings(base, {name: v})
            except ParameterError as e:
                raise ParameterError(f"--bounds {name}", v, e.allowed) from None


def _sweep(args) -> None:
    lo, hi, n = args.frequencies
    step = args.step or DEFAULT_COSIM_STEP
    if not (n >= 1 and n == int(n) and 0 < lo < hi and step > 0 and args.max_duration > 0):
        return                                  # the command's own check names the range
    steps = int(n) * args.max_duration / step
    check_fits(f"--frequencies {lo:g} {hi:g} {int(n)} --max-duration {args.max_duration:g}",
               bytes_needed=int(n) * BYTES_PER_MAP_CELL, cpu_seconds=steps * CPU_SECONDS_PER_MACRO_STEP,
               hint="use fewer frequencies or a shorter --max-duration")


def _check(args) -> None:
    """``check --rpm-range``: in rev/min, the limit of the frequency range converted with --factor."""
    from hammerbit.model.validation import RANGES, ParameterError
    if not args.rpm_range:
        return
    factor = args.factor if args.factor and args.factor > 0 else 1.0
    hz = RANGES["check.range"]
    hi = hz.hi * 60.0 / factor
    for end, v in zip(("LO", "HI"), args.rpm_range):
        if not (math.isfinite(v) and 0.0 <= v <= hi):
            raise ParameterError(f"--rpm-range {end}", v, f"[0, {hi:g}] rev/min (the frequency range "
                                                         f"[{hz.lo:g}, {hz.hi:g}] Hz at --factor {factor:g})")


_CHECKS = {"check": _check, "simulate": _simulate, "map": _map, "cosim": _cosim, "bifurcation": _bifurcation,
           "optimize": _optimize, "sweep": _sweep}


# ---------------------------------------------------------------------------
# --set in the user's words
# ---------------------------------------------------------------------------
#: Bisection steps for the edge of an SI range (a relative resolution far below the 4 digits shown).
_BISECTION_STEPS = 80


def apply_user_settings(base, settings: dict):
    """:func:`hammerbit.model.settings.apply_settings`, with errors naming what was typed.

    When an SI value (``A=1e9``) is within its own range but makes a derived
    group (``a``) leave its range, the error names the SI parameter as typed,
    its value, and the range of that parameter that the groups allow at the
    other values of this scene, in its SI unit.
    """
    from hammerbit.model.settings import apply_settings
    from hammerbit.model.validation import ParameterError
    try:
        return apply_settings(base, settings)
    except ParameterError as err:
        if err.name in settings:
            raise
        culprit = _culprit(base, settings)
        if culprit is None:
            raise
        raise _si_range_error(base, settings, culprit, err) from None


def _ok(base, settings) -> bool:
    from hammerbit.model.settings import apply_settings
    from hammerbit.model.validation import ParameterError
    try:
        apply_settings(base, settings)
        return True
    except ParameterError:
        return False


def _culprit(base, settings):
    """The SI name typed last whose value alone (with the others) makes the settings fail."""
    from hammerbit.model.settings import setting_target
    for key in reversed(list(settings)):
        if setting_target(key)[0] == "group":
            continue
        others = {k: v for k, v in settings.items() if k != key}
        if _ok(base, others):
            return key
    return None


def _si_range_error(base, settings, key, err):
    from hammerbit.model.settings import apply_settings, setting_target
    from hammerbit.model.validation import RANGES, ParameterError
    field = setting_target(key)[1]
    others = {k: v for k, v in settings.items() if k != key}
    rng = RANGES[field]
    good = float(getattr(apply_settings(base, others).to_rig(), field))
    bad = float(settings[key])

    def edge(inside, outside):
        for _ in range(_BISECTION_STEPS):
            if inside > 0 and outside > 0:
                mid = math.sqrt(inside * outside)
            else:
                mid = 0.5 * (inside + outside)
            if mid in (inside, outside):
                break
            if _ok(base, {**others, key: mid}):
                inside = mid
            else:
                outside = mid
        return inside

    far = rng.hi if bad < good else rng.lo          # the other side, up to the parameter's own range
    limit_bad = edge(good, bad)
    limit_far = far if _ok(base, {**others, key: far}) else edge(good, far)
    lo, hi = sorted((limit_bad, limit_far))
    unit = f" {rng.unit}" if rng.unit and rng.unit != "1" else ""
    return ParameterError(key, settings[key],
                          f"[{lo:.4g}, {hi:.4g}]{unit} with the other parameters of this scene "
                          f"(it sets the group {err.name!r} = {_num(err.value)}, allowed {err.allowed})")


def _num(v) -> str:
    try:
        return f"{float(v):.6g}"
    except (TypeError, ValueError):
        return str(v)


# ---------------------------------------------------------------------------
# errors raised in a run, put in the words of the option that caused them
# ---------------------------------------------------------------------------
def in_user_words(exc: BaseException, args) -> BaseException:
    """``exc`` rephrased for the user where the run knows better than the library what was typed."""
    from hammerbit.drillstring import DrillStringError
    if isinstance(exc, DrillStringError) and exc.key == "elements":
        option = _mesh_option(args)
        if option:
            return UsageError(f"{option}: needs {exc.value:,} finite elements in {exc.where}, above the "
                              f"limit ({exc.allowed}); ask for less (fewer or lower modes, a narrower "
                              f"range) or a looser --rtol")
    from hammerbit.model.validation import ParameterError
    if isinstance(exc, ParameterError):
        if str(exc.allowed).startswith(_UNKNOWN):
            return UsageError(f"unknown name {exc.name!r}; allowed: {exc.allowed[len(_UNKNOWN):]}")
        if getattr(args, str(exc.name), None) is not None:      # a config field set by its option
            return exc.renamed("--" + str(exc.name).replace("_", "-"))
    if isinstance(exc, UnicodeDecodeError):
        return UsageError(f"an input file is not UTF-8 text: {exc.reason} at offset {exc.start}")
    return exc


def _mesh_option(args) -> str:
    """The options that set how fine ``modes`` or ``check`` mesh the string, as typed."""
    cmd = getattr(args, "command", None)
    parts = []
    if cmd == "modes":
        if getattr(args, "fmax", None) is not None:
            parts.append(f"--fmax {args.fmax:g}")
        if getattr(args, "count", None) is not None:
            parts.append(f"--count {args.count}")
    elif cmd == "check":
        if getattr(args, "range", None):
            parts.append("--range " + " ".join(f"{v:g}" for v in args.range))
        elif getattr(args, "rpm_range", None):
            parts.append("--rpm-range " + " ".join(f"{v:g}" for v in args.rpm_range))
        elif getattr(args, "frequency", None) is not None:
            parts.append(f"--frequency {args.frequency:g}")
    else:
        return ""
    rtol = getattr(args, "rtol", None)
    from hammerbit.drillstring import DEFAULT_RTOL
    if rtol is not None and rtol != DEFAULT_RTOL:
        parts.append(f"--rtol {rtol:g}")
    return " ".join(parts) or "--rtol"
