"""Run a ``drilling.ssp`` in the masters a user would reach for: libcosimpy and FMPy's SSP runner.

Both are fixed-step Jacobi masters.  Each function returns a
:class:`RunnerResult` of the hammer's bit position (the penetration) and rock
force (the WOB) at the communication points, ``time`` first.
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass

import numpy as np

from hammerbit.ssp.package import HAMMER

__all__ = ["RunnerResult", "run_libcosim", "run_fmpy", "RUNNER_DTYPE"]

#: the series a runner records, ``time`` first (SI)
RUNNER_DTYPE = np.dtype([("time", "f8"), ("bit_position", "f8"), ("wob", "f8")])
#: nanoseconds per second (libcosim's clock)
_NS = 1_000_000_000


@dataclass
class RunnerResult:
    """A runner's series (:data:`RUNNER_DTYPE`) and the wall time of its run [s] (set-up included)."""

    runner: str
    data: np.ndarray
    wall_time_s: float

    @property
    def penetration_m(self) -> float:
        return float(self.data["bit_position"][-1])

    def wob_amplitude(self, t_from: float, frequency: float) -> float:
        """The WOB's fundamental harmonic at ``frequency`` [Hz] over the whole forcing periods after
        ``t_from`` [N] (as ``CosimResult.wob_amplitude``)."""
        from hammerbit.cosim.amplitude import fundamental
        return float(fundamental(self.data["time"], self.data["wob"], frequency, t_from)[0])


def run_libcosim(path, stop: float) -> RunnerResult:
    """libcosimpy: ``CosimExecution.from_ssp_file`` (the package's step annotation), stepped to ``stop``."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    log_output_level(CosimLogLevel.ERROR)
    t0 = _time.perf_counter()
    ex = CosimExecution.from_ssp_file(str(path))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    idx = {s.name.decode(): s.index for s in ex.slave_infos()}[HAMMER]
    vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}
    refs = [vr["bit_position"], vr["rock_force"]]
    rows = []
    target = int(round(stop * _NS))
    while True:
        t_ns = ex.status().current_time
        vals = obs.last_real_values(idx, refs)
        rows.append((t_ns / _NS, vals[0], vals[1]))
        if t_ns >= target:
            break
        ex.step()
    wall = _time.perf_counter() - t0
    return RunnerResult("libcosimpy", np.array(rows, dtype=RUNNER_DTYPE), wall)


def run_fmpy(path, stop: float, step: float) -> RunnerResult:
    """FMPy: ``fmpy.ssp.simulate_ssp`` with the fixed step ``step``.

    Its loop adds ``step`` to its clock and records each row at the step's start time with the
    values at its end; the series here is put at the end times ``(k + 1) step``, to ``stop``."""
    from fmpy.ssp.simulation import simulate_ssp
    t0 = _time.perf_counter()
    res = simulate_ssp(str(path), stop_time=stop, step_size=step)
    wall = _time.perf_counter() - t0
    n = int(round(stop / step))
    k = np.arange(1, n + 1)
    out = np.zeros(n, dtype=RUNNER_DTYPE)
    out["time"] = k * step
    out["bit_position"] = res[f"{HAMMER}.bit_position"][:n]
    out["wob"] = res[f"{HAMMER}.rock_force"][:n]
    return RunnerResult("fmpy", out, wall)
