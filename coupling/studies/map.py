"""Regime maps: period-n, rate of penetration, impacts and the scene's own flags on a grid.

:func:`regime_map` runs one scene per cell of a grid over 1 to 3 parameters
(any group or SI name, applied with :func:`hammerbit.model.settings.apply_settings`,
which carries each cell's own scales) and returns an :class:`xarray.Dataset`.
Per cell, from rest over ``periods`` forcing periods:

``period``
    period-n of the bounded motion (:func:`hammerbit.scene.analysis.detect_period`
    on the Poincaré samples of the second half), NaN when none up to 32;
``transient``, ``settled_after``
    1 when that period has not settled (:mod:`hammerbit.scene.flags`), and
    the forcing periods the orbit needed (or, still settling, an
    extrapolation; NaN: unknown);
``rop_x0_per_period``
    rate of penetration, the mean penetration per forcing period over the
    second half of the horizon, nondimensional [x0 per period], with
    ``rop_mm_per_period`` and ``rop_m_per_h`` in SI (the cell's own scales,
    :meth:`Groups.rop`);
``impacts_per_period``
    hammer-bit impacts per forcing period over the second half;
``peak_contact_force_n``
    largest hammer-bit contact force over the whole run, start-up included
    [N] (:func:`hammerbit.scene.contact.peak_of_run`, the figure of
    ``simulate`` and ``optimize``); ``peak_contact_force_steady_n`` the
    largest over the second half only;
``min_drive_f0``, ``min_drive_n``
    lowest drive on the bit, nondimensional [F0] and [N];
``runaway``, ``bounce``, ``bounces``, ``tension``
    the scene's own flags (:mod:`hammerbit.scene.flags`, 1 = set);
``valid``
    1 when the cell is a drilling point: it ran, neither runaway nor bounce;
``domain_a_ge_b``, ``domain_a_plus_b_gt_1``, ``domain_b_gt_mu``
    the paper's static rules it breaks (:func:`hammerbit.model.regime.regime`);
``status``
    0 when the scene ran, 1 when the solver stopped (the message is in the
    dataset's ``errors`` attribute), 2 when the cell's parameters are invalid.

A cell is exactly the scene ``simulate(groups, periods)`` of the same
parameters: the same stepper from rest, one call to the end of the horizon.
The figures of a cell come out of compiled passes over its Poincaré rows
and event log (:func:`cell_figures`, :func:`hammerbit.scene.flags.scene_flags`),
so the Python work per cell is the scene's set-up and validation; the
solver's own time dominates.
"""
from __future__ import annotations

import json
import math
import time as _time
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
from numba import njit

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups
from hammerbit.model.regime import regime
from hammerbit.model.settings import apply_settings, setting_target
from hammerbit.model.validation import ParameterError
from hammerbit.model.solver_errors import MaxStepsError, SolverError
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper

from hammerbit.model.regime_codes import REGIME_BITS
from hammerbit.scene.contact import peak_of_run, steady_peak
from hammerbit.scene.flags import SceneFlags, stepper_flags
from .bifurcation import SECONDS_PER_PERIOD
from .executor import Executor, ExecutorOptions

__all__ = ["Axis", "CELL_DTYPE", "MapCell", "run_cell", "cell_figures", "regime_map", "map_to_json", "axis_unit",
           "best_valid_cell", "eligible_cells", "FLAG_FIELDS", "DOMAIN_FIELDS", "STATUS_OK", "STATUS_SOLVER",
           "STATUS_INVALID", "map_chunk"]

STATUS_OK, STATUS_SOLVER, STATUS_INVALID = 0, 1, 2

CELL_DTYPE = np.dtype([("period", "f8"), ("transient", "i1"), ("settled_after", "f8"),
                       ("rop_x0_per_period", "f8"), ("rop_mm_per_period", "f8"),
                       ("rop_m_per_h", "f8"), ("impacts_per_period", "f8"),
                       ("peak_contact_force_n", "f8"), ("peak_contact_force_steady_n", "f8"),
                       ("min_drive_f0", "f8"), ("min_drive_n", "f8"),
                       ("runaway", "i1"), ("bounce", "i1"), ("bounces", "f8"), ("tension", "i1"),
                       ("stall", "i1"), ("regime", "i2"), ("valid", "i1"), ("domain_a_ge_b", "i1"), ("domain_a_plus_b_gt_1", "i1"),
                       ("domain_b_gt_mu", "i1"), ("status", "i1")])

#: The scene flags and the paper's rules of a cell (1 = set), in ``CELL_DTYPE`` order.
FLAG_FIELDS = ("runaway", "bounce", "tension", "stall", "transient")
DOMAIN_FIELDS = {"bounce": "domain_a_ge_b", "overload": "domain_a_plus_b_gt_1", "runaway": "domain_b_gt_mu"}

#: Units of SI names (spec symbols and RigParameters/FMU names).
_SI_UNITS = {
    "hammer_mass": "kg", "bit_mass": "kg", "stiffness": "N/m", "damping": "N s/m", "mu_static": "1",
    "mu_kinetic": "1", "friction_decay": "s/m", "normal_force": "N", "contact_stiffness": "N/m^n",
    "contact_exponent": "1", "contact_damping": "s/m", "gap": "m", "preload": "N", "amplitude": "N",
    "frequency": "Hz", "phase": "rad",
}

_VARS = {
    "period": ("period-n of the bounded motion over the second half (NaN: none up to 32)", "1"),
    "transient": ("flag: the period has not settled within the horizon", "1"),
    "settled_after": ("forcing period from which the last quarter's period repeats up to the end (seen)", "1"),
    "rop_x0_per_period": ("rate of penetration over the second half, nondimensional", "x0 per forcing period"),
    "rop_mm_per_period": ("rate of penetration over the second half", "mm per forcing period"),
    "rop_m_per_h": ("rate of penetration over the second half", "m/h"),
    "impacts_per_period": ("hammer-bit impacts per forcing period over the second half", "1"),
    "peak_contact_force_n": ("largest hammer-bit contact force over the whole run, start-up included", "N"),
    "peak_contact_force_steady_n": ("largest hammer-bit contact force over the second half", "N"),
    "min_drive_f0": ("lowest drive on the bit, nondimensional", "F0"),
    "min_drive_n": ("lowest drive on the bit", "N"),
    "runaway": ("flag: the drift accelerates without bound (the scene's own dynamics)", "1"),
    "bounce": ("flag: the drive fell below -F_s while the bit was stuck", "1"),
    "bounces": ("bounce violations (drive below -F_s while stuck)", "1"),
    "tension": ("flag: the drive on the bit fell below zero", "1"),
    "stall": ("flag: the bit has not slipped over the last STALL_PERIODS forcing periods", "1"),
    "regime": ("the regime verdict: sum of runaway 1, bounce 2, tension 4, stall 8, transient 16", "1"),
    "valid": ("1: a drilling point (ran, no runaway, no bounce)", "1"),
    "domain_a_ge_b": ("paper's domain broken: a >= b", "1"),
    "domain_a_plus_b_gt_1": ("paper's domain broken: a + b > 1", "1"),
    "domain_b_gt_mu": ("paper's domain broken: b above the kinetic friction floor", "1"),
    "status": ("0 ran, 1 solver stopped (see attribute errors), 2 invalid parameters", "1"),
}


def axis_unit(name: str) -> str:
    """Unit of a parameter name: ``"1"`` for a group, SI for an SI name."""
    kind, target = setting_target(name)
    return "1" if kind == "group" else _SI_UNITS.get(target, "")


@dataclass(frozen=True)
class Axis:
    """One axis of a map: a parameter name (group or SI) and its values."""

    name: str
    values: tuple

    @classmethod
    def parse(cls, text: str) -> "Axis":
        """``"a=0.05:0.25:81"`` -> 81 values from 0.05 to 0.25; ``"a=0.1"`` -> one value."""
        if "=" not in text:
            raise ParameterError("--axis", text, "NAME=LO:HI:N")
        name, spec = (s.strip() for s in text.split("=", 1))
        parts = spec.split(":")
        try:
            if len(parts) == 1:
                vals = (float(parts[0]),)
            elif len(parts) == 3:
                lo, hi, n = float(parts[0]), float(parts[1]), parts[2]
                if not n.strip().isdigit() or int(n) < 1:
                    raise ValueError
                vals = tuple(float(v) for v in np.linspace(lo, hi, int(n)))
            else:
                raise ValueError
        except ValueError:
            raise ParameterError(f"--axis {name}", spec, "LO:HI:N with numbers LO, HI and a count N >= 1")\
                from None
        setting_target(name, spec)             # unknown names fail here, named as typed
        if not all(math.isfinite(v) for v in vals):
            raise ParameterError(f"--axis {name}", spec, "finite values")
        return cls(name, vals)

    @property
    def unit(self) -> str:
        return axis_unit(self.name)


@dataclass(frozen=True)
class MapCell:
    """The figures of one cell (see the module docstring)."""

    period: Optional[int]
    rop: float
    """Rate of penetration, nondimensional [x0 per forcing period]."""
    rop_mm_per_period: float
    rop_m_per_h: float
    impacts_per_period: float
    peak_contact_force_n: float
    """Over the whole run, start-up included [N]."""
    peak_contact_force_steady_n: float
    """Over the second half [N]."""
    flags: Optional[SceneFlags]
    groups: Optional[Groups]
    status: int = STATUS_OK
    error: str = ""

    @property
    def valid(self) -> bool:
        """A drilling point: the scene ran and its dynamics neither run away nor bounce."""
        return self.status == STATUS_OK and self.flags is not None and not self.flags.unusable

    def row(self) -> tuple:
        f = self.flags
        nan = float("nan")
        dom = regime(self.groups) if self.groups is not None else None
        F0 = self.groups.scales.friction_force if self.groups is not None else nan
        return (np.nan if self.period is None else float(self.period),
                int(f.transient) if f else 0,
                float(f.settled_after) if f and f.settled_after is not None else nan,
                self.rop, self.rop_mm_per_period, self.rop_m_per_h, self.impacts_per_period,
                self.peak_contact_force_n, self.peak_contact_force_steady_n,
                f.min_drive if f else nan, f.min_drive * F0 if f else nan,
                int(f.runaway) if f else 0, int(f.bounce) if f else 0, float(f.bounces) if f else nan,
                int(f.tension) if f else 0, int(f.stall) if f else 0, f.code if f else 0, int(self.valid),
                int(dom.bounce) if dom else 0, int(dom.overload) if dom else 0, int(dom.runaway) if dom else 0,
                self.status)


class _Buffers:
    """Record buffers reused by every scene of a chunk."""

    def __init__(self, periods: int):
        self.poin = np.zeros((periods + 1, 5))
        self.log = np.zeros((max(64, 8 * periods), KL.N_LOG_COLS))
        self.figures = np.zeros(_N_FIGURES)


#: Slots of :func:`cell_figures`'s ``out``.
_FIG_ROP, _FIG_IMPACTS, _FIG_PEAK_STEADY = range(3)
_N_FIGURES = 3


@njit(cache=True, nogil=True)
def cell_figures(poin, n_poin, y_bit, log, n_log, periods, t_half, current_peak, out):
    """A cell's figures from its Poincaré rows and event log, into ``out``.

    ``out[0]`` the rate of penetration [x0 per period] over the second half
    (``periods // 2`` to ``periods``; ``y_bit`` is the bit position at the end
    when the last sample is missing), ``out[1]`` the impacts at or after
    ``t_half``, ``out[2]`` the steady peak contact force [F0]
    (:func:`hammerbit.scene.contact.steady_peak`, ``current_peak`` for a
    contact still going at the end).
    """
    half = periods // 2
    x3_end = poin[periods, 3] if n_poin > periods else y_bit
    out[_FIG_ROP] = (x3_end - poin[half, 3]) / (periods - half)
    impacts = 0
    for i in range(n_log):
        if log[i, KL.L_T] >= t_half and log[i, KL.L_KIND] == KL.EV_IMPACT:
            impacts += 1
    out[_FIG_IMPACTS] = impacts
    out[_FIG_PEAK_STEADY] = steady_peak(log, n_log, t_half, current_peak)


def run_cell(groups: Groups, periods: int, solver: SolverOptions = SolverOptions(),
             buffers: Optional[_Buffers] = None) -> MapCell:
    """Run one cell: the scene from rest over ``periods`` forcing periods.

    The integration is that of :func:`hammerbit.scene.simulate.simulate` (same
    stepper, one call to the end), recording Poincaré samples and the event
    log into preallocated buffers.
    """
    buf = buffers or _Buffers(periods)
    T = groups.period
    st = Stepper(groups, solver=solver)
    poin = buf.poin[: periods + 1]
    log = buf.log
    st.advance(st.time, poincare=poin, log=log)
    while True:
        status = st.advance(periods * T, poincare=poin, log=log)
        if status == "max_steps":
            raise MaxStepsError(f"more than max_steps={solver.max_steps} steps in one call", time=st.time,
                                status=KL.ST_MAX_STEPS)
        if status != "log_full":
            break
        buf.log = log = np.concatenate([log, np.zeros_like(log)])
    n_poin = int(st.istate[KL.I_POIN_NEXT])
    fig = buf.figures
    current = float(st.fstate[KL.F_PEAK]) if st.istate[KL.I_CONTACT] != KL.FREE else 0.0
    cell_figures(poin, n_poin, st.y[2], log, int(st.istate[KL.I_NLOG]), periods, (periods // 2) * T,
                 current, fig)
    rop = float(fig[_FIG_ROP])
    flags = stepper_flags(groups, st, poin[:n_poin])
    si = groups.rop(rop)
    F0 = groups.scales.friction_force
    return MapCell(period=flags.period, rop=rop, rop_mm_per_period=si["mm_per_period"],
                   rop_m_per_h=si["m_per_h"], impacts_per_period=fig[_FIG_IMPACTS] / (periods - periods // 2),
                   peak_contact_force_n=peak_of_run(st) * F0,
                   peak_contact_force_steady_n=float(fig[_FIG_PEAK_STEADY]) * F0, flags=flags, groups=groups)


def _failed(status: int, message: str, groups: Optional[Groups]) -> MapCell:
    nan = float("nan")
    return MapCell(None, nan, nan, nan, nan, nan, nan, None, groups, status, message)


def map_chunk(cells, base, names, periods, solver):
    """Chunk function: one row of ``CELL_DTYPE`` and an error message per cell."""
    buf = _Buffers(periods)
    out = []
    for values in cells:
        g = None
        try:
            g = apply_settings(base, dict(zip(names, values)))
            c = run_cell(g, periods, solver, buf)
        except ParameterError as e:
            c = _failed(STATUS_INVALID, str(e), None)
        except SolverError as e:
            c = _failed(STATUS_SOLVER, f"{type(e).__name__}: {e}", g)
        out.append((c.row(), c.error))
    return out


def regime_map(groups: Groups, axes: Sequence[Axis], *, periods: int = 300,
               solver: SolverOptions = SolverOptions(), executor: Optional[Executor] = None,
               options: ExecutorOptions = ExecutorOptions(), attrs: Optional[dict] = None):
    """The regime map of ``groups`` over 1 to 3 axes.

    Parameters
    ----------
    groups : Groups
        Base scene (the axes override its parameters cell by cell).
    axes : sequence of Axis
        1 to 3 axes, distinct names.
    periods : int
        Forcing periods per cell, from rest (>= 4).
    solver : SolverOptions
    executor : Executor, optional
        A running executor (reused); default one made from ``options``.
    options : ExecutorOptions
    attrs : dict, optional
        Extra dataset attributes (e.g. the preset name and the ``--set`` overrides).

    Returns
    -------
    xarray.Dataset
        Dimensions: the axis names (coordinates = their values, with units);
        variables of ``CELL_DTYPE`` (see the module docstring).  Attributes:
        ``periods``, ``method``, ``rtol``, ``atol``, ``groups`` and ``scales``
        of the base scene (JSON), ``failed_cells``, ``errors`` (JSON list of
        the first messages), ``wall_time_s``, ``cpu_time_s`` (summed over the
        workers), ``workers``.
    """
    import xarray as xr
    axes = list(axes)
    if not 1 <= len(axes) <= 3:
        raise ParameterError("axes", len(axes), "1 to 3 axes")
    names = tuple(a.name for a in axes)
    if len(set(names)) != len(names):
        raise ParameterError("axes", ",".join(names), "distinct parameter names")
    targets = [setting_target(n) for n in names]
    if len(set(targets)) != len(targets):
        raise ParameterError("axes", ",".join(names), "axes that change different parameters")
    if not (isinstance(periods, (int, np.integer)) and 4 <= periods <= 10_000_000):
        raise ParameterError("periods", periods, "an integer in [4, 1e7]")
    shape = tuple(len(a.values) for a in axes)
    # the corners of the grid are validated here, so that a bad range fails before any work
    for corner in np.ndindex(*(2,) * len(axes)):
        apply_settings(groups, {a.name: a.values[-1 if c else 0] for a, c in zip(axes, corner)})
    grid = np.stack(np.meshgrid(*[np.asarray(a.values) for a in axes], indexing="ij"), axis=-1)
    cells = [tuple(float(v) for v in row) for row in grid.reshape(-1, len(axes))]
    own = executor is None
    ex = Executor(options) if own else executor
    try:
        ex.connect()
        t0 = _time.perf_counter()
        cpu0 = ex.cpu_s
        res = ex.run(map_chunk, cells, fixed=(groups, names, int(periods), solver),
                     cost_s=periods * SECONDS_PER_PERIOD, label="map")
        wall = _time.perf_counter() - t0
        cpu = ex.cpu_s - cpu0
        workers = ex.workers
    finally:
        if own:
            ex.close()
    table = np.array([r for r, _ in res], dtype=CELL_DTYPE).reshape(shape)
    errors = [f"{dict(zip(names, cells[i]))}: {m}" for i, (_, m) in enumerate(res) if m]
    coords = {}
    for a in axes:
        coords[a.name] = xr.Variable(a.name, np.asarray(a.values, dtype=float),
                                     attrs={"units": a.unit, "long_name": a.name})
    data = {}
    for name in CELL_DTYPE.names:
        long, unit = _VARS[name]
        data[name] = xr.Variable(names, table[name], attrs={"long_name": long, "units": unit})
    at = {
        "title": "hammerbit regime map",
        "periods": int(periods), "method": solver.method, "rtol": solver.rtol, "atol": solver.atol,
        "groups": json.dumps({k: (None if isinstance(v, float) and math.isinf(v) else v)
                              for k, v in groups.values().items()}),
        "scales": json.dumps(groups.scales.to_dict()),
        "failed_cells": len(errors), "errors": json.dumps(errors[:20]),
        "wall_time_s": wall, "cpu_time_s": cpu, "workers": int(workers),
        "total_periods": int(periods * len(cells)),
    }
    at.update(attrs or {})
    return xr.Dataset(data, coords=coords, attrs=at)


def _nested(a: np.ndarray, *, integer: bool = False):
    """Nested lists, NaN -> None."""
    if a.ndim == 0:
        v = float(a)
        return None if not math.isfinite(v) else (int(v) if integer else v)
    return [_nested(x, integer=integer) for x in a]


def eligible_cells(ds) -> np.ndarray:
    """Cells that may be the best one: valid (ran, a drilling point), no flag of the scene
    (:data:`FLAG_FIELDS`: runaway, bounce, tension, a transient period, ...) and inside the paper's
    domain (:data:`DOMAIN_FIELDS`: a < b, a + b <= 1, b <= mu) (boolean array, the map's shape)."""
    ok = ds["valid"].values == 1
    for name in tuple(FLAG_FIELDS) + tuple(DOMAIN_FIELDS.values()):
        if name in ds:
            ok &= ds[name].values == 0
    return ok


def best_valid_cell(ds) -> Optional[dict]:
    """The eligible cell (:func:`eligible_cells`: a drilling point, unflagged, inside the domain) of
    the highest ROP: ``{"index", "values", "rop_m_per_h", ...}``, or None."""
    rop = np.where(eligible_cells(ds), ds["rop_m_per_h"].values, np.nan)
    if not np.isfinite(rop).any():
        return None
    i = np.unravel_index(int(np.nanargmax(rop)), rop.shape)
    names = list(ds["period"].dims)
    return {"index": [int(k) for k in i], "values": {n: float(ds[n].values[k]) for n, k in zip(names, i)},
            "rop_m_per_h": float(rop[i]), "rop_mm_per_period": float(ds["rop_mm_per_period"].values[i]),
            "period": None if not np.isfinite(ds["period"].values[i]) else int(ds["period"].values[i])}


def map_to_json(ds) -> dict:
    """The JSON form: ``axes`` and nested lists (one level per axis); nondimensional fields say so."""
    names = [d for d in ds["period"].dims]
    flags = np.empty(ds["period"].shape, dtype=object)
    domain = np.empty(ds["period"].shape, dtype=object)
    rules = {"domain_a_ge_b": "a >= b", "domain_a_plus_b_gt_1": "a + b > 1", "domain_b_gt_mu": "b > mu"}
    for idx in np.ndindex(*flags.shape):
        flags[idx] = [f for f in FLAG_FIELDS if int(ds[f].values[idx])]
        domain[idx] = [rule for f, rule in rules.items() if int(ds[f].values[idx])]

    def nest(a):
        return [nest(x) for x in a] if a.ndim > 1 else [list(x) for x in a]

    out = {
        "axes": [{"name": n, "unit": ds[n].attrs.get("units", ""), "values": [float(v) for v in ds[n].values]}
                 for n in names],
        "period": _nested(ds["period"].values, integer=True),
        "flags": nest(flags),
        "paper_domain_outside": nest(domain),
        "best_valid_cell": best_valid_cell(ds),
        "regime_bits": dict(REGIME_BITS),
    }
    for name in CELL_DTYPE.names:
        if name in ("period",) + FLAG_FIELDS or name in rules:
            continue
        out[name] = _nested(ds[name].values.astype(float),
                            integer=name in ("status", "valid", "bounces", "settled_after", "regime"))
    for f in FLAG_FIELDS:
        out[f] = _nested(ds[f].values.astype(float), integer=True)
    for k in ("periods", "method", "rtol", "failed_cells", "wall_time_s", "workers", "total_periods"):
        out[k] = ds.attrs.get(k)
    out["errors"] = json.loads(ds.attrs.get("errors", "[]"))
    for k in ("groups", "scales"):
        out[k] = json.loads(ds.attrs[k])
    return out
