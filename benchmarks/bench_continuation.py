"""The P1/P2 boundary of paper-fig9 in (a, eta): continuation against a brute-force regime map.

``python -m benchmarks --only continuation`` measures, in one process,

* the continuation: the period-1 orbit at a = 0.2 followed down to its
  period-doubling, then that boundary followed in eta over [0.8, 1.2] (41
  points) -- the curve;
* ``regime_map`` of paper-fig9 over a in [0.12, 0.22] x eta in [0.8, 1.2],
  41 x 41 cells at 1,000 periods each (the map the issue compares with);

both after a warm-up (numba compiled).  Goal: the curve in at most 1/30 of
the map's wall time.  It also counts the map's progressing period-1 cells
(a stuck bit's orbit is period-1 too, with no progression) that lie below
the curve (where the period-1 orbit is unstable) by more than one cell: those
would contradict it.  Period-2 cells above the curve are no contradiction: the
stable period-2 orbit coexists with the period-1 one there and a run from rest
may reach either (docs/continuation.md).
Writes ``results/continuation.json``.
"""
from __future__ import annotations

import time

import numpy as np

from benchmarks import fmt_ratio, fmt_time, harness_command, machine_info, save_result, summary_row

NAME = "continuation"
GOAL_RATIO = 30.0
A_RANGE = (0.12, 0.22)
ETA_RANGE = (0.8, 1.2)


def _config(quick: bool) -> dict:
    if quick:
        return {"cells": 11, "periods": 300, "curve_points": 11}
    return {"cells": 41, "periods": 1000, "curve_points": 41}


def _curve(points: int):
    from hammerbit.continuation import correct_orbit, orbit_from_simulation
    from hammerbit.continuation.bifurcation import detect
    from hammerbit.continuation.boundary import follow_boundary
    from hammerbit.continuation.continuation import follow_branch
    from hammerbit.continuation.parameter import Parameter
    from hammerbit.model.presets import preset
    base = preset("paper-fig9").replace(a=0.2)
    n, s = orbit_from_simulation(base)
    orbit = correct_orbit(base, s, n)
    param = Parameter.on("a", base)
    branch = follow_branch(param, base, orbit, A_RANGE[0])
    pd = next(b for b in detect(param, base, branch.points, 0) if b.kind == "period-doubling")
    return follow_boundary(base, pd, "a", "eta", *ETA_RANGE, points=points)


def _map(cfg):
    from hammerbit.model.presets import preset
    from hammerbit.studies.map import Axis, regime_map
    n = cfg["cells"]
    axes = [Axis.parse(f"a={A_RANGE[0]}:{A_RANGE[1]}:{n}"), Axis.parse(f"eta={ETA_RANGE[0]}:{ETA_RANGE[1]}:{n}")]
    return regime_map(preset("paper-fig9"), axes, periods=cfg["periods"])


def _contradictions(ds, curve) -> int:
    """Progressing period-1 cells more than one cell below the period-doubling curve (a_pd(eta) interpolated)."""
    a = ds["a"].values
    eta = ds["eta"].values
    pts = sorted(curve.points, key=lambda p: p[1])
    a_pd = np.interp(eta, [p[1] for p in pts], [p[0] for p in pts])
    da = a[1] - a[0]
    per = ds["period"].transpose("a", "eta").values
    rop = ds["rop_m_per_h"].transpose("a", "eta").values
    bad = 0
    for j in range(len(eta)):
        for i in range(len(a)):
            # a period-1 cell with no progression is the stuck bit's orbit, another period-1 orbit
            if per[i, j] == 1 and rop[i, j] > 0 and a[i] < a_pd[j] - da:
                bad += 1
    return bad


def run(quick: bool = False) -> dict:
    cfg = _config(quick)
    _curve(3)                                   # warm-up: compiles the continuation's kernels
    _map({"cells": 2, "periods": 10})           # and the map's
    t0 = time.perf_counter()
    curve = _curve(cfg["curve_points"])
    t_curve = time.perf_counter() - t0
    t0 = time.perf_counter()
    ds = _map(cfg)
    t_map = time.perf_counter() - t0
    ratio = t_map / t_curve
    bad = _contradictions(ds, curve)
    cmd = harness_command(NAME, quick)
    result = {
        "benchmark": NAME, "quick": quick, "command": cmd, "machine": machine_info(), "config": cfg,
        "curve_wall_s": t_curve, "map_wall_s": t_map, "ratio": ratio, "curve_points": len(curve.points),
        "curve_stopped": curve.stopped, "curve": curve.points, "map_workers": int(ds.attrs["workers"]),
        "period1_cells_below_curve": bad,
        "summary": [summary_row(
            f"P1/P2 boundary of paper-fig9 in (a, eta): the period-doubling curve by continuation "
            f"({len(curve.points)} points) vs a {cfg['cells']}x{cfg['cells']} map at {cfg['periods']} periods "
            f"({bad} progressing period-1 cells below the curve)",
            fmt_time(t_curve), peer=fmt_time(t_map), ratio=fmt_ratio(ratio), goal=f">= {GOAL_RATIO:g}x",
            met=ratio >= GOAL_RATIO, command=cmd)],
    }
    save_result(NAME, result)
    return result
