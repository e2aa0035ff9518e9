"""An optimization with no feasible point: exit 6, the binding constraint and the least-violating
point, against a brute force of the same grid computed here with ``simulate``.

The violation of each point is written out in the test, relative to each constraint's limit: the
peak contact force (simulate's, start-up included) over the limit, ``a + b - 1`` (the threshold F0
is 1 in the groups), a bounce or a runaway flag as 1.
"""
from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from cli_run import run_cli
from hammerbit.model.presets import preset
from hammerbit.model.settings import apply_settings
from hammerbit.scene.simulate import simulate
from hammerbit.studies.executor import ExecutorOptions
from hammerbit.studies.optimize import Bound, OptimizeConfig, optimize

LIMIT = 500.0
BOUNDS = (Bound("frequency", 1.0, 1.9), Bound("amplitude", 1.0, 15.0))
GRID, PERIODS = 3, 30


def _violation(g, r):
    v = {"contact_force": max(0.0, r.peak_contact_force_n() - LIMIT) / LIMIT,
         "threshold": max(0.0, g.a + g.b - 1.0)}
    if r.counts["bounce"]:
        v["bounce"] = 1.0
    return v


def test_no_feasible_point_names_the_binding_constraint_and_the_least_violating_point():
    g0 = preset("paper-fig12")
    res = optimize(g0, OptimizeConfig(bounds=BOUNDS, max_contact_force=LIMIT, periods=PERIODS, grid=GRID),
                   options=ExecutorOptions(workers=1))
    assert res.optimum is None and res.infeasible is not None
    brute = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for f in np.linspace(BOUNDS[0].lo, BOUNDS[0].hi, GRID):
            for A in np.linspace(BOUNDS[1].lo, BOUNDS[1].hi, GRID):
                g = apply_settings(g0, {"frequency": float(f), "amplitude": float(A)})
                brute.append(((float(f), float(A)), _violation(g, simulate(g, PERIODS))))
    assert all(max(v.values()) > 0 for _, v in brute)            # nothing is feasible
    best_key, best_v = min(brute, key=lambda kv: max(kv[1].values()))
    inf = res.infeasible
    p = inf.point
    assert (p.values["frequency"], p.values["amplitude"]) == pytest.approx(best_key)
    assert inf.binding == max(best_v, key=best_v.get) == "contact_force"
    assert inf.violations["contact_force"] == pytest.approx(best_v["contact_force"], rel=1e-9)
    assert inf.cells_violating["contact_force"] == sum(v["contact_force"] > 0 for _, v in brute)


def test_cli_infeasible_optimization_exits_6(capsys):
    code, out, err = run_cli(["optimize", "--preset", "paper-fig12", "--bounds", "frequency=1.0:1.9",
                              "amplitude=1:15", "--max-contact-force", str(LIMIT), "--grid", str(GRID),
                              "--periods", str(PERIODS), "--workers", "1", "--json"], capsys)
    assert code == 6, err
    assert "binding constraint: contact_force" in err and "least-violating point" in err
    d = json.loads(out)
    assert d["infeasible"]["binding_constraint"] == "contact_force"
    pt = d["infeasible"]["least_violating_point"]
    assert d["infeasible"]["violations"]["contact_force"]["relative"] == pytest.approx(
        (pt["peak_contact_force_n"] - LIMIT) / LIMIT, rel=1e-12)
    assert "Traceback" not in err


@pytest.mark.slow
def test_the_issues_infeasible_optimization_exits_6(capsys):
    code, out, err = run_cli(["optimize", "--preset", "paper-fig12", "--bounds", "frequency=1.0:1.9",
                              "amplitude=1:15", "--max-contact-force", "500"], capsys)
    assert code == 6, err
    assert "binding constraint" in err
