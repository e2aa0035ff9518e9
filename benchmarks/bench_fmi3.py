"""FMI 3.0 native FMU benchmark: HammerBitRock.fmu built with ``--runtime native --fmi-version 3``.

Measures, in one run, with the FMI 2.0 native FMU of the same sources built beside it:

1. **Co-Simulation step, FMI 3.0 against FMI 2.0**, from plain C hosts (``tests/fmi3_host.c``,
   ``tests/fmu_native_host.c``) as FMI toolchains call an FMU: 100 s of model time at h = 1 ms
   on the lab rig, each host a new process, runs alternating (ABBA); the ratio is the median of
   the pairs' ratios.  Goal: at most 1.05x.
2. **Early return on against off** over 10 s at h = 1 ms (the FMI 3.0 host with
   ``earlyReturnAllowed``), alternating the same way; the number of early returns is recorded.
3. **Model Exchange against Co-Simulation** of the FMI 3.0 FMU through fmpy: paper-fig12
   (a = 0.06) over 10 s, ME with CVode at rtol 1e-10, CS at h = 1 ms with early return and Event
   Mode; wall time of each.

Run: ``python -m benchmarks --only fmi3`` (``--quick`` for a short run).
"""
from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

if __name__ == "__main__":  # run as a script: the package lives in the repository root
    _root = str(Path(__file__).resolve().parents[1])
    if _root not in sys.path:
        sys.path.insert(0, _root)

from benchmarks import harness_command, machine_info, save_result, summary_row  # noqa: E402

NAME = "fmi3"
TESTS = Path(__file__).resolve().parents[1] / "tests"
GOAL_RATIO = 1.05
#: model time of the early-return comparison [s]
EARLY_SECONDS = 10


def _build(tmp: Path):
    from hammerbit.fmu.build import build_fmu
    dirs = {}
    for version in (2, 3):
        fmu = build_fmu(tmp / f"v{version}" / "HammerBitRock.fmu", runtime="native", fmi_version=version)
        d = tmp / f"x{version}"
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(d)
        (d / "resources").mkdir(exist_ok=True)
        dirs[version] = (fmu, d)
    return dirs


def _hosts(tmp: Path, dirs) -> dict:
    import fmpy
    from fmpy import read_model_description

    from hammerbit.fmu.native import find_compiler
    inc = Path(fmpy.__file__).parent / "c-code"
    cc = find_compiler()
    h2, h3 = tmp / "h2", tmp / "h3"
    subprocess.run([cc, "-O2", "-I", str(inc), "-o", str(h2), str(TESTS / "fmu_native_host.c"), "-ldl",
                    "-lpthread"], check=True)
    subprocess.run([cc, "-O2", "-I", str(inc), "-o", str(h3), str(TESTS / "fmi3_host.c"), "-ldl"], check=True)
    md2 = read_model_description(str(dirs[2][1] / "modelDescription.xml"))
    md3 = read_model_description(str(dirs[3][1] / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md3.modelVariables}["bit_position"]
    return {"md2": md2, "md3": md3, "h2": h2, "h3": h3, "vr": vr}


def _timed(cmd) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def _early_returns(cmd) -> int:
    """The early returns a host run took (its ``returns <n>`` line)."""
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return int(next(line.split()[1] for line in out.splitlines() if line.startswith("returns ")))


def _abba(run_a, run_b, pairs: int) -> dict:
    ratios = []
    for k in range(pairs):
        if k % 2:
            b, a = run_b(), run_a()
        else:
            a, b = run_a(), run_b()
        ratios.append(a / b)
    return {"median": statistics.median(ratios), "ratios": ratios}


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    from fmpy import simulate_fmu

    from hammerbit.model.presets import preset
    sys.path.insert(0, str(TESTS))
    from test_fmi3_native import scene_start_values
    steps, pairs = (20000, 4) if quick else (100000, 8)
    early_steps = EARLY_SECONDS * 1000          # h = 1 ms
    cmd = harness_command(NAME, quick)
    with tempfile.TemporaryDirectory(prefix="hammerbit_bench_fmi3_") as tmp:
        tmp = Path(tmp)
        dirs = _build(tmp)
        h = _hosts(tmp, dirs)
        d2, d3 = dirs[2][1], dirs[3][1]
        fmi2 = [str(h["h2"]), str(d2 / "binaries/linux64/HammerBitRock.so"), f"file://{d2}/resources",
                h["md2"].guid, "1", f"steps={steps}", f"out={h['vr']}"]

        def fmi3(early, n=steps):
            return [str(h["h3"]), str(d3 / "binaries/x86_64-linux/HammerBitRock.so"), f"{d3}/resources/",
                    h["md3"].guid, str(n), "1e-3", str(h["vr"]), f"early={int(early)}"]
        step = _abba(lambda: _timed(fmi3(False)), lambda: _timed(fmi2), pairs)
        early = _abba(lambda: _timed(fmi3(True, early_steps)), lambda: _timed(fmi3(False, early_steps)), pairs)
        early["returns"] = _early_returns(fmi3(True, early_steps))
        g = preset("paper-fig12").replace(a=0.06)
        sv = scene_start_values(g)
        t0 = time.perf_counter()
        me = simulate_fmu(str(dirs[3][0]), fmi_type="ModelExchange", relative_tolerance=1e-10, stop_time=10.0,
                          output_interval=1e-3, start_values=sv)
        t_me = time.perf_counter() - t0
        t0 = time.perf_counter()
        cs = simulate_fmu(str(dirs[3][0]), stop_time=10.0, output_interval=1e-3, step_size=1e-3,
                          early_return_allowed=True, use_event_mode=True, start_values=sv)
        t_cs = time.perf_counter() - t0
    res = {"benchmark": NAME, "quick": quick, "command": cmd, "machine": machine_info(),
           "steps": steps, "pairs": pairs, "fmi3_vs_fmi2_step": step, "early_vs_plain": early,
           "me_s": t_me, "cs_s": t_cs,
           "me_bit_position_m": float(me["bit_position"][-1]), "cs_bit_position_m": float(cs["bit_position"][-1])}
    r = step["median"]
    res["summary"] = [
        summary_row(f"FMI 3.0 native FMU: a run of {steps} steps (h = 1 ms) from a C host, FMI 3.0 vs FMI 2.0 "
                    f"(new process each, median of {pairs} alternating pairs)", f"{r:.3f}x", ratio=r,
                    goal=f"<= {GOAL_RATIO}x", met=r <= GOAL_RATIO, command=cmd),
        summary_row(f"FMI 3.0 native FMU: {EARLY_SECONDS} s at h = 1 ms from a C host with earlyReturnAllowed "
                    f"({early['returns']} early returns) vs without", f"{early['median']:.3f}x",
                    ratio=early["median"], command=cmd),
        summary_row("FMI 3.0 native FMU, paper-fig12 10 s: Model Exchange (fmpy CVode, rtol 1e-10) vs "
                    "Co-Simulation (h = 1 ms, early return and Event Mode), wall time",
                    f"{t_me:.2f} s vs {t_cs:.2f} s", ratio=t_me / t_cs, command=cmd)]
    if verbose:
        for row in res["summary"]:
            print(row)
    save_result(NAME, res)
    return res


if __name__ == "__main__":  # pragma: no cover
    run(quick="--quick" in sys.argv)
