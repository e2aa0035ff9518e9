"""Coverage of the co-simulation's coupling-error estimate over random scenes and strings.

For each of ``N`` random scenes (string, hammer frequency and amplitude, fixed hook or a feed,
an adaptive run at ``tol`` or a fixed step) the run's own estimate of its relative error in the
WOB amplitude and in the penetration is compared with its true error against a fixed 2.5e-5 s
run of the same scene (the truth: about 1e-6 from the monolithic reference).  Reported: the
*coverage*, the fraction of (run, quantity) pairs with a true error above
:data:`TRUE_FLOOR` whose estimate / true error lies within 1/3..3 (goal >= 95 %), apart for the
amplitude and the penetration, and how often an exit-0 run (estimate within tol / 3) is within
``tol`` of the truth.  Runs that claim no estimate (impacts; a first harmonic whose error misses the
claim and is mostly a phase lag, :func:`hammerbit.cosim.error.phase_dominated`) are counted apart, by
reason, with their true errors; a scene whose
run fails (a coarse fixed step that makes the coupling unstable or the hammer's solver give up)
is listed apart with its error.

Runs are short (6 to 12 forcing periods on the field strings, 3 or 4 on the lab's) so that
``N = 100`` takes minutes: ``python -m benchmarks --only estimate_coverage`` (``--quick``: 16 scenes).
"""
from __future__ import annotations

import math
import time

import numpy as np

from benchmarks import harness_command, save_result, stage_logger, summary_row

NAME = "estimate_coverage"
#: Below this true relative error the ratio means little (the truth's own error is about 1e-6).
TRUE_FLOOR = 1e-6
#: The truth's fixed step [s].
TRUTH_STEP = 2.5e-5
#: The estimate must be within this factor of the true error.
FACTOR = 3.0
SEED = 33

SHORT = '''name = "field-900m"
description = "800 m of 5 in pipe with tool joints above 100 m of 6.5 in collars"
modal_damping_ratio = 0.03
mud_density = 1100.0
max_element_length = 10.0
[boundaries]
top = "fixed"
bottom = "free"
[[section]]
name = "drill pipe"
length = 800.0
od = 0.127
id = 0.1086
linear_mass = 33.6
[[section]]
name = "drill collars"
length = 100.0
od = 0.1651
id = 0.0714375
'''


def _strings():
    from hammerbit.drillstring import load_string, loads_string
    return {"field-2200m": load_string("field-2200m"), "field-900m": loads_string(SHORT),
            "lab": load_string("lab")}


def _scene(rng, names):
    """One random scene: ``(string name, frequency ratio, a, top, periods, step)``: ``step`` None
    for the adaptive run, else the fixed step as a fraction of the largest one the scene resolves."""
    name = names[int(rng.integers(len(names)))] if rng.uniform() > 0.1 else "lab"
    ratio = float(rng.uniform(0.7, 1.8))
    a = float(rng.uniform(0.03, 0.3))
    top = "fixed" if rng.uniform() < 0.5 else f"feed:{float(rng.choice([5.0, 20.0, 60.0])):g}"
    periods = int(rng.integers(6, 13)) if name != "lab" else int(rng.integers(3, 5))
    step = None if rng.uniform() < 0.5 else float(rng.choice([0.1, 0.25, 0.5]))
    return name, ratio, a, top, periods, step


def _one(string, scene, tol):
    from hammerbit.cosim.config import CosimConfig, CouplingInstabilityError, default_hammer
    from hammerbit.cosim.error import step_limits
    from hammerbit.cosim.master import cosimulate
    from hammerbit.cosim.string_side import StringSide
    from hammerbit.model.solver_errors import SolverError
    from hammerbit.drillstring.top import TopCondition
    name, ratio, a, top, periods, step = scene
    base = default_hammer(string)
    f = base.frequency * ratio
    rig = base.replace(frequency=f, amplitude=a * base.scales.friction_force)
    stop = periods / f
    c = CosimConfig(stop=stop, rig=rig, top=TopCondition.parse(top), tol=tol, record=("wob", "bit_position"))
    side = StringSide(string, c)                  # one string side for the truth and the run
    try:
        truth = cosimulate(string, c.replace(step=TRUTH_STEP, estimate=False, check_step=False), side=side)
        if step is None:
            run = cosimulate(string, c.replace(adaptive=True, step=min(1e-3, 0.05 / f)), side=side)
        else:
            h = step * min(lim.max_step_s for lim in step_limits(side, c))
            run = cosimulate(string, c.replace(step=h), side=side)
    except (CouplingInstabilityError, SolverError) as e:
        return {"scene": [name, f, a, top, stop, step], "failed": f"{type(e).__name__}: {e}"[:300]}
    est = run.estimate
    floor = est.penetration_floor_m
    true_amp = abs(run.wob_amplitude() / truth.wob_amplitude() - 1)
    true_pen = abs(run.penetration_m - truth.penetration_m) / max(abs(truth.penetration_m), floor)
    return {"string": name, "frequency_hz": f, "a": a, "top": top, "stop_s": stop,
            "mode": "adaptive" if step is None else f"fixed, {step:g} of the largest resolving step",
            "claimed": bool(est.claimed), "meets_tolerance": bool(est.meets_tolerance), "note": est.note,
            "har": est.wob_harmonic_rel,
            "impacts": int(run.counts.get("impacts", 0)), "slips": int(run.counts.get("slips", 0)),
            "amplitude": {"true": true_amp, "estimate": est.wob_amplitude_rel},
            "penetration": {"true": true_pen, "estimate": est.penetration_rel}}


def _coverage(rows, key, mode=None):
    pairs = [r[key] for r in rows if r["claimed"] and r[key]["true"] > TRUE_FLOOR
             and (mode is None or r["mode"].startswith(mode))]
    within = [p for p in pairs if 1 / FACTOR <= p["estimate"] / p["true"] <= FACTOR]
    ratios = [p["estimate"] / p["true"] for p in pairs]
    return {"pairs": len(pairs), "within": len(within),
            "coverage": len(within) / len(pairs) if pairs else math.nan,
            "ratio_min": min(ratios) if ratios else math.nan, "ratio_max": max(ratios) if ratios else math.nan}


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    log = stage_logger(NAME, verbose)
    n, tol = (16 if quick else 100), 1e-3
    rng = np.random.default_rng(SEED)
    strings = _strings()
    names = [k for k in strings if k != "lab"]
    rows, failed, t0 = [], [], time.perf_counter()
    for i in range(n):
        scene = _scene(rng, names)
        row = _one(strings[scene[0]], scene, tol)
        (failed if "failed" in row else rows).append(row)
        if verbose and (i + 1) % 10 == 0:
            log(f"{i + 1}/{n} scenes, {time.perf_counter() - t0:.0f} s")
    amp, pen = _coverage(rows, "amplitude"), _coverage(rows, "penetration")
    by_mode = {m: {"amplitude": _coverage(rows, "amplitude", m), "penetration": _coverage(rows, "penetration", m)}
               for m in ("adaptive", "fixed")}
    exit0 = [r for r in rows if r["meets_tolerance"]]
    held = [r for r in exit0 if max(r["amplitude"]["true"], r["penetration"]["true"]) <= tol]
    cmd = harness_command(NAME, quick)
    summary = [summary_row(
        f"coupling-error estimate coverage over {n} random scenes on {len(strings)} strings (adaptive and fixed "
        f"steps, fixed hook or feed; truth: fixed {TRUTH_STEP:g} s run): estimate/true within 1/3..3, "
        f"true error > {TRUE_FLOOR:g}",
        f"amplitude {amp['coverage']:.0%} ({amp['within']}/{amp['pairs']}), penetration {pen['coverage']:.0%} "
        f"({pen['within']}/{pen['pairs']})", goal=">= 95 %",
        met=bool(amp["coverage"] >= 0.95 and pen["coverage"] >= 0.95), command=cmd),
        summary_row(
        "the same, by run: adaptive (the default, tol 1e-3) and fixed steps (0.1-0.5 of the largest step "
        "that resolves the scene)",
        "; ".join(f"{m}: amplitude {v['amplitude']['within']}/{v['amplitude']['pairs']}, penetration "
                  f"{v['penetration']['within']}/{v['penetration']['pairs']}" for m, v in by_mode.items()),
        goal=">= 95 %", met=all(v[k]["coverage"] >= 0.95 for v in by_mode.values() for k in v
                                if v[k]["pairs"]), command=cmd),
        summary_row(f"exit-0 runs (estimate within tol/3, tol {tol:g}) within tol of the truth",
                    f"{len(held)}/{len(exit0)}", goal="all", met=len(held) == len(exit0), command=cmd)]
    result = {"benchmark": NAME, "quick": quick, "command": cmd, "scenes": n, "tol": tol,
              "truth_step_s": TRUTH_STEP, "true_floor": TRUE_FLOOR, "amplitude": amp, "penetration": pen,
              "by_mode": by_mode, "exit0_runs": len(exit0), "exit0_within_tol": len(held),
              "unclaimed_runs": sum(not r["claimed"] for r in rows),
              "unclaimed_phase_dominated": sum(not r["claimed"] and "phase" in r["note"] for r in rows),
              "unclaimed_impacts": sum(not r["claimed"] and "impacts" in r["note"] for r in rows),
              "failed_runs": failed,
              "wall_time_s": time.perf_counter() - t0,
              "runs": rows, "summary": summary}
    save_result(NAME, result)
    return result
