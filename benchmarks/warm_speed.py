"""Warm solver speed of one checkout: the probe that ``bench_warm_speed`` runs in two checkouts.

It prints JSON: for each scene the best of N timings (kernels compiled and cached
by a warm-up call first) of 200 forcing periods of ``simulate``, and of a small
single-worker bifurcation sweep (the throughput benchmark's scene, shortened);
and the digests of each scene's result, field by field (wall times and the
scene's input aside), so that the two checkouts' results can be compared bit
for bit.
The paper presets' calibration changed after the code it is compared with, so the
paper scenes are given the old groups in both checkouts: the same dynamics, the
same events, the same work.

    python -m benchmarks --only warm_speed      # this checkout against the code before, same run
    python benchmarks/warm_speed.py 30          # one checkout, best of 30
"""
import dataclasses
import hashlib
import json
import sys
import time

import numpy as np

try:  # the layout of this checkout
    from hammerbit.model.presets import preset
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.scene.simulate import Record, simulate
except ImportError:  # the layout before the split into packages (13a99bd)
    from hammerbit.model.params import preset
    from hammerbit.model.stepping import SolverOptions
    from hammerbit.simulate import Record, simulate
from hammerbit.studies.bifurcation import bifurcation
from hammerbit.studies.executor import ExecutorOptions

SCENES = [("paper-fig9", {"a": 0.083}, "adaptive"), ("paper-fig12", {"a": 0.06}, "adaptive"),
          ("paper-fig9", {"a": 0.083}, "dp54"), ("paper-fig9", {"a": 0.083}, "rk4"), ("lab", {}, "adaptive")]
#: the paper presets' groups before their calibration changed, set in both checkouts
OLD_PAPER_GROUPS = {"xi": 0.074, "mu": 0.85}
PERIODS = 200
#: the throughput benchmark's sweep (a in [0, 0.25], rtol 1e-8), fewer values
SWEEP = {"values": np.linspace(0.0, 0.25, 24), "periods": 300, "keep": 64, "rtol": 1e-8, "atol": 1e-10}


def _groups(name, changes):
    g = preset(name).replace(**changes)
    return g.replace(**OLD_PAPER_GROUPS) if name.startswith("paper") else g


#: result fields left out of the digests: timings, and the scene's input (its type's repr changed)
NOT_DIGESTED = ("wall_time_s", "groups")


def digest(value) -> str:
    """A SHA-256 of ``value``'s bits: arrays by dtype, shape and bytes, dicts by sorted key, dataclasses
    by field (:data:`NOT_DIGESTED` aside), floats by ``repr`` (every bit), anything else by ``repr``."""
    h = hashlib.sha256()
    if isinstance(value, np.ndarray):
        a = np.ascontiguousarray(value)
        h.update(f"{a.dtype.str}{a.dtype.descr}{a.shape}".encode())
        h.update(a.tobytes())
    elif isinstance(value, dict):
        for k in sorted(value, key=str):
            h.update(f"{k!s}={digest(value[k])};".encode())
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for name, d in result_digests(value).items():
            h.update(f"{name}={d};".encode())
    elif isinstance(value, (list, tuple)):
        for v in value:
            h.update(f"{digest(v)},".encode())
    elif isinstance(value, (float, np.floating)):
        h.update(repr(float(value)).encode())
    else:
        h.update(repr(value).encode())
    return h.hexdigest()


def result_digests(result, prefix: str = "") -> dict:
    """``{field: digest}`` of a result dataclass (``SimResult``, ``BifurcationResult``); a field that
    is a dataclass itself (the scene's flags) by its own fields, as ``flags.code``, ``flags.bounce``,
    ... (a field added to it later leaves the others comparable)."""
    out = {}
    for f in dataclasses.fields(result):
        if f.name in NOT_DIGESTED:
            continue
        value = getattr(result, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            out.update(result_digests(value, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = digest(value)
    return out


def best_of(fn, repeats, digests=None, scene=None):
    """The best wall time of ``repeats`` calls of ``fn`` after a warm-up call, whose result's digests
    go to ``digests[scene]``."""
    first = fn()  # compile or load the kernels, warm the caches
    if digests is not None:
        digests[scene] = result_digests(first)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


#: what each ``simulate`` call records: as a user calls it (the default record: since the
#: scene's flags, a run keeps its Poincaré rows whether asked or not) and the same work in
#: both checkouts (the Poincaré rows asked for)
RECORDS = {"as called": Record(), "same work": Record(poincare=True)}


def measure(repeats):
    """``{"seconds": {scene: best time}, "digests": {scene: {field: digest}}}``."""
    out, digests = {}, {}
    for name, changes, method in SCENES:
        g, opts = _groups(name, changes), SolverOptions(method=method)
        for label, record in RECORDS.items():
            scene = f"{name} {changes} {method}, {label}"
            out[scene] = best_of(lambda: simulate(g, PERIODS, solver=opts, record=record), repeats, digests, scene)
    g = _groups("paper-fig9", {})
    solver = SolverOptions(rtol=SWEEP["rtol"], atol=SWEEP["atol"])
    scene = "bifurcation sweep, 1 worker"
    out[scene] = best_of(
        lambda: bifurcation(g, "a", SWEEP["values"], periods=SWEEP["periods"], keep=SWEEP["keep"], solver=solver,
                            options=ExecutorOptions(workers=1)), max(3, repeats // 5), digests, scene)
    return {"seconds": out, "digests": digests}


if __name__ == "__main__":
    print(json.dumps(measure(int(sys.argv[1]) if len(sys.argv) > 1 else 15)))
