"""Bifurcation diagrams and penetration sweeps over one parameter (Figs. 9-14).

A bifurcation sweep asks the kernels only for the last Poincaré points of
each scene and never allocates a trajectory.  Scenes run on the study
executor (:mod:`hammerbit.studies.executor`): in process, on local worker
processes or on a Dask cluster, with the same result.
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from hammerbit.model import kernel_layouts
from hammerbit.model.params import Groups
from hammerbit.model.settings import apply_settings, setting_target
from hammerbit.model.validation import RANGES, ParameterError
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper

from hammerbit.scene.flags import stepper_flags
from .executor import Executor, ExecutorOptions

__all__ = ["BifurcationResult", "bifurcation", "penetration_sweep", "poincare_tail",
           "SECONDS_PER_PERIOD"]

#: Rough cost of one forcing period of one scene [s] (for the chunk size only).
SECONDS_PER_PERIOD = 2e-5


@dataclass
class BifurcationResult:
    """Poincaré points of a sweep.

    Attributes
    ----------
    param : str
        Swept parameter, as given (a group or an SI name).
    values : ndarray, shape (m,)
        Parameter values.
    points : ndarray, shape (m, k, 5)
        The last k Poincaré samples [tau, x1, x2, x3, x4] for each value.
    periods : list of int or None
        Period-n of each value, by the rule of :func:`hammerbit.scene.simulate.simulate`: the
        last half of the whole run (not only the kept samples).
    drift : ndarray, shape (m,)
        Penetration per forcing period over the kept samples [x0].
    wall_time_s : float
        Wall time of the sweep (executor set-up excluded).
    total_periods : int
        Forcing periods integrated in all.
    workers : int
        Worker processes that ran it (1: in process).
    groups : Groups, optional
        The base scene (its scales turn the results into SI).
    regime : ndarray of int, shape (m,)
        The regime verdict of each value (:mod:`hammerbit.model.regime_codes`; 0: drilling).
    """

    param: str
    values: np.ndarray
    points: np.ndarray
    periods: list
    drift: np.ndarray
    wall_time_s: float
    total_periods: int
    workers: int = 1
    groups: Optional[Groups] = None
    regime: Optional[np.ndarray] = None

    @property
    def periods_per_second(self) -> float:
        return self.total_periods / self.wall_time_s if self.wall_time_s > 0 else float("nan")

    def to_csv(self, path) -> None:
        """One row per Poincaré point, in SI with each value's own scales (header ``name [unit]``):
        the parameter, time [s], relative displacement x_b - x_s [mm], relative velocity
        v_b - v_s [m/s], bit velocity [m/s] and bit position (penetration) [mm].

        Without ``groups`` (no scales known) the columns stay nondimensional, named so:
        tau [1/Omega], lengths [x0], velocities [x0 Omega].
        """
        kind, target = setting_target(self.param)
        unit = "1" if kind == "group" else RANGES[target].unit
        rows = []
        for i, v in enumerate(self.values):
            P = self.points[i]
            if self.groups is not None:
                sc = apply_settings(self.groups, {self.param: float(v)}).scales
                t, L, V = sc.time, sc.length * 1e3, sc.velocity
            else:
                t = L = V = 1.0
            for r in P:
                rows.append((v, r[0] * t, (r[1] - r[3]) * L, (r[2] - r[4]) * V, r[4] * V, r[3] * L))
        if self.groups is not None:
            names = ("time [s]", "x_b - x_s [mm]", "v_b - v_s [m/s]", "bit velocity v_s [m/s]",
                     "bit position x_s [mm]")
        else:
            names = ("tau [1/Omega]", "x1 - x3 [x0]", "x2 - x4 [x0 Omega]", "x4 [x0 Omega]", "x3 [x0]")
        np.savetxt(path, np.array(rows).reshape(-1, 6), delimiter=",",
                   header=",".join((f"{self.param} [{unit}]",) + names), comments="")


def poincare_tail(groups: Groups, periods: int, keep: int, solver: SolverOptions,
                  phase: float = 0.0) -> np.ndarray:
    """The last ``keep`` Poincaré rows [tau, x1, x2, x3, x4] of a run from rest (no trajectory).

    Rows are taken at ``(k + phase) T`` for ``k = 0 .. periods`` and the last
    ``keep`` returned: the same sampling times, to the bit, as
    :func:`hammerbit.scene.simulate.simulate` with ``Record(poincare=True)``.
    """
    return _tail_and_flags(groups, periods, keep, solver, phase)[0]


def _tail_and_flags(groups: Groups, periods: int, keep: int, solver: SolverOptions, phase: float):
    """The last ``keep`` Poincaré rows and the scene's flags from all of them (the rule of ``simulate``)."""
    T = groups.period
    st = Stepper(groups, solver=solver)
    st.opts[kernel_layouts.O_POIN_T0] = phase * T
    poin = np.zeros((periods + 1, 5))
    st.advance(periods * T + (phase * T if phase > 0 else 0.0), poincare=poin)
    n = int(st.istate[kernel_layouts.I_POIN_NEXT])
    return poin[max(n - keep, 0):n].copy(), stepper_flags(groups, st, poin[:n])


def _scenes(groups: Groups, param: str, values: np.ndarray) -> list:
    setting_target(param, values[0])          # unknown names fail here, as typed
    return [apply_settings(groups, {param: float(v)}) for v in values]


def _bifurcation_chunk(scenes, periods, keep, solver, phase):
    """Per scene: its tail, and its period-n and verdict by the rule of ``simulate`` (the whole run)."""
    out = []
    for g in scenes:
        tail, flags = _tail_and_flags(g, periods, keep, solver, phase)
        out.append((tail, flags.period, flags.code))
    return out


def _penetration_chunk(scenes, periods, solver):
    from hammerbit.scene.simulate import simulate
    return [simulate(g, periods, solver=solver).penetration for g in scenes]


def bifurcation(groups: Groups, param: str, values: Sequence[float], *, periods: int = 300,
                keep: int = 64, solver: SolverOptions = SolverOptions(), phase: float = 0.0,
                executor: Optional[Executor] = None,
                options: ExecutorOptions = ExecutorOptions()) -> BifurcationResult:
    """Bifurcation diagram: Poincaré points against one parameter.

    Parameters
    ----------
    groups : Groups
        Base parameters.
    param : str
        Parameter to sweep: a group (``a``, ``b``, ``eta`` ...) or an SI name
        (``A``, ``f``, ``preload`` ...; :func:`hammerbit.model.settings.apply_settings`).
    values : sequence of float
        Values of ``param``.
    periods : int
        Forcing periods per value (from rest); the last ``keep`` are kept.
    keep : int
        Poincaré samples kept per value.
    solver : SolverOptions
        Integrator options.
    phase : float
        Poincaré phase, fraction of the period, in [0, 1).
    executor : Executor, optional
        A running executor (reused); default one made from ``options``.
    options : ExecutorOptions
        Workers, scheduler, progress bar (used without ``executor``).

    Returns
    -------
    BifurcationResult
    """
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size == 0:
        raise ParameterError("values", values, "a non-empty 1-D sequence")
    if not (isinstance(periods, (int, np.integer)) and periods >= 2):
        raise ParameterError("periods", periods, "an integer >= 2")
    if not (isinstance(keep, (int, np.integer)) and keep >= 1):
        raise ParameterError("keep", keep, "an integer >= 1")
    if not 0.0 <= phase < 1.0:
        raise ParameterError("phase", phase, "[0, 1)")
    keep = int(min(keep, periods))
    scenes = _scenes(groups, param, values)
    own = executor is None
    ex = Executor(options) if own else executor
    try:
        ex.connect()
        t0 = _time.perf_counter()
        tails = ex.run(_bifurcation_chunk, scenes, fixed=(int(periods), keep, solver, phase),
                       cost_s=periods * SECONDS_PER_PERIOD, label=f"bifurcation {param}")
        wall = _time.perf_counter() - t0
        workers = ex.workers
    finally:
        if own:
            ex.close()
    out = np.full((values.size, keep, 5), np.nan)
    per, drift, codes = [], np.zeros(values.size), np.zeros(values.size, dtype=np.int64)
    for i, (pts, period, code) in enumerate(tails):
        out[i, : pts.shape[0]] = pts
        per.append(period)
        codes[i] = code
        drift[i] = (out[i, -1, 3] - out[i, 0, 3]) / max(keep - 1, 1)
    return BifurcationResult(param=param, values=values, points=out, periods=per, drift=drift,
                             wall_time_s=wall, total_periods=int(periods * values.size), workers=workers,
                             groups=groups, regime=codes)


def penetration_sweep(groups: Groups, values: Sequence[float], *, param: str = "a", periods: int = 100,
                      solver: SolverOptions = SolverOptions(), executor: Optional[Executor] = None,
                      options: ExecutorOptions = ExecutorOptions()) -> np.ndarray:
    """Penetration x3 after ``periods`` forcing periods against one parameter (Fig. 14).

    Returns
    -------
    ndarray, shape (m,)
        Penetration [x0] for each value, as :func:`hammerbit.scene.simulate.simulate` gives it.
    """
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or values.size == 0:
        raise ParameterError("values", values, "a non-empty 1-D sequence")
    scenes = _scenes(groups, param, values)
    own = executor is None
    ex = Executor(options) if own else executor
    try:
        res = ex.run(_penetration_chunk, scenes, fixed=(periods, solver),
                     cost_s=periods * SECONDS_PER_PERIOD, label=f"penetration {param}")
    finally:
        if own:
            ex.close()
    return np.array(res, dtype=float)
