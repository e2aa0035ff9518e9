"""DrillingSystem.fmu's ``regime`` output: the runaway and stall verdicts against the library's own.

The oracle is :func:`hammerbit.cosim.config.cosim_regime` applied to the monolithic reference
(:func:`hammerbit.cosim.reference.monolithic`) of the same scene, cut at the time the FMU is read:
the FMU's verdicts are causal, so at every whole second they must be what the library says of the
run up to that second.  A stall: the auto-driller off resonance (field-2200m's default hammer: one
slip, then the bit stays stuck with the WOB held).  A runaway: the set point (100 kN) above the
rock's sliding capacity mu_d F_N (90.3 kN) at A = 15 kN, f = 22.5 Hz.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("fmpy")

from test_system_fmu import Slave  # noqa: E402

from hammerbit.cosim.config import CosimConfig, cosim_regime, default_hammer  # noqa: E402
from hammerbit.drillstring import load_string  # noqa: E402
from hammerbit.drillstring.top import TopCondition  # noqa: E402
from hammerbit.model.regime_codes import REGIME_RUNAWAY, REGIME_STALL  # noqa: E402

VERDICTS = REGIME_RUNAWAY | REGIME_STALL


def scene(field, stop, *, wob=None, amplitude=None, frequency=None):
    rig = default_hammer(field)
    if amplitude is not None:
        rig = rig.replace(amplitude=amplitude, frequency=frequency)
    return CosimConfig(stop=stop, step=0.01, rig=rig, top=TopCondition.parse("auto-driller"), wob=wob,
                       rtol=1e-5)


@pytest.fixture(scope="module")
def field():
    return load_string("field-2200m")


def library_verdicts(string, cfg, seconds):
    """``{second: runaway | stall bits}`` of cosim_regime on the reference cut at each second."""
    from hammerbit.cosim.reference import monolithic
    r = monolithic(string, cfg)
    out = {}
    for sec in seconds:
        cut = dataclasses.replace(r, data=r.data[r.data["time"] <= sec + 1e-9])
        out[sec] = cosim_regime(cut)["code"] & VERDICTS
    return out


def fmu_verdicts(path, seconds, h, logged):
    """``({second: runaway | stall bits}, the regime after each step)`` of a run at the step ``h``."""
    s = Slave(path, logger=logged)
    out, every = {}, []
    try:
        n_per = int(round(1.0 / h))
        for k in range(max(seconds) * n_per):
            s.step(h)
            every.append(s.fmu.getInteger([s.vr["regime"]])[0])
            if (k + 1) % n_per == 0 and (k + 1) // n_per in seconds:
                out[(k + 1) // n_per] = every[-1] & VERDICTS
    finally:
        s.close()
    return out, np.array(every)


def build(field, cfg, tmp_path):
    from hammerbit.fmu.build_system import build_system_fmu
    return build_system_fmu(field, cfg, tmp_path / "DS.fmu", log=lambda m: None)


def changes(every):
    """How often the runaway or stall bits change along the run."""
    v = every & VERDICTS
    return int(np.count_nonzero(np.diff(np.r_[0, v])))


@pytest.fixture(scope="module")
def stall_fmu(built_field_system_fmu):
    """The FMU of the stalling scene (the session's shared build of field-2200m under the
    auto-driller: the build takes nothing from the scene's stop, step or rtol)."""
    return built_field_system_fmu


def test_stall_off_resonance_is_the_librarys_verdict_at_every_second(field, stall_fmu):
    seconds = [1, 2, 3]
    cfg = scene(field, 3.0)
    logged = []
    got, every = fmu_verdicts(stall_fmu, seconds, 0.01, logged)
    want = library_verdicts(field, cfg, seconds)
    assert want[3] == REGIME_STALL, "the scene does not stall: the test would be vacuous"
    assert want[1] == 0, "the scene stalls within a second: the causal check would be vacuous"
    assert got == want
    # one log message per change of the verdict, naming it
    regime_msgs = [m for m in logged if "regime at t" in m]
    assert len(regime_msgs) == changes(every) >= 1 and "stall yes" in regime_msgs[-1]


def test_stall_verdict_is_part_of_the_state(field, stall_fmu):
    """Rolled back to before the stall, the verdict is 0 again and comes back at the same step; a
    state whose regime memory is corrupted is refused."""
    cfg = scene(field, 3.0)
    s = Slave(stall_fmu)
    try:
        for _ in range(50):
            s.step(0.01)
        before = s.fmu.getFMUstate()
        data = bytes(s.fmu.serializeFMUstate(before))
        trace = []
        for _ in range(150):
            s.step(0.01)
            trace.append(s.fmu.getInteger([s.vr["regime"]])[0])
        assert trace[0] & REGIME_STALL == 0 and trace[-1] & REGIME_STALL
        s.fmu.setFMUstate(before)
        s.t = 0.5
        assert s.fmu.getInteger([s.vr["regime"]])[0] & REGIME_STALL == 0
        again = []
        for _ in range(150):
            s.step(0.01)
            again.append(s.fmu.getInteger([s.vr["regime"]])[0])
        assert again == trace
        # the regime memory sits right before the kernel parameters (model_system.h): its verdict,
        # then the 64 impulse samples, the 64 positions, the 64 times and the sample count
        from hammerbit.fmu.build_system import system_data
        p = system_data(field, cfg)["p"]
        at_p = data.find(p.tobytes())
        assert at_p > 0
        verdict, n_at = at_p - 8, at_p - 8 - 3 * 64 * 8 - 8
        assert int.from_bytes(data[verdict:verdict + 8], "little") == 0
        for where, value in ((verdict, 32), (n_at, 65), (n_at, -1)):
            bad = bytearray(data)
            bad[where:where + 8] = int(value).to_bytes(8, "little", signed=True)
            with pytest.raises(Exception):
                s.fmu.deSerializeFMUstate(bytes(bad))
            s.fmu.setFMUstate(before)       # the refusal is an fmi2Error; a state recovers
        s.fmu.freeFMUstate(before)
    finally:
        s.close()


@pytest.mark.slow
def test_runaway_above_the_sliding_capacity_is_the_librarys_verdict(field, tmp_path):
    seconds = [10, 30, 60]
    cfg = scene(field, 60.0, wob=100e3, amplitude=15e3, frequency=22.5)
    logged = []
    got, every = fmu_verdicts(build(field, cfg, tmp_path), seconds, 0.01, logged)
    want = library_verdicts(field, cfg, seconds)
    assert want[60] & REGIME_RUNAWAY, "the scene does not run away: the test would be vacuous"
    assert got == want
    assert len([m for m in logged if "regime at t" in m]) == changes(every)
