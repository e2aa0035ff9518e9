"""The FMI 3.0 native Drillstring.fmu (``hammerbit fmu build-string --runtime native --fmi-version 3``).

Oracle: the FMI 2.0 native Drillstring of the same build, driven by the same hammer motion; the
two fronts share the model layer, so each communication point's outputs are the same bits.
"""
from __future__ import annotations

import zipfile

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402

STRING = "lab"
H = 1e-3
STEPS = 200
OUT = ("interface_force", "held_force", "hook_load", "top_position", "top_velocity")
AMP, FREQ = 5e-5, 25.0


@pytest.fixture(scope="module")
def fmus(built_native_string_fmu, built_native_string_fmu3):
    """The lab string's native Drillstring.fmu in FMI 2.0 and 3.0 (the session's shared builds)."""
    return built_native_string_fmu, built_native_string_fmu3


def drive(t: float, rest: float) -> tuple:
    """The hammer's (position, velocity) at t: a periodic parabola about its rest position."""
    u = FREQ * t
    s = u - float(int(u))
    return rest + 4.0 * AMP * s * (1.0 - s), 4.0 * AMP * FREQ * (1.0 - 2.0 * s)


def run3(path, tmp) -> np.ndarray:
    with zipfile.ZipFile(path) as zf:
        zf.extractall(tmp)
    md = read_model_description(str(tmp / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(tmp), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="s3")
    s.instantiate()
    s.enterInitializationMode(startTime=0.0)
    s.exitInitializationMode()
    rest = s.getFloat64([vr["hammer_position_at_rest"]])[0]
    outs = [vr[n] for n in OUT]
    rows = [s.getFloat64(outs)]
    for i in range(STEPS):
        x, v = drive(i * H, rest)
        s.setFloat64([vr["hammer_position"], vr["hammer_velocity"]], [x, v])
        _, _, early, t = s.doStep(i * H, H)
        assert not early and t == pytest.approx((i + 1) * H, rel=1e-15)
        rows.append(s.getFloat64(outs))
    s.terminate()
    s.freeInstance()
    return np.array(rows)


def run2(path) -> np.ndarray:
    from hammerbit.fmu.host import FMUInstance
    fmu = FMUInstance(path, "string2", init=False)
    try:
        fmu.fmu.exitInitializationMode()
        rest = fmu.get("hammer_position_at_rest")[0]
        rows = [fmu.get(*OUT)]
        for i in range(STEPS):
            x, v = drive(i * H, rest)
            fmu.set(hammer_position=x, hammer_velocity=v)
            fmu.step(H)
            rows.append(fmu.get(*OUT))
    finally:
        fmu.close()
    return np.array(rows)


def test_fmi3_string_description_is_valid(fmus):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fmus[1])) == []
    md = read_model_description(str(fmus[1]))
    assert md.fmiVersion == "3.0" and not md.coSimulation.mightReturnEarlyFromDoStep
    assert {v.name for v in md.modelVariables} - {"time"} == \
        {v.name for v in read_model_description(str(fmus[0])).modelVariables}


def test_fmi3_string_equals_fmi2_step_for_step(fmus, tmp_path):
    want, got = run2(fmus[0]), run3(fmus[1], tmp_path)
    assert np.ptp(want[:, 0]) > 10.0             # the hammer drives the string: tens of N
    assert np.array_equal(got, want)


def test_fmi3_string_reference_results_equal_its_run_in_fmpy(fmus):
    """The FMI-LS-REF results of the FMI 3.0 build (the library's slave) against fmpy's run."""
    from reference_check import compare_with_fmpy
    compare_with_fmpy(fmus[1])
