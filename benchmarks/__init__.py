"""Benchmarks of hammerbit and the harness that runs them (``python -m benchmarks``).

Conventions every ``benchmarks/bench_*.py`` module follows
------------------------------------------------------------
* It exposes ``run(quick: bool = False) -> dict``.  ``quick=True`` is a fast,
  smaller run (seconds to a minute) for development and CI; the full run is
  what the README reports.
* Its result name is the module name without ``bench_`` (``bench_solvers`` ->
  ``solvers``).  ``run`` writes ``benchmarks/results/<name>.json`` (and, if it
  draws one, ``<name>.png``) through :func:`save_result`; if it does not, the
  harness writes the returned dict itself.
* The dict is JSON-serialisable and has at least:

  ``benchmark``
      the result name;
  ``quick``
      whether it was a quick run;
  ``command``
      the exact command that reproduces it (e.g.
      ``python -m benchmarks --only solvers``);
  ``machine``
      :func:`machine_info` (CPU count and model, load average, Python, numpy,
      numba, scipy versions ...);
  ``summary``
      a list of rows for the README's performance table, each made by
      :func:`summary_row`: ``{metric, ours, peer, ratio, goal, met, command}``.
      ``ours``/``peer``/``ratio`` are display strings with units (the raw
      numbers live elsewhere in the dict); ``peer``, ``ratio``, ``goal`` may be
      ``None`` and ``met`` is ``True``/``False``/``None`` (no goal).

* Every number is measured in that run; nothing is hard-coded.  Timings are
  the minimum over a few repeats and exclude numba compilation (warm up first).
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import sys
import tempfile
import time

__all__ = ["RESULTS_DIR", "REPO_ROOT", "TRACKED_RESULTS_DIR", "TRACKED_FIGURES_DIR", "SCRATCH_DIR",
           "configure_output", "results_dir", "figures_dir", "machine_info", "summary_row", "save_result",
           "fmt_time", "fmt_ratio", "fmt_num", "harness_command", "result_name", "kernel_source",
           "repo_on_path", "LoadedFMU"]

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(BENCH_DIR)
#: The tracked results (``benchmarks/results``) and figures (``docs/figures``):
#: written only when asked (``python -m benchmarks --update``).
TRACKED_RESULTS_DIR = os.path.join(BENCH_DIR, "results")
TRACKED_FIGURES_DIR = os.path.join(REPO_ROOT, "docs", "figures")
#: Where a run writes otherwise: ``$HAMMERBIT_BENCH_OUT`` or a directory in the system's temp dir.
SCRATCH_DIR = os.environ.get("HAMMERBIT_BENCH_OUT") or os.path.join(tempfile.gettempdir(), "hammerbit-benchmarks")
#: Where :func:`save_result` writes now (see :func:`configure_output`).
RESULTS_DIR = os.path.join(SCRATCH_DIR, "results")
FIGURES_DIR = os.path.join(SCRATCH_DIR, "figures")
UPDATE = False


def configure_output(update: bool) -> str:
    """Point the benchmarks' outputs at the tracked files (``update=True``) or the scratch dir.

    Returns the results directory now in use.  Benchmarks write their JSON and
    PNG through :func:`save_result` and their figures into :func:`figures_dir`,
    so nothing tracked changes unless a run is asked to update.
    """
    global RESULTS_DIR, FIGURES_DIR, UPDATE
    UPDATE = bool(update)
    RESULTS_DIR = TRACKED_RESULTS_DIR if UPDATE else os.path.join(SCRATCH_DIR, "results")
    FIGURES_DIR = TRACKED_FIGURES_DIR if UPDATE else os.path.join(SCRATCH_DIR, "figures")
    return RESULTS_DIR


def results_dir() -> str:
    """The directory :func:`save_result` writes into now."""
    return RESULTS_DIR


def figures_dir() -> str:
    """Where benchmarks that draw the documentation's figures write them now (created)."""
    os.makedirs(FIGURES_DIR, exist_ok=True)
    return FIGURES_DIR


def repo_on_path() -> None:
    """Put the repository root on ``sys.path`` (once) for its top-level modules (``build_fmu``)."""
    if REPO_ROOT not in sys.path:
        sys.path.insert(0, REPO_ROOT)


def result_name(module_name: str) -> str:
    """Result name of a benchmark module: ``benchmarks.bench_solvers`` -> ``solvers``."""
    base = module_name.rsplit(".", 1)[-1]
    return base[len("bench_"):] if base.startswith("bench_") else base


def harness_command(name: str, quick: bool) -> str:
    """The command that reproduces one benchmark's results."""
    return f"python -m benchmarks --only {name}" + (" --quick" if quick else "")


def _cpu_model() -> str | None:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def machine_info() -> dict:
    """Machine and library versions, for every results JSON.

    Returns
    -------
    dict
        ``cpu_count``, ``cpu_affinity`` (usable cores), ``cpu_model``,
        ``load_average`` (1, 5, 15 min at call time: the machine may be
        shared), ``platform``, ``python``, and versions of numpy, numba, scipy
        and hammerbit.
    """
    info = {
        "cpu_count": os.cpu_count(),
        "cpu_model": _cpu_model(),
        "platform": platform.platform(),
        "python": sys.version.split()[0],
        "timestamp": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    try:
        info["cpu_affinity"] = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        info["cpu_affinity"] = None
    try:
        info["load_average"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        info["load_average"] = None
    for mod in ("numpy", "numba", "scipy", "matplotlib", "fmpy"):
        try:
            m = __import__(mod)
            info[mod] = getattr(m, "__version__", "?")
        except Exception:  # pragma: no cover - optional
            info[mod] = None
    try:
        from importlib.metadata import version
        info["hammerbit"] = version("hammerbit")
    except Exception:  # pragma: no cover
        info["hammerbit"] = None
    return info


def kernel_source() -> dict:
    """Where this process got its compiled kernels: loaded from the on-disk cache or compiled.

    Call after the kernels ran once.  The two run at different speeds on some
    machines, so every timing result should record it.
    """
    try:
        from hammerbit.model import kernel_driver, numba_cache
    except Exception:  # pragma: no cover
        return {"source": None}
    out = {"cache_dir": numba_cache.cache_root(), "functions": {}}
    for name in (*kernel_driver.HAMMER_ENTRY.values(), "advance"):
        d = getattr(kernel_driver, name, None)
        if d is None or not getattr(d, "signatures", None):
            continue
        hits = sum(d.stats.cache_hits.values())
        misses = sum(d.stats.cache_misses.values())
        out["functions"][name] = {"cache_hits": hits, "cache_misses": misses}
    hits = sum(v["cache_hits"] for v in out["functions"].values())
    miss = sum(v["cache_misses"] for v in out["functions"].values())
    out["source"] = ("cache" if hits and not miss else "compiled" if miss and not hits
                     else "mixed" if hits else None)
    return out


def summary_row(metric: str, ours, *, peer=None, ratio=None, goal=None, met=None,
                command: str = "") -> dict:
    """One row of the README performance table.

    Parameters
    ----------
    metric : str
        What is measured, with the scene (e.g. ``"work-precision, no impact:
        time at rel. error 1e-8"``).
    ours, peer, ratio : str or None
        Display values with units (use :func:`fmt_time`, :func:`fmt_ratio`).
    goal : str or None
        The goal as stated in the issue (e.g. ``">= 300x"``).
    met : bool or None
        Whether the goal is met in this run (None: no goal / not decidable).
    command : str
        Command that reproduces the number.
    """
    return {"metric": metric, "ours": ours, "peer": peer, "ratio": ratio, "goal": goal,
            "met": None if met is None else bool(met), "command": command}


def fmt_num(x, digits: int = 3) -> str:
    """A number with ``digits`` significant digits ('n/a' for None/NaN)."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}"


def fmt_time(s) -> str:
    """Seconds as a readable string with units (µs, ms, s)."""
    if s is None or not math.isfinite(s):
        return "n/a"
    if s < 1e-3:
        return f"{s * 1e6:.3g} µs"
    if s < 1.0:
        return f"{s * 1e3:.3g} ms"
    return f"{s:.3g} s"


def fmt_ratio(r) -> str:
    """A speed ratio as ``'123x'``."""
    if r is None or not math.isfinite(r):
        return "n/a"
    return f"{r:.3g}x" if r < 10 else f"{r:.0f}x"


def _jsonable(o):
    """Make numpy scalars/arrays and non-finite floats JSON-safe."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        np = None
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if np is not None:
        if isinstance(o, np.ndarray):
            return _jsonable(o.tolist())
        if isinstance(o, np.generic):
            return _jsonable(o.item())
    if isinstance(o, float) and not math.isfinite(o):
        return None if math.isnan(o) else ("inf" if o > 0 else "-inf")
    return o


def save_result(name: str, result: dict, fig=None) -> str:
    """Write ``<name>.json`` (and ``<name>.png`` if a figure is given) into :func:`results_dir`.

    Parameters
    ----------
    name : str
        Result name (module name without ``bench_``).
    result : dict
        The benchmark's result; numpy values and non-finite floats are converted.
        ``benchmark`` (``name``) and ``machine`` (:func:`machine_info`) are
        added when missing.
    fig : matplotlib.figure.Figure, optional
        Saved as ``results/<name>.png`` (150 dpi) and closed.

    Returns
    -------
    str
        Path of the JSON file.
    """
    result.setdefault("benchmark", name)
    result.setdefault("machine", machine_info())
    os.makedirs(RESULTS_DIR, exist_ok=True)
    if fig is not None:
        png = os.path.join(RESULTS_DIR, f"{name}.png")
        fig.savefig(png, dpi=150, bbox_inches="tight")
        import matplotlib.pyplot as plt
        plt.close(fig)
        inside = os.path.commonpath([os.path.abspath(png), REPO_ROOT]) == REPO_ROOT
        result.setdefault("png", os.path.relpath(png, REPO_ROOT) if inside else png)
    path = os.path.join(RESULTS_DIR, f"{name}.json")
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(_jsonable(result), fh, indent=1, allow_nan=False)
        fh.write("\n")
    os.replace(tmp, path)
    return path


def standalone(run, doc: str) -> None:
    """``python benchmarks/bench_X.py [--quick]``: run one benchmark and print its summary rows."""
    import argparse
    ap = argparse.ArgumentParser(description=(doc or "").strip().splitlines()[0] if doc else None)
    ap.add_argument("--quick", action="store_true", help="short runs")
    ap.add_argument("--update", action="store_true",
                    help="write benchmarks/results (tracked); default: the scratch dir " + SCRATCH_DIR)
    a = ap.parse_args()
    configure_output(a.update)
    res = run(quick=a.quick)
    print(f"results in {RESULTS_DIR}", file=sys.stderr)
    for row in res["summary"]:
        print(f"{row['metric']}: {row['ours']} (peer {row.get('peer')}, ratio {row.get('ratio')}, "
              f"goal {row.get('goal')})")


def stage_logger(name: str, verbose: bool):
    """``log(msg)`` printing ``  name: msg`` to stderr when ``verbose``."""
    def log(msg):
        if verbose:
            print(f"  {name}: {msg}", file=sys.stderr, flush=True)
    return log


class LoadedFMU:
    """An FMU loaded and initialised through the project's loader (:class:`hammerbit.fmu.host.FMUInstance`).

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file; extracted into a temporary directory that
        :meth:`close` removes.
    name : str
        Instance name.
    reals : dict, optional
        ``{variable: value}`` set between entering and leaving initialisation mode.
    """

    def __init__(self, path, name, reals=None):
        from hammerbit.fmu.host import FMUInstance
        self.host = FMUInstance(path, name, reals=reals, logging=False)
        self.vr, self.fmu, self.dir = self.host.vr, self.host.fmu, self.host.dir
        self.n = 0

    def loop(self, n, vin, value, vout, h):
        """n steps of setReal(1) + doStep(h) + getReal(len(vout)), continuing the time grid; seconds per step."""
        setReal, doStep, getReal = self.fmu.setReal, self.fmu.doStep, self.fmu.getReal
        vin, vals = [vin], [value]
        k0 = self.n
        t0 = time.perf_counter()
        for k in range(k0, k0 + n):
            setReal(vin, vals)
            doStep(k * h, h)
            getReal(vout)
        dt = time.perf_counter() - t0
        self.n = k0 + n
        return dt / n

    def close(self):
        self.host.close()


_TRIVIAL_SLAVE = '''
from pythonfmu import Fmi2Slave, Fmi2Causality, Fmi2Variability, Real


class TrivialFloor(Fmi2Slave):
    author = "hammerbit benchmarks"
    description = "FMI call floor: input u, outputs y0..y{last}; do_step does nothing"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        for i in range({n}):
            setattr(self, f"y{{i}}", 0.0)
            self.register_variable(Real(f"y{{i}}", causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous))

    def do_step(self, current_time, step_size):
        return True
'''


def build_trivial_fmu(dest, n_outputs: int = 1):
    """Build the trivial pythonfmu FMU (the FMI call floor) into ``dest``.

    One input ``u`` and ``n_outputs`` outputs ``y0 .. y{n-1}``; its ``do_step``
    does nothing, so stepping it measures only the FMI/pythonfmu/fmpy calls.
    """
    from pathlib import Path
    from hammerbit.fmu.build import pythonfmu_builder
    FmuBuilder = pythonfmu_builder()       # the installed pythonfmu, not an FMU's copy
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    script = dest / "trivialfloor.py"
    script.write_text(_TRIVIAL_SLAVE.format(n=int(n_outputs), last=int(n_outputs) - 1))
    try:
        return Path(FmuBuilder.build_FMU(script, dest=dest))
    finally:
        sys.modules.pop("trivialfloor", None)
