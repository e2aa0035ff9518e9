"""The FMUs' declared limits, refused at once in both flavours: the time range of
fmi2SetupExperiment and fmi2DoStep (±1e9 s), HammerBitRock's longest step (MAX_PERIODS_PER_STEP
forcing periods), Model Exchange functions on a Co-Simulation instance, and FMU-state calls on
an FMU that declares no states.  The native FMUs in FMI 3.0 too (fmi3EnterInitializationMode
takes the experiment's times there)."""
from __future__ import annotations

import ctypes
import math
import zipfile

import pytest

from fmu_slave import FMI_ERROR, FMI_OK, Slave
from hammerbit.model.fmu_variables import MAX_PERIODS_PER_STEP
from hammerbit.model.validation import RANGES

pytest.importorskip("fmpy")

#: the native FMUs in FMI 3.0 too, behind the same FMI 2.0 calls (tests/fmi3_as_fmi2.py)
ALL_FMUS = ["built_fmu", "built_native_fmu", "built_string_fmu", "built_native_string_fmu",
            "built_native_fmu3", "built_native_string_fmu3"]
#: the HammerBitRock FMUs: both flavours, the native one in FMI 2.0 and 3.0
HAMMER_FMUS = ["built_fmu", "built_native_fmu", "built_native_fmu3"]
TIME_LIMIT = RANGES["fmu.time"].hi


def _extract(fmu, tmp):
    with zipfile.ZipFile(fmu) as zf:
        zf.extractall(tmp)
    return tmp


#: (startTime, stopTime) outside the FMU's time range, or stopTime before startTime
BAD_TIMES = [(-6.2e144, None), (math.nextafter(TIME_LIMIT, math.inf), None),
             (-math.nextafter(TIME_LIMIT, math.inf), None), (math.nan, None), (0.0, 2e9), (5.0, 4.0)]


@pytest.mark.parametrize("built", ALL_FMUS, indirect=True)
def test_setup_experiment_refuses_times_outside_the_declared_range(built, tmp_path):
    """Each refused with fmi2Error naming the range (fmi2Reset between them: out of the Error
    state); the ends of the range are accepted."""
    s = Slave(_extract(built, tmp_path), logging=True, setup=False)
    try:
        for start, stop in BAD_TIMES:
            n = len(s.errors())
            assert s.status_of(s.fmu.setupExperiment, None, start, stop) == FMI_ERROR, (start, stop)
            assert any("out of range" in m and "1e+09" in m for m in s.errors()[n:]), (start, stop, s.errors())
            s.fmu.reset()
        assert s.status_of(s.fmu.setupExperiment, None, -TIME_LIMIT, TIME_LIMIT) == FMI_OK
    finally:
        s.fmu.freeInstance()


@pytest.mark.parametrize("built", HAMMER_FMUS, indirect=True)
def test_a_step_beyond_max_periods_is_refused_at_once_naming_the_limit(built, tmp_path):
    s = Slave(_extract(built, tmp_path), logging=True)
    try:
        f = s.get("frequency")[0]
        before = s.get("bit_position", "hammer_position")
        cap = MAX_PERIODS_PER_STEP / f
        assert s.status_of(s.fmu.doStep, 0.0, cap * (1.0 + 1e-9)) == FMI_ERROR
        assert any("MAX_PERIODS_PER_STEP = 100000" in m for m in s.errors()), s.errors()
        assert s.get("bit_position", "hammer_position") == before
    finally:
        s.fmu.freeInstance()


@pytest.mark.parametrize("built", HAMMER_FMUS, indirect=True)
def test_a_step_over_the_whole_default_run_is_legal(built, tmp_path):
    """20 s (the default experiment) in one step, and in 1000 steps: the same state to the tolerance."""
    one, many = (Slave(_extract(built, tmp_path / k), reals={"tolerance": 1e-10}) for k in ("a", "b"))
    try:
        assert one.status_of(one.fmu.doStep, 0.0, 20.0) == FMI_OK
        for i in range(1000):
            many.fmu.doStep(i * 0.02, 0.02)
        a, b = one.get("bit_position")[0], many.get("bit_position")[0]
        assert abs(a - b) <= 1e-6 * max(abs(b), 1e-9), (a, b)
    finally:
        one.close()
        many.close()


def test_model_exchange_functions_are_refused_on_a_co_simulation_instance(built_native_fmu, tmp_path):
    s = Slave(_extract(built_native_fmu, tmp_path), logging=True, init=False)
    try:
        fn = s.fmu.dll.fmi2GetDerivatives
        fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t], ctypes.c_int
        dx = (ctypes.c_double * 4)()
        assert fn(s.fmu.component, dx, 4) == FMI_ERROR
        assert any("instantiated for Co-Simulation" in m for m in s.errors()), s.errors()
    finally:
        s.fmu.freeInstance()


def test_state_calls_are_refused_on_the_pythonfmu_drillstring(built_string_fmu, tmp_path):
    """It declares no FMU states: pythonfmu would save its variables only, not the string's state."""
    s = Slave(_extract(built_string_fmu, tmp_path), logging=True)
    try:
        assert s.md.coSimulation.canGetAndSetFMUstate is False
        assert s.status_of(s.fmu.getFMUstate) == FMI_ERROR
        assert any("does not support FMU states" in m for m in s.errors()), s.errors()
    finally:
        s.fmu.freeInstance()
