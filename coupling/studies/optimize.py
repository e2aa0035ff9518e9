"""The operating point of the highest rate of penetration (the paper's section 8).

:func:`optimize` maximises the ROP in SI [m/h] over bounded parameters
(typically the hammer's frequency, amplitude and preload) subject to

* **no bounce**: ``a < b`` (the harmonic force never exceeds the preload);
* **static threshold**: ``a + b <= 1`` (preload plus amplitude below
  ``F0 = mu_e F_N``, the paper's domain);
* **no runaway**: the preload stays below the kinetic friction floor
  (:func:`hammerbit.model.regime.regime`);
* **frequency check**: with a drillstring, the hammer frequency lies in a
  window where :func:`hammerbit.check.frequency.check` passes robustly (bit on
  and off bottom, over the check's damping range);
* **contact force**: the peak hammer-bit contact force stays below a limit.

The ROP landscape is piecewise smooth, with steps where the period-n of the
motion changes.  A global stage evaluates a grid (``grid`` points per
variable) through the study executor; a local stage (Nelder-Mead, bounded,
:func:`scipy.optimize.minimize`) refines from the best feasible cells.  A
refined point replaces its start only when it is feasible and better, so
the optimum is never below the best feasible grid cell.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hammerbit.model.params import Groups
from hammerbit.model.regime import regime
from hammerbit.model.settings import apply_settings, setting_target
from hammerbit.model.validation import ParameterError
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.solver_options import SolverOptions

from .executor import Executor, ExecutorOptions
from .map import STATUS_OK, Axis, map_chunk, axis_unit, run_cell
from .bifurcation import SECONDS_PER_PERIOD

__all__ = ["Bound", "OptimizeConfig", "Candidate", "OptimizeResult", "optimize", "frequency_windows"]


@dataclass(frozen=True)
class Bound:
    """A bounded variable: a parameter name (group or SI, as typed) and its range."""

    name: str
    lo: float
    hi: float

    def __post_init__(self):
        setting_target(self.name, self.lo)
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and self.lo < self.hi):
            raise ParameterError(f"--bounds {self.name}", f"{self.lo}:{self.hi}", "finite LO < HI")

    @classmethod
    def parse(cls, text: str) -> "Bound":
        """``"frequency=1.0:2.0"`` -> Bound("frequency", 1.0, 2.0)."""
        if "=" not in text or text.count(":") != 1:
            raise ParameterError("--bounds", text, "NAME=LO:HI")
        name, spec = (s.strip() for s in text.split("=", 1))
        lo, hi = spec.split(":")
        try:
            return cls(name, float(lo), float(hi))
        except ValueError:
            raise ParameterError(f"--bounds {name}", spec, "LO:HI with numbers LO < HI") from None

    @property
    def unit(self) -> str:
        return axis_unit(self.name)


@dataclass(frozen=True, kw_only=True)
class OptimizeConfig:
    """Options of :func:`optimize` (keyword-only).

    Attributes
    ----------
    bounds : tuple of Bound
        The variables (1 to 3) and their ranges.
    margin : float
        Frequency-check band half-width around each natural frequency [-].
    max_contact_force : float
        Largest allowed hammer-bit contact force [N] (inf: no limit).
    periods : int
        Forcing periods per evaluation, from rest; the ROP is the mean over
        the second half.
    grid : int
        Grid points per variable of the global stage (default 21).
    starts : int
        Best feasible grid cells refined locally.
    max_evaluations : int
        Scene evaluations per local refinement.
    solver : SolverOptions
    """

    bounds: tuple
    margin: float = 0.15
    max_contact_force: float = math.inf
    periods: int = 200
    grid: int = 21
    starts: int = 3
    max_evaluations: int = 60
    solver: SolverOptions = field(default_factory=SolverOptions)

    def __post_init__(self):
        b = tuple(self.bounds)
        object.__setattr__(self, "bounds", b)
        if not 1 <= len(b) <= 3:
            raise ParameterError("bounds", len(b), "1 to 3 bounded variables")
        targets = [setting_target(x.name) for x in b]
        if len(set(targets)) != len(targets):
            raise ParameterError("bounds", ",".join(x.name for x in b), "distinct parameters")
        if not 0 < self.margin < 1:
            raise ParameterError("margin", self.margin, "(0, 1)")
        if not self.max_contact_force > 0:
            raise ParameterError("max_contact_force", self.max_contact_force, "> 0 N")
        if not (isinstance(self.periods, int) and 4 <= self.periods <= 100_000):
            raise ParameterError("periods", self.periods, "an integer in [4, 100000]")
        if not (isinstance(self.grid, int) and 2 <= self.grid <= 201):
            raise ParameterError("grid", self.grid, "an integer in [2, 201]")
        if not (isinstance(self.starts, int) and self.starts >= 0):
            raise ParameterError("starts", self.starts, "an integer >= 0")


@dataclass(frozen=True)
class Candidate:
    """One evaluated operating point."""

    values: dict
    """The variables as given (SI or groups)."""
    groups: Groups
    period: Optional[int]
    rop_m_per_h: float
    rop_mm_per_period: float
    peak_contact_force_n: float
    margins: dict
    """Constraint -> margin (>= 0 feasible; units in :data:`MARGIN_UNITS`); None when not checked."""
    feasible: bool

    def to_dict(self) -> dict:
        rig = self.groups.to_rig()
        return {"values": self.values, "frequency_hz": rig.frequency, "amplitude_n": rig.amplitude,
                "preload_n": rig.preload, "a": self.groups.a, "b": self.groups.b, "eta": self.groups.eta,
                "period": self.period, "rop_m_per_h": self.rop_m_per_h,
                "rop_mm_per_period": self.rop_mm_per_period,
                "peak_contact_force_n": self.peak_contact_force_n,
                "margins": {k: _margin_dict(k, v) for k, v in self.margins.items()},
                "feasible": self.feasible}


#: Units of the constraint margins.
MARGIN_UNITS = {"bounce": "N", "threshold": "N", "runaway": "N", "frequency": "relative",
                "contact_force": "N"}


def _margin_dict(name, v):
    return {"margin": v, "unit": MARGIN_UNITS[name], "ok": None if v is None else bool(v >= 0)}


@dataclass
class OptimizeResult:
    """Result of :func:`optimize`.

    Attributes
    ----------
    optimum : Candidate or None
        The best feasible point (None when no grid cell is feasible).
    runners_up : list of Candidate
        The best feasible points of up to two other regimes (period-n).
    best_grid : Candidate or None
        The best feasible grid cell.
    grid_feasible : int
        Feasible cells of the grid.
    grid_shape : tuple
    evaluations : int
        Scene evaluations in all.
    frequency_windows_hz : list or None
        Safe windows of the frequency check over the frequency bounds.
    """

    optimum: Optional[Candidate]
    runners_up: list
    best_grid: Optional[Candidate]
    grid_feasible: int
    grid_shape: tuple
    evaluations: int
    frequency_windows_hz: Optional[list]
    wall_time_s: float = 0.0

    def at_bounds(self, bounds) -> dict:
        """Variables of the optimum that sit on a bound: name -> ``"lower"`` or ``"upper"``."""
        out = {}
        if self.optimum is None:
            return out
        for b in bounds:
            v = self.optimum.values[b.name]
            tol = 1e-6 * (b.hi - b.lo)
            if v <= b.lo + tol:
                out[b.name] = "lower"
            elif v >= b.hi - tol:
                out[b.name] = "upper"
        return out

    def to_dict(self) -> dict:
        return {"optimum": None if self.optimum is None else self.optimum.to_dict(),
                "runners_up": [c.to_dict() for c in self.runners_up],
                "best_grid_cell": None if self.best_grid is None else self.best_grid.to_dict(),
                "grid_shape": list(self.grid_shape), "grid_feasible_cells": self.grid_feasible,
                "evaluations": self.evaluations, "frequency_windows_hz": self.frequency_windows_hz,
                "wall_time_s": self.wall_time_s}


def frequency_windows(string, lo_hz: float, hi_hz: float, margin: float) -> list:
    """Robustly safe hammer-frequency windows [Hz] of the string over [lo, hi].

    The windows where the frequency check passes, bit on and off bottom, over
    the check's whole damping range (a *robust pass*; windows that pass at the
    nominal damping only are left out).  A window edge at an end of the
    checked range is not a limit of the check: it is returned as 0 or inf.
    """
    from hammerbit.check.frequency import CheckConfig, check
    res = check(string, CheckConfig(excitation_hz=0.5 * (lo_hz + hi_hz), margin=margin,
                                    frequency_range_hz=(lo_hz, hi_hz)))
    labelled = getattr(res, "windows", None)
    if labelled is None:                       # a check without damping range: nominal windows
        spans = [tuple(w) for w in res.safe_windows_hz]
    else:
        spans = []
        for w in labelled:
            if not w.robust:
                continue
            if spans and abs(spans[-1][1] - w.lo_hz) <= 1e-12 * max(1.0, w.lo_hz):
                spans[-1] = (spans[-1][0], w.hi_hz)
            else:
                spans.append((w.lo_hz, w.hi_hz))
    tol = 1e-9 * hi_hz
    return [(0.0 if a <= lo_hz + tol else float(a), math.inf if b >= hi_hz - tol else float(b))
            for a, b in spans]


def _frequency_margin(f: float, windows) -> float:
    """Relative distance of f into the nearest safe window (negative outside all)."""
    best = -math.inf
    for lo, hi in windows:
        edges = [e for e in (lo, hi) if 0.0 < e < math.inf]    # 0 and inf: ends of the checked range
        if lo <= f <= hi:
            return min(abs(f - e) for e in edges) / f if edges else math.inf
        best = max(best, -min(abs(f - e) for e in edges) / f)
    return best


class _Problem:
    def __init__(self, groups: Groups, config: OptimizeConfig, windows):
        self.groups = groups
        self.c = config
        self.names = tuple(b.name for b in config.bounds)
        self.lo = np.array([b.lo for b in config.bounds])
        self.hi = np.array([b.hi for b in config.bounds])
        self.windows = windows
        self.evaluations = 0

    def margins(self, g: Groups, peak_n: float) -> dict:
        F0 = g.scales.friction_force
        floor = g.mu if g.gamma_hat > 0.0 else 1.0
        m = {"bounce": (g.b - g.a) * F0, "threshold": (1.0 - g.a - g.b) * F0,
             "runaway": (floor - g.b) * F0, "frequency": None, "contact_force": None}
        if self.windows is not None:
            m["frequency"] = _frequency_margin(g.to_rig().frequency, self.windows)
        if math.isfinite(self.c.max_contact_force):
            m["contact_force"] = self.c.max_contact_force - peak_n
        return m

    @staticmethod
    def feasible(g: Groups, m: dict) -> bool:
        """The regime flags decide bounce, threshold and runaway (one definition,
        :func:`regime`); the frequency and contact-force margins must be >= 0."""
        r = regime(g)
        if r.bounce or r.overload or r.runaway:
            return False
        return all(m[k] >= 0 for k in ("frequency", "contact_force") if m[k] is not None)

    def candidate(self, values: dict, g: Optional[Groups], period, rop_h, rop_mm, peak_n, ok: bool) -> Candidate:
        if g is None:
            return Candidate(values, self.groups, None, math.nan, math.nan, math.nan, {}, False)
        m = self.margins(g, peak_n)
        return Candidate(values, g, period, rop_h, rop_mm, peak_n, m, ok and self.feasible(g, m))

    def evaluate(self, x: np.ndarray) -> Candidate:
        values = {n: float(v) for n, v in zip(self.names, x)}
        self.evaluations += 1
        try:
            g = apply_settings(self.groups, values)
        except ParameterError:
            return self.candidate(values, None, None, math.nan, math.nan, math.nan, False)
        try:
            c = run_cell(g, self.c.periods, self.c.solver)
        except SolverError:
            return self.candidate(values, g, None, math.nan, math.nan, math.nan, False)
        return self.candidate(values, g, c.period, c.rop_m_per_h, c.rop_mm_per_period,
                              c.peak_contact_force_n, True)


def _refine(prob: _Problem, start: Candidate, step: np.ndarray) -> Candidate:
    """Bounded Nelder-Mead from a feasible cell; returns the best feasible point seen."""
    from scipy.optimize import minimize
    span = prob.hi - prob.lo
    best = [start]

    def f(u):
        x = prob.lo + np.clip(u, 0.0, 1.0) * span
        c = prob.evaluate(x)
        if c.feasible and math.isfinite(c.rop_m_per_h):
            if c.rop_m_per_h > best[0].rop_m_per_h:
                best[0] = c
            return -c.rop_m_per_h
        viol = sum(-v for v in c.margins.values() if v is not None and v < 0) if c.margins else 1.0
        return abs(start.rop_m_per_h) + 1.0 + viol

    u0 = (np.array([start.values[n] for n in prob.names]) - prob.lo) / span
    k = u0.size
    simplex = np.tile(u0, (k + 1, 1))
    for i in range(k):
        d = step[i] / span[i]
        simplex[i + 1, i] = u0[i] + d if u0[i] + d <= 1.0 else u0[i] - d
    minimize(f, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * k,
             options={"initial_simplex": simplex, "maxfev": prob.c.max_evaluations,
                      "xatol": 1e-4, "fatol": 1e-6})
    return best[0]


def optimize(groups: Groups, config: OptimizeConfig, *, string=None, executor: Optional[Executor] = None,
             options: ExecutorOptions = ExecutorOptions()) -> OptimizeResult:
    """Maximise the ROP [m/h] over ``config.bounds`` under the drilling constraints.

    Parameters
    ----------
    groups : Groups
        Base scene (its scales turn the ROP into m/h).
    config : OptimizeConfig
    string : DrillString, optional
        The drillstring of the frequency check (no check without one).
    executor, options
        Where the global stage runs.

    Returns
    -------
    OptimizeResult
    """
    import time as _time
    t0 = _time.perf_counter()
    c = config
    names = tuple(b.name for b in c.bounds)
    for corner in np.ndindex(*(2,) * len(names)):
        apply_settings(groups, {b.name: (b.hi if k else b.lo) for b, k in zip(c.bounds, corner)})
    windows = None
    if string is not None:
        base = apply_settings(groups, {})
        fs = []
        for corner in np.ndindex(*(2,) * len(names)):
            g = apply_settings(groups, {b.name: (b.hi if k else b.lo) for b, k in zip(c.bounds, corner)})
            fs.append(g.to_rig().frequency)
        f_lo, f_hi = min(fs + [base.to_rig().frequency]), max(fs + [base.to_rig().frequency])
        # checked over a wider range than the bounds, so that the margin measures the distance
        # to the nearest mode band, not to the end of the range (inf: no band in 0.25-4 x the bounds)
        windows = frequency_windows(string, 0.25 * f_lo, 4.0 * f_hi, c.margin)
    prob = _Problem(groups, c, windows)
    axes = [Axis(b.name, tuple(float(v) for v in np.linspace(b.lo, b.hi, c.grid))) for b in c.bounds]
    grid = np.stack(np.meshgrid(*[np.asarray(a.values) for a in axes], indexing="ij"), axis=-1)
    cells = [tuple(float(v) for v in row) for row in grid.reshape(-1, len(axes))]
    own = executor is None
    ex = Executor(options) if own else executor
    try:
        rows = ex.run(map_chunk, cells, fixed=(groups, names, c.periods, c.solver),
                      cost_s=c.periods * SECONDS_PER_PERIOD, label="optimize: grid")
    finally:
        if own:
            ex.close()
    prob.evaluations += len(cells)
    cands = []
    for vals, (row, _msg) in zip(cells, rows):
        values = dict(zip(names, vals))
        status = int(row[-1])
        g = apply_settings(groups, values) if status != 2 else None
        period = None if not math.isfinite(row[0]) else int(row[0])
        cands.append(prob.candidate(values, g, period, float(row[3]), float(row[2]), float(row[5]),
                                    status == STATUS_OK))
    feasible = [x for x in cands if x.feasible and math.isfinite(x.rop_m_per_h)]
    feasible.sort(key=lambda x: -x.rop_m_per_h)
    if not feasible:
        return OptimizeResult(None, [], None, 0, grid.shape[:-1], prob.evaluations, windows,
                              _time.perf_counter() - t0)
    best_grid = feasible[0]
    step = (prob.hi - prob.lo) / max(c.grid - 1, 1)
    refined = [_refine(prob, s, step) for s in feasible[: c.starts]]
    optimum = max([best_grid] + refined, key=lambda x: x.rop_m_per_h)
    pool = sorted(feasible + refined, key=lambda x: -x.rop_m_per_h)
    runners, seen = [], {optimum.period}
    for x in pool:
        if x.period not in seen:
            runners.append(x)
            seen.add(x.period)
        if len(runners) == 2:
            break
    return OptimizeResult(optimum, runners, best_grid, len(feasible), grid.shape[:-1], prob.evaluations,
                          windows, _time.perf_counter() - t0)
