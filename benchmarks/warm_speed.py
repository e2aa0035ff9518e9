"""Warm solver speed of one checkout, to compare two checkouts in one session.

Run it with each checkout's own Python (for example a venv with ``pip install --no-deps -e``
of an older commit), alternating, and compare the JSON it prints: the best of N timings of
200 forcing periods of a few fixed scenes. The paper presets' calibration changed, so the
paper scenes are given the old groups in both checkouts.

    python benchmarks/warm_speed.py 30
"""
import json, sys, time
try:
    from hammerbit.model.presets import preset
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.scene.simulate import simulate
except ImportError:
    from hammerbit.model.params import preset
    from hammerbit.model.stepping import SolverOptions
    from hammerbit.simulate import simulate
SCENES = [("paper-fig9", {"a": 0.083}, "adaptive"), ("paper-fig12", {"a": 0.06}, "adaptive"),
          ("paper-fig9", {"a": 0.083}, "dp54"), ("paper-fig9", {"a": 0.083}, "rk4"), ("lab", {}, "adaptive")]
# the same groups in both checkouts: the paper presets' calibration changed, so the old values are set
OLD = {"xi": 0.074, "mu": 0.85}
out = {}
for name, ch, method in SCENES:
    g = preset(name).replace(**ch)
    if name.startswith("paper"):
        g = g.replace(**OLD)
    opts = SolverOptions(method=method)
    simulate(g, 20, solver=opts)
    best = float("inf")
    for _ in range(int(sys.argv[1]) if len(sys.argv) > 1 else 15):
        t = time.perf_counter(); simulate(g, 200, solver=opts); best = min(best, time.perf_counter() - t)
    out[f"{name} {ch} {method}"] = best
print(json.dumps(out))
