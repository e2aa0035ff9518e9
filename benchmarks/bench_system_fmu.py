"""DrillingSystem.fmu against ``hammerbit cosim``: the same drilling run, both timed in one run.

60 s of auto-driller drilling on field-2200m (55 kN): ``DrillingSystem.fmu``
(``hammerbit fmu build-system``) stepped by fmpy's ``FMU2Slave`` at a 10 ms
master step, reading its outputs at every step, against ``hammerbit cosim``
(adaptive exchange, in-process hammer, tolerance 1e-3) of the same run, each
as a process's wall time of the run itself (the build and the string's set-up
are not counted: both are paid once).  Goal: the FMU at most 0.5x.  The two
penetrations are reported with the ratio.

Run: ``python -m benchmarks --only system_fmu`` (``--quick``: 6 s of drilling).
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __name__ == "__main__":  # run as a script: the package lives in the repository root
    _root = str(Path(__file__).resolve().parents[1])
    if _root not in sys.path:
        sys.path.insert(0, _root)

from benchmarks import (fmt_ratio, fmt_time, harness_command, machine_info, save_result,  # noqa: E402
                        stage_logger, summary_row)

NAME = "system_fmu"
STRING = "field-2200m"
TOP = "auto-driller"
WOB = 55000.0
STOP = 60.0
STEP = 0.01
GOAL_RATIO = 0.5

#: the fmpy loop, in a process of its own: prints the wall time of the stepping and the penetration
_FMPY_LOOP = """
import sys, time
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
path, stop, h = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
md = read_model_description(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
s = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier="DrillingSystem", instanceName="b")
s.instantiate(); s.setupExperiment(startTime=0.0); s.enterInitializationMode(); s.exitInitializationMode()
outs = [vr["bit_position"], vr["mean_wob"], vr["hook_load"]]
n = int(round(stop / h)); t0 = time.perf_counter(); t = 0.0
for k in range(n):
    s.doStep(t, h); t = (k + 1) * h
    x = s.getReal(outs)
wall = time.perf_counter() - t0
print(wall, x[0])
s.terminate(); s.freeInstance()
"""


def run(quick: bool = False, *, verbose: bool = True) -> dict:
    """Run the benchmark; write ``benchmarks/results/system_fmu.json``."""
    log = stage_logger(NAME, verbose)
    stop = 6.0 if quick else STOP
    work = Path(tempfile.mkdtemp(prefix="hammerbit_bench_system_"))
    try:
        t0 = time.perf_counter()
        fmu = work / "DrillingSystem.fmu"
        subprocess.run([sys.executable, "-m", "hammerbit", "fmu", "build-system", "--string", STRING, "--top", TOP,
                        "--wob", str(WOB), "--out", str(fmu)], check=True, capture_output=True)
        log(f"built {fmu.name} in {time.perf_counter() - t0:.1f} s")
        r = subprocess.run([sys.executable, "-c", _FMPY_LOOP, str(fmu), str(stop), str(STEP)], check=True,
                           capture_output=True, text=True)
        fmu_wall, fmu_pen = (float(v) for v in r.stdout.split())
        log(f"DrillingSystem.fmu through fmpy at {STEP * 1e3:g} ms: {fmu_wall:.2f} s")
        r = subprocess.run([sys.executable, "-m", "hammerbit", "cosim", "--string", STRING, "--top", TOP,
                            "--wob", str(WOB), "--stop", str(stop), "--json"], capture_output=True, text=True)
        if r.returncode not in (0, 5):
            raise RuntimeError(f"hammerbit cosim failed: {r.stderr[-2000:]}")
        cosim = json.loads(r.stdout)
        cosim_wall = float(cosim["wall_time_s"])
        log(f"hammerbit cosim: {cosim_wall:.2f} s")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    ratio = fmu_wall / cosim_wall
    cmd = harness_command(NAME, quick)
    res = {"benchmark": NAME, "quick": quick, "command": cmd, "machine": machine_info(),
           "stop_s": stop, "step_s": STEP, "fmu_wall_s": fmu_wall, "cosim_wall_s": cosim_wall, "ratio": ratio,
           "fmu_penetration_m": fmu_pen, "cosim_penetration_m": cosim["penetration_m"],
           "summary": [summary_row(
               f"DrillingSystem.fmu through fmpy at {STEP * 1e3:g} ms vs hammerbit cosim (adaptive, tol 1e-3): "
               f"{stop:g} s of auto-driller drilling on {STRING}, wall time of the run",
               fmt_time(fmu_wall), peer=fmt_time(cosim_wall), ratio=fmt_ratio(ratio), goal=f"<= {GOAL_RATIO}x",
               met=ratio <= GOAL_RATIO, command=cmd)]}
    save_result(NAME, res)
    return res


if __name__ == "__main__":
    run(quick="--quick" in sys.argv)
