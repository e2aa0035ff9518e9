"""Warm solver speed of this checkout against a baseline commit, in the same run.

Issue 30 splits the solver driver ``advance`` into pieces and asks that the
warm speed stay within 3 % of the code before (3b15ef7,
``$HAMMERBIT_BENCH_BASELINE`` to name another commit) on every scene.  This
benchmark checks that commit out into a temporary git worktree, then runs the
probe :mod:`benchmarks.warm_speed` in a fresh process of each checkout,
alternating, ``rounds`` times: the best time per scene over all rounds is
compared, as the ratio this / before (1.0 = the same speed; goal <= 1.03).
Each probe also returns the digests of every scene's result, field by field:
the fields both checkouts return must be bit-identical between them, and in
every round of each (goal: every scene).
Both checkouts run from their sources on the same Python (the packages are
mapped onto ``hammerbit`` and ``hammerbit.model`` as the editable install
does), with the same kernels' numba cache rules; the first call of each probe
compiles or loads its kernels outside the timing.

The scenes: ``simulate`` of 200 periods (paper-fig9 a = 0.083 adaptive, dp54
and rk4; paper-fig12 a = 0.06; lab), each as a user calls it and with the
Poincaré rows asked for, and a single-worker bifurcation sweep (24 values x
300 periods, rtol 1e-8).  The probe sets the paper groups of an older
calibration in both checkouts (the same dynamics in both, whichever the
baseline).  Every scene is judged against the goal; with a baseline older
than the scene's flags (issue 23, e.g. 13a99bd) the scenes "as called" do more
work here and are context only.

Run ``python -m benchmarks --only warm_speed`` (``--quick``: one round of 5).
``$HAMMERBIT_BENCH_ROUNDS`` sets the number of rounds (default 3): on a loaded
machine more rounds bring each checkout's best time closer to its true one.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time

from benchmarks import REPO_ROOT, fmt_ratio, fmt_time, harness_command, machine_info, save_result, stage_logger, \
    summary_row

NAME = "warm_speed"
#: the code before ``advance`` was split into pieces (issue 30 was filed on it)
DEFAULT_BASELINE = "3b15ef7"
#: alternating rounds of the two checkouts (``$HAMMERBIT_BENCH_ROUNDS`` overrides; ``--quick``: 1)
DEFAULT_ROUNDS = 3
#: baselines older than the scene's flags (issue 23): they record less in the scenes "as called"
BASELINES_WITHOUT_FLAGS = ("13a99bd",)
GOAL_RATIO = 1.03
PROBE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "warm_speed.py")
PROBE_TIMEOUT_S = 1800
#: scenes run as a user calls ``simulate``: against a baseline without the scene's flags this
#: code records more there (their Poincaré rows), so they are context, not the goal's comparison
AS_CALLED = ", as called"

#: run the probe against the sources of one checkout: ``coupling/`` as ``hammerbit``,
#: ``fmu_src/`` as ``hammerbit.model`` (what the editable install maps), nothing installed
_BOOT = r"""
import importlib.util, os, runpy, sys
root, probe = sys.argv[1], sys.argv[2]
# an editable install of another checkout must not answer for these packages
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in (getattr(f, "__module__", "") or "")
                    and "editable" not in type(f).__module__]
def package(name, folder):
    spec = importlib.util.spec_from_file_location(name, os.path.join(folder, "__init__.py"),
                                                  submodule_search_locations=[folder])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    return spec, mod
top = package("hammerbit", os.path.join(root, "coupling"))
model = package("hammerbit.model", os.path.join(root, "fmu_src"))
top[1].model = model[1]
model[0].loader.exec_module(model[1])
top[0].loader.exec_module(top[1])
sys.argv = [probe] + sys.argv[3:]
runpy.run_path(probe, run_name="__main__")
"""


def _git(*args, cwd=REPO_ROOT):
    return subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True)


def run_probe(root: str, repeats: int) -> dict:
    """The probe's JSON, run on the sources of ``root`` in a new process."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTHONPATH", None)
    r = subprocess.run([sys.executable, "-c", _BOOT, root, PROBE, str(repeats)], capture_output=True, text=True,
                       env=env, cwd=tempfile.gettempdir(), timeout=PROBE_TIMEOUT_S)
    if r.returncode != 0:
        raise RuntimeError(f"warm-speed probe on {root} failed ({r.returncode}):\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def compare(base: list, ours: list) -> dict:
    """Best time per scene over the rounds of each checkout, and their ratio ours / base."""
    out = {}
    for scene in ours[0]:
        b = min(r[scene] for r in base)
        o = min(r[scene] for r in ours)
        out[scene] = {"before_s": b, "ours_s": o, "ratio": o / b}
    return out


def compare_bits(base: list, ours: list) -> dict:
    """Per scene, the result fields of both checkouts (``{field: digest}`` per round): ``identical``
    (every round of both the same digest), ``differ`` (fields both return, other bits between the
    checkouts or between rounds), ``only_before``/``only_ours`` (fields one checkout's result lacks)."""
    out = {}
    for scene in ours[0]:
        b = [r[scene] for r in base]
        o = [r[scene] for r in ours]
        common = sorted(set(b[0]) & set(o[0]))
        same = [f for f in common if len({r.get(f) for r in b + o}) == 1]
        out[scene] = {"identical": same, "differ": [f for f in common if f not in same],
                      "only_before": sorted(set(b[0]) - set(o[0])), "only_ours": sorted(set(o[0]) - set(b[0]))}
    return out


def _figure(scenes: dict, baseline: str):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(scenes)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.barh(range(len(names)), [scenes[n]["ratio"] for n in names], color="tab:blue")
    ax.axvline(1.0, color="k", lw=0.8)
    ax.axvline(GOAL_RATIO, color="tab:red", ls="--", lw=0.8, label=f"goal {GOAL_RATIO}")
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.set_xlabel(f"wall time, this code / {baseline} (best of the rounds)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def rounds_from_env() -> int:
    """The number of rounds from ``$HAMMERBIT_BENCH_ROUNDS`` (a positive integer), else DEFAULT_ROUNDS."""
    text = os.environ.get("HAMMERBIT_BENCH_ROUNDS", "").strip()
    if not text:
        return DEFAULT_ROUNDS
    try:
        rounds = int(text)
    except ValueError:
        rounds = 0
    if rounds < 1:
        raise ValueError(f"HAMMERBIT_BENCH_ROUNDS={text!r}: expected a positive integer (rounds of the benchmark)")
    return rounds


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    log = stage_logger(NAME, verbose)
    baseline = os.environ.get("HAMMERBIT_BENCH_BASELINE", DEFAULT_BASELINE)
    rounds, repeats = (1, 5) if quick else (rounds_from_env(), 30)
    head = _git("rev-parse", "--short", "HEAD").stdout.strip()
    if _git("cat-file", "-e", f"{baseline}^{{commit}}").returncode != 0:
        log(f"skipped: {REPO_ROOT} is not a git checkout holding commit {baseline} "
            "(set HAMMERBIT_BENCH_BASELINE to a commit it holds)")
        res = {"benchmark": NAME, "skipped": f"no commit {baseline}", "summary": []}
        save_result(NAME, res)
        return res
    with tempfile.TemporaryDirectory(prefix="hammerbit-baseline-") as tmp:
        base_root = os.path.join(tmp, "before")
        r = _git("worktree", "add", "--detach", base_root, baseline)
        if r.returncode != 0:
            raise RuntimeError(f"git worktree add {baseline} failed: {r.stderr.strip()}")
        try:
            base, ours = [], []
            for k in range(rounds):
                t0 = time.perf_counter()
                base.append(run_probe(base_root, repeats))
                ours.append(run_probe(REPO_ROOT, repeats))
                log(f"round {k + 1}/{rounds}: {time.perf_counter() - t0:.1f} s, load {os.getloadavg()[0]:.1f}")
        finally:
            _git("worktree", "remove", "--force", base_root)
    scenes = compare([r["seconds"] for r in base], [r["seconds"] for r in ours])
    bits = compare_bits([r["digests"] for r in base], [r["digests"] for r in ours])
    differ = {scene: b["differ"] for scene, b in bits.items() if b["differ"]}
    context_only = baseline in BASELINES_WITHOUT_FLAGS
    judged = {k: v for k, v in scenes.items() if not (context_only and k.endswith(AS_CALLED))}
    worst = max(s["ratio"] for s in judged.values())
    geo = math.exp(sum(math.log(s["ratio"]) for s in judged.values()) / len(judged))
    cmd = harness_command(NAME, quick)
    summary = []
    for scene, s in scenes.items():
        context = context_only and scene.endswith(AS_CALLED)
        summary.append(summary_row(
            f"warm speed against {baseline}, {scene}"
            + (" (context: this code also records the Poincaré rows of the scene's flags)" if context else "")
            + f": best of {rounds} x {repeats}, alternating processes", fmt_time(s["ours_s"]),
            peer=fmt_time(s["before_s"]), ratio=fmt_ratio(s["ratio"]), goal=None if context else f"<= {GOAL_RATIO}x",
            met=None if context else s["ratio"] <= GOAL_RATIO, command=cmd))
    summary.append(summary_row(f"warm speed against {baseline}, the same work: geometric mean / worst ratio over "
                               "the scenes", f"{geo:.3f}x / {worst:.3f}x", goal=f"<= {GOAL_RATIO}x",
                               met=worst <= GOAL_RATIO, command=cmd))
    fields = sum(len(b["identical"]) + len(b["differ"]) for b in bits.values())
    summary.append(summary_row(
        f"results against {baseline}: scenes whose result fields (all that both return, "
        f"{fields} in all) are bit-identical between the checkouts and their rounds",
        f"{len(bits) - len(differ)} of {len(bits)}", goal="all", met=not differ, command=cmd))
    for scene, s in scenes.items():
        log(f"{scene}: {s['ours_s'] * 1e3:.3f} ms vs {s['before_s'] * 1e3:.3f} ms, ratio {s['ratio']:.3f}; "
            + (f"bits differ in {', '.join(differ[scene])}" if scene in differ else
               f"{len(bits[scene]['identical'])} result fields bit-identical"))
    res = {"benchmark": NAME, "baseline": baseline, "head": head, "rounds": rounds, "repeats": repeats,
           "scenes": scenes, "bits": bits, "before_rounds": base, "ours_rounds": ours, "geo_mean_ratio": geo,
           "worst_ratio": worst, "goal_ratio": GOAL_RATIO, "machine": machine_info(), "summary": summary}
    save_result(NAME, res, _figure(scenes, baseline))
    return res


if __name__ == "__main__":
    from benchmarks import standalone
    standalone(run, __doc__)
