"""The operating point of the highest rate of penetration (the paper's section 8).

:func:`optimize` maximises the ROP in SI [m/h] over bounded parameters
(typically the hammer's frequency, amplitude and preload) subject to

* **a drilling point**: the scene's own dynamics neither run away nor bounce
  (:mod:`hammerbit.scene.flags`: the drift does not accelerate without bound,
  the drive never falls below ``-F_s`` while the bit is stuck);
* **static threshold**: ``a + b <= 1`` (preload plus amplitude below
  ``F0 = mu_e F_N``, the paper's domain);
* **frequency check**: with a drillstring, the hammer frequency lies in a
  window where :func:`hammerbit.check.frequency.check` passes robustly (bit on
  and off bottom, over the check's damping range);
* **contact force**: the peak hammer-bit contact force over the whole run,
  start-up included (:func:`hammerbit.scene.contact.peak_of_run`, the figure
  of ``simulate`` and ``map``), stays below a limit.

The ROP landscape is piecewise smooth, with steps where the period-n of the
motion changes.  A global stage evaluates a grid (41 points per variable for
one or two variables, 15 for three) through the study executor; a local
stage (:func:`hammerbit.studies.refine.pattern_search`) refines from the best
feasible cells along the grid directions and diagonals, halving its step when
no move improves, so a faster point cut off by a constraint is approached from
the feasible side and the search ends on the active constraint.  The optimum is the best feasible point evaluated, never below
the best feasible grid cell.  Runners-up are the best drilling points
(a period found, a positive ROP) of other periods.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hammerbit.model.params import Groups
from hammerbit.model.settings import apply_settings, setting_target
from hammerbit.model.validation import ParameterError
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.solver_options import SolverOptions

from .executor import Executor, ExecutorOptions
from .map import Axis, MapCell, axis_unit, run_cell
from .refine import pattern_search
from .bifurcation import SECONDS_PER_PERIOD

__all__ = ["Bound", "OptimizeConfig", "Candidate", "OptimizeResult", "optimize", "frequency_windows",
           "Infeasibility", "infeasibility", "violations", "VIOLATION_BASIS"]


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


#: Grid points per variable of the global stage, by the number of variables.
DEFAULT_GRID = {1: 41, 2: 41, 3: 15}


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
    grid : int, optional
        Grid points per variable of the global stage (default
        :data:`DEFAULT_GRID`: 41 for one or two variables, 15 for three).
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
    grid: Optional[int] = None
    starts: int = 3
    max_evaluations: int = 80
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
        if self.grid is None:
            object.__setattr__(self, "grid", DEFAULT_GRID[len(b)])
        if not (isinstance(self.grid, int) and 2 <= self.grid <= 201):
            raise ParameterError("grid", self.grid, "an integer in [2, 201]")
        if not (isinstance(self.max_evaluations, int) and self.max_evaluations >= 0):
            raise ParameterError("max_evaluations", self.max_evaluations, "an integer >= 0")
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
    """Over the whole run, start-up included [N]."""
    margins: dict
    """Constraint -> margin (units in :data:`MARGIN_UNITS`; None: not checked or a flag)."""
    checks: dict
    """Constraint -> passed (None: not checked)."""
    flags: Optional[dict] = None
    """The scene's own flags (:meth:`hammerbit.scene.flags.SceneFlags.to_dict`)."""

    @property
    def feasible(self) -> bool:
        return bool(self.checks) and all(v for v in self.checks.values() if v is not None)

    @property
    def drilling(self) -> bool:
        """A drilling point: feasible, a period found and a positive ROP."""
        return self.feasible and self.period is not None and self.rop_m_per_h > 0.0

    def to_dict(self) -> dict:
        rig = self.groups.to_rig()
        return {"values": self.values, "frequency_hz": rig.frequency, "amplitude_n": rig.amplitude,
                "preload_n": rig.preload, "a": self.groups.a, "b": self.groups.b, "eta": self.groups.eta,
                "period": self.period, "rop_m_per_h": self.rop_m_per_h,
                "rop_mm_per_period": self.rop_mm_per_period,
                "peak_contact_force_n": self.peak_contact_force_n,
                "margins": {k: _margin_dict(k, v, self.checks.get(k)) for k, v in self.margins.items()},
                "regime": None if self.flags is None else self.flags["regime"],
                "regime_names": None if self.flags is None else self.flags["regime_names"],
                "flags": self.flags, "feasible": self.feasible}


#: Units of the constraint margins (runaway is a flag of the scene's dynamics: no margin).
MARGIN_UNITS = {"bounce": "N", "threshold": "N", "runaway": "flag", "frequency": "relative",
                "contact_force": "N"}


def _margin_dict(name, v, ok):
    return {"margin": v, "unit": MARGIN_UNITS[name], "ok": ok}


#: What each constraint's violation is relative to, for people.
VIOLATION_BASIS = {"threshold": "F0 (a + b <= 1)", "bounce": "F_s (the drive above -F_s while stuck)",
                   "contact_force": "the contact-force limit", "frequency": "the frequency",
                   "runaway": "a flag (1: set)", "ran": "the scene ran (inf: it did not)"}


def violations(c: Candidate, max_contact_force: float) -> dict:
    """Constraint -> violation of ``c``, relative to the constraint's limit (0: met): the
    threshold and bounce margins over ``F0``, the contact force's over its limit, the frequency
    margin as it is (relative to the frequency), a flag 1, a scene that did not run inf."""
    F0 = c.groups.scales.friction_force
    out = {}
    for name, ok in c.checks.items():
        if ok is None:
            continue
        m = c.margins.get(name)
        if name == "ran":
            v = 0.0 if ok else math.inf
        elif m is None or not math.isfinite(m):
            v = 0.0 if ok else 1.0
        elif name == "contact_force":
            v = max(0.0, -m) / max_contact_force
        elif name == "frequency":
            v = max(0.0, -m)
        else:
            v = max(0.0, -m) / F0
        out[name] = 0.0 if ok else max(v, 1e-300)
    return out


@dataclass(frozen=True)
class Infeasibility:
    """Why no point is feasible: the least-violating point and the constraint that binds there.

    Attributes
    ----------
    binding : str
        The constraint with the largest relative violation at ``point``.
    point : Candidate
        The evaluated point whose largest relative violation is the smallest.
    violations : dict
        Constraint -> relative violation at ``point`` (:func:`violations`).
    cells_violating : dict
        Constraint -> evaluated points that violate it.
    """

    binding: str
    point: Candidate
    violations: dict
    cells_violating: dict

    def to_dict(self) -> dict:
        return {"binding_constraint": self.binding, "least_violating_point": self.point.to_dict(),
                "violations": {k: {"relative": v, "relative_to": VIOLATION_BASIS.get(k, "its limit")}
                               for k, v in self.violations.items()},
                "points_violating": dict(self.cells_violating)}

    def text(self) -> str:
        """One line for people (SI)."""
        p = self.point.to_dict()
        v = self.violations[self.binding]
        return (f"binding constraint: {self.binding} (violated by {self.cells_violating[self.binding]} of the "
                f"points evaluated); least-violating point: frequency {p['frequency_hz']:.4g} Hz, amplitude "
                f"{p['amplitude_n']:.4g} N, preload {p['preload_n']:.4g} N, peak contact force "
                f"{p['peak_contact_force_n']:.4g} N, where {self.binding} is violated by {v:.3g} relative to "
                f"{VIOLATION_BASIS.get(self.binding, 'its limit')}")


def infeasibility(points, max_contact_force: float) -> Optional[Infeasibility]:
    """The :class:`Infeasibility` of evaluated ``points`` none of which is feasible (None if empty)."""
    scored = []
    counts: dict = {}
    for c in points:
        v = violations(c, max_contact_force)
        for k, x in v.items():
            if x > 0.0:
                counts[k] = counts.get(k, 0) + 1
        if v:
            scored.append((max(v.values()), sum(v.values()), c, v))
    if not scored:
        return None
    worst, _, point, v = min(scored, key=lambda s: (s[0], s[1]))
    binding = max(v, key=lambda k: v[k])
    return Infeasibility(binding, point, v, counts)


@dataclass
class OptimizeResult:
    """Result of :func:`optimize`.

    Attributes
    ----------
    optimum : Candidate or None
        The best feasible point (None when no grid cell is feasible).
    runners_up : list of Candidate
        The best drilling points (feasible, a period found, ROP > 0) of up to
        two other periods.
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
    infeasible: Optional[Infeasibility] = None
    """Without a feasible point: the least-violating one and the binding constraint."""

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
                "wall_time_s": self.wall_time_s,
                "infeasible": None if self.infeasible is None else self.infeasible.to_dict()}


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
        self.seen = {}

    def candidate(self, values: dict, cell: Optional[MapCell]) -> Candidate:
        """The candidate of a cell (None: invalid parameters)."""
        if cell is None or cell.groups is None:
            return Candidate(values, self.groups, None, math.nan, math.nan, math.nan, {}, {"ran": False})
        g = cell.groups
        F0 = g.scales.friction_force
        fl = cell.flags
        ran = fl is not None
        # the rule of hammerbit.model.regime.regime (overload: a + b > 1), so that a cell on the line counts as inside
        m = {"bounce": None, "threshold": (1.0 - (g.a + g.b)) * F0, "runaway": None, "frequency": None,
             "contact_force": None}
        ok = {"ran": ran, "bounce": None if not ran else not fl.bounce, "threshold": not (g.a + g.b > 1.0),
              "runaway": None if not ran else not fl.runaway, "frequency": None, "contact_force": None}
        if ran:
            low = (fl.min_drive + 1.0) * F0        # lowest drive above -F_s; a dip while slipping is no bounce
            m["bounce"] = low if fl.bounce else max(low, 0.0)
        if self.windows is not None:
            m["frequency"] = _frequency_margin(g.to_rig().frequency, self.windows)
            ok["frequency"] = m["frequency"] >= 0
        if math.isfinite(self.c.max_contact_force):
            m["contact_force"] = self.c.max_contact_force - cell.peak_contact_force_n
            ok["contact_force"] = bool(m["contact_force"] >= 0)       # NaN (did not run): False
        return Candidate(values, g, cell.period, cell.rop_m_per_h, cell.rop_mm_per_period,
                         cell.peak_contact_force_n, m, ok, None if fl is None else fl.to_dict(F0))

    def evaluate(self, x: np.ndarray) -> Candidate:
        key = tuple(float(v) for v in x)
        if key in self.seen:
            return self.seen[key]
        values = dict(zip(self.names, key))
        self.evaluations += 1
        try:
            g = apply_settings(self.groups, values)
        except ParameterError:
            c = self.candidate(values, None)
        else:
            try:
                c = self.candidate(values, run_cell(g, self.c.periods, self.c.solver))
            except SolverError:
                c = self.candidate(values, MapCell(None, *(math.nan,) * 6, None, g, 1))
        self.seen[key] = c
        return c


def _grid_chunk(cells, base, names, periods, solver):
    """Chunk function of the global stage: the :class:`MapCell` of each cell (None: invalid)."""
    out = []
    for values in cells:
        try:
            g = apply_settings(base, dict(zip(names, values)))
        except ParameterError:
            out.append(None)
            continue
        try:
            out.append(run_cell(g, periods, solver))
        except SolverError:
            out.append(MapCell(None, *(math.nan,) * 6, None, g, 1))
    return out


def _starts(feasible: list, k: int, step: np.ndarray, names) -> list:
    """Up to ``k`` best feasible cells, each more than one grid step from the ones before."""
    out = []
    for c in feasible:
        x = np.array([c.values[n] for n in names])
        if all(np.any(np.abs(x - np.array([o.values[n] for n in names])) > 1.5 * step) for o in out):
            out.append(c)
        if len(out) == k:
            break
    return out


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
        rows = ex.run(_grid_chunk, cells, fixed=(groups, names, c.periods, c.solver),
                      cost_s=c.periods * SECONDS_PER_PERIOD, label="optimize: grid")
    finally:
        if own:
            ex.close()
    prob.evaluations += len(cells)
    for vals, cell in zip(cells, rows):
        prob.seen[vals] = prob.candidate(dict(zip(names, vals)), cell)
    feasible = [x for x in prob.seen.values() if x.feasible and math.isfinite(x.rop_m_per_h)]
    feasible.sort(key=lambda x: -x.rop_m_per_h)
    if not feasible:
        return OptimizeResult(None, [], None, 0, grid.shape[:-1], prob.evaluations, windows,
                              _time.perf_counter() - t0,
                              infeasible=infeasibility(prob.seen.values(), c.max_contact_force))
    best_grid = feasible[0]
    step = (prob.hi - prob.lo) / max(c.grid - 1, 1)
    for s0 in _starts(feasible, c.starts, step, names):
        x0 = np.array([s0.values[n] for n in names])
        pattern_search(prob.evaluate, x0, s0, prob.lo, prob.hi, step, c.max_evaluations)
    pool = sorted((x for x in prob.seen.values() if x.feasible and math.isfinite(x.rop_m_per_h)),
                  key=lambda x: -x.rop_m_per_h)
    optimum = pool[0]
    runners, seen = [], {optimum.period}
    for x in pool:
        if x.drilling and x.period not in seen:
            runners.append(x)
            seen.add(x.period)
        if len(runners) == 2:
            break
    return OptimizeResult(optimum, runners, best_grid, len(feasible), grid.shape[:-1], prob.evaluations,
                          windows, _time.perf_counter() - t0)
