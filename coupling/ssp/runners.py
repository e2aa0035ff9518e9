"""Run a ``drilling.ssp`` in the masters a user would reach for: libcosimpy and FMPy's SSP runner.

Both are fixed-step Jacobi masters.  Each function returns a
:class:`RunnerResult` of the hammer's bit position (the penetration) and rock
force (the WOB) at the communication points, ``time`` first.  A failed step
stops the run at once: :class:`RunnerStepError` names the runner, the time
and what the FMUs logged with status error (libcosim's log writes them to
the process's standard output, FMPy prints them: both are read while the run
goes, and passed on).
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
import time as _time
from dataclasses import dataclass

import numpy as np

from hammerbit.ssp.package import HAMMER

__all__ = ["RunnerResult", "RunnerStepError", "run_libcosim", "run_fmpy", "run_user_loop", "WIRINGS",
           "RUNNER_DTYPE"]

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


class RunnerStepError(RuntimeError):
    """A runner's step failed: the run stopped there.  ``messages``: what the FMUs logged with
    status error (the last one is the refusal)."""

    def __init__(self, runner: str, time: float, messages: list):
        self.runner, self.time, self.messages = runner, float(time), list(messages)
        said = messages[-1] if messages else "no message from the FMUs"
        super().__init__(f"{runner}: the step from t = {time:.9g} s failed; run stopped there. The FMU: {said}")


#: a libcosim log line of an FMU's message with status error or fatal
_LIBCOSIM_FMU_ERROR = re.compile(r"\[FMI status=(?:error|fatal)[^\]]*\]\s*(.*)")
#: an FMU message as FMPy's default logger prints it
_FMPY_FMU_ERROR = re.compile(r"^\[(?:ERROR|FATAL)\]\s*(.*)")


@contextlib.contextmanager
def _stdout_captured():
    """The process's standard output (file descriptor 1: libcosim's C++ log writes there) into a
    temporary file while the block runs; yields a function that reads what came so far.
    Afterwards the text goes on to the real standard output."""
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)

        def read() -> str:
            sys.stdout.flush()
            tmp.seek(0)
            return tmp.read().decode("utf-8", "replace")
        try:
            yield read
        finally:
            text = read()
            os.dup2(saved, 1)
            os.close(saved)
            sys.stdout.write(text)
            sys.stdout.flush()


def run_libcosim(path, stop: float) -> RunnerResult:
    """libcosimpy: ``CosimExecution.from_ssp_file`` (the package's step annotation), stepped to ``stop``;
    a failed step raises :class:`RunnerStepError` with the FMU's message."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    log_output_level(CosimLogLevel.ERROR)
    t0 = _time.perf_counter()
    with _stdout_captured() as log:
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
            if not ex.step():
                raise RunnerStepError("libcosim", t_ns / _NS, _LIBCOSIM_FMU_ERROR.findall(log()))
    wall = _time.perf_counter() - t0
    return RunnerResult("libcosimpy", np.array(rows, dtype=RUNNER_DTYPE), wall)


class _Tee(io.TextIOBase):
    """A text stream that writes through to ``out`` and keeps what it was given."""

    def __init__(self, out):
        self.out, self.text = out, []

    def write(self, s: str) -> int:
        self.text.append(s)
        return self.out.write(s)

    def flush(self) -> None:
        self.out.flush()


def run_fmpy(path, stop: float, step: float) -> RunnerResult:
    """FMPy: ``fmpy.ssp.simulate_ssp`` with the fixed step ``step``.

    Its loop adds ``step`` to its clock and records each row at the step's start time with the
    values at its end; the series here is put at the end times ``(k + 1) step``, to ``stop``.  Its
    loop stops at the first failed call: :class:`RunnerStepError` with the FMU's message (FMPy does
    not say when: ``time`` is nan)."""
    from fmpy.fmi1 import FMICallException
    from fmpy.ssp.simulation import simulate_ssp
    t0 = _time.perf_counter()
    tee = _Tee(sys.stdout)
    try:
        with contextlib.redirect_stdout(tee):      # FMPy's default logger prints the FMUs' messages
            res = simulate_ssp(str(path), stop_time=stop, step_size=step)
    except FMICallException as e:                  # its loop stops at the first failed call
        said = [m.group(1) for line in "".join(tee.text).splitlines() if (m := _FMPY_FMU_ERROR.match(line))]
        raise RunnerStepError("FMPy simulate_ssp", float("nan"), said or [str(e)]) from None
    wall = _time.perf_counter() - t0
    n = int(round(stop / step))
    k = np.arange(1, n + 1)
    out = np.zeros(n, dtype=RUNNER_DTYPE)
    out["time"] = k * step
    out["bit_position"] = res[f"{HAMMER}.bit_position"][:n]
    out["wob"] = res[f"{HAMMER}.rock_force"][:n]
    return RunnerResult("fmpy", out, wall)


#: how a user's loop feeds the string's force to the hammer's ``harmonic_force`` (the hammer's
#: ``preload`` held at the WOB): ``held_force_change``, the package's wiring (the mean force over
#: the next step, less the WOB), or ``interface_force - wob`` (the force at the communication
#: point, less the WOB: a natural guess, and wrong by a fifth of the penetration at 1 ms)
WIRINGS = ("held_force_change", "interface_force - wob")


#: the derivative orders of (position, velocity, position, velocity) passed from hammer to string
_ORDERS = [1, 1, 2, 2]


def _check_derivatives(string, hammer) -> None:
    """The hammer gives output derivatives of order 2 and the string takes input derivatives."""
    order = int(hammer.md.coSimulation.maxOutputDerivativeOrder or 0)
    if order < 2 or not string.md.coSimulation.canInterpolateInputs:
        raise ValueError(f"output_derivatives: the package's FMUs do not pass derivatives (HammerBitRock "
                         f"maxOutputDerivativeOrder = {order}, Drillstring canInterpolateInputs = "
                         f"{bool(string.md.coSimulation.canInterpolateInputs)}); build it with --runtime native")


def run_user_loop(path, stop: float, step: float, wiring: str = "held_force_change", *,
                  output_derivatives: bool = False) -> RunnerResult:
    """A user's own fixed-step Jacobi loop over the package's two FMUs (fmpy ``FMU2Slave``, the
    FMUs' own start values, which are the system's): at each communication point both FMUs take
    the other's outputs, then both step ``step`` [s], to ``stop``; ``wiring`` (:data:`WIRINGS`).
    ``output_derivatives``: the hammer's output derivatives of orders 1 and 2 (its position and
    velocity, after its new input is set) go to the string's input derivatives every step (the
    native flavour: ``maxOutputDerivativeOrder`` and ``canInterpolateInputs``; else a ValueError
    before the run)."""
    import zipfile

    from hammerbit.fmu.host import FMUInstance
    from hammerbit.ssp.package import STRING
    if wiring not in WIRINGS:
        raise ValueError(f"wiring = {wiring!r}: allowed {', '.join(map(repr, WIRINGS))}")
    t0 = _time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hammerbit_user_loop_") as tmp:
        with zipfile.ZipFile(path) as z:
            for name in ("Drillstring", "HammerBitRock"):
                with open(os.path.join(tmp, f"{name}.fmu"), "wb") as fh:
                    fh.write(z.read(f"resources/{name}.fmu"))
        string = FMUInstance(os.path.join(tmp, "Drillstring.fmu"), STRING)
        hammer = FMUInstance(os.path.join(tmp, "HammerBitRock.fmu"), HAMMER)
        try:
            if output_derivatives:
                _check_derivatives(string, hammer)
            motion = [hammer.vr["hammer_position"], hammer.vr["hammer_velocity"]] * 2
            motion_in = [string.vr["hammer_position"], string.vr["hammer_velocity"]] * 2
            wob = string.get("wob")[0]
            n = int(round(stop / step))
            out = np.zeros(n + 1, dtype=RUNNER_DTYPE)
            x, v, pos, rock = hammer.get("hammer_position", "hammer_velocity", "bit_position", "rock_force")
            out[0] = (0.0, pos, rock)
            for k in range(n):
                held, force = string.get("held_force_change", "interface_force")
                string.set(hammer_position=x, hammer_velocity=v)
                hammer.set(harmonic_force=held if wiring == WIRINGS[0] else force - wob)
                if output_derivatives:   # x', v', x'', v'' of the hammer with its new input, into the string
                    string.fmu.setRealInputDerivatives(motion_in, _ORDERS,
                                                       hammer.fmu.getRealOutputDerivatives(motion, _ORDERS))
                string.step(step)
                hammer.step(step)
                x, v, pos, rock = hammer.get("hammer_position", "hammer_velocity", "bit_position", "rock_force")
                out[k + 1] = ((k + 1) * step, pos, rock)
        finally:
            string.close()
            hammer.close()
    name = f"user loop ({wiring}{', output derivatives' if output_derivatives else ''})"
    return RunnerResult(name, out, _time.perf_counter() - t0)
