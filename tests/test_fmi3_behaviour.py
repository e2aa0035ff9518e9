"""FMU behaviour on the FMI 3.0 native HammerBitRock.fmu: statuses, rollback, no repeated events.

The FMI 2.0 behaviour suite runs on the FMI 3.0 builds through tests/fmi3_as_fmi2.py (limits and
fuzzed states: tests/test_fmu_limits.py, test_fmu_fuzz.py); here what needs FMI 3.0's own calls.

Oracles: a clean instance of the same FMU that made only the valid calls (the adversarial
sequences end bit-identical to it); the same FMU's run without rollback (a rolled-back step is
redone bit for bit); FMI 3.0's rule for early return (time advances at every fmi3DoStep, an event
reported at a communication point is not reported again).
"""
from __future__ import annotations

import re
import zipfile

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402

from fmu_slave import Slave  # noqa: E402
from test_fmi3_native import H, OUTS, impact_scene, scene_start_values  # noqa: E402
from test_fmu_fuzz import _bad_call  # noqa: E402


@pytest.fixture(scope="module")
def fmu3_dir(built_native_fmu3, tmp_path_factory):
    d = tmp_path_factory.mktemp("fmi3_behaviour")
    with zipfile.ZipFile(built_native_fmu3) as zf:
        zf.extractall(d)
    return d


class Inst:
    """An FMI 3.0 instance behind the FMI 2.0 calls, with what tests/test_fmu_fuzz.py's bad calls use."""

    REALS = ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity", "rock_force")
    INTS = ("stick_slip", "impact_count", "slip_count", "bounce_count")

    def __init__(self, fmu_dir, **kw):
        self.s = Slave(fmu_dir, logging=True, **kw)
        self.fmu, self.vr = self.s.fmu, self.s.vr

    @property
    def t(self):
        return self.s.t

    def step(self, h):
        self.s.step(h)

    def errors(self):
        return self.s.errors()

    def outputs(self):
        return (tuple(self.fmu.getReal([self.vr[n] for n in self.REALS])) +
                tuple(self.fmu.getInteger([self.vr[n] for n in self.INTS])) +
                tuple(self.fmu.getBoolean([self.vr["in_contact"]])))

    def expect(self, status, fn, *args):
        got = self.s.status_of(fn, *args)
        assert got == status, (got, self.s.messages[-3:])

    def close(self):
        self.s.close()


@pytest.mark.parametrize("seed", [1, 2])
def test_fmi3_adversarial_sequences_end_as_the_clean_run(fmu3_dir, seed):
    """Bad calls (absurd inputs, bad steps and communication points, fixed parameters, bad
    tolerances, unknown or mistyped value references) are each fmi3Error with a message in FMI
    3.0's names and change nothing; after each the host restores the state saved before it
    (fmi3SetFMUState, the recovery from fmi3Error), and the fuzzed instance ends bit-identical to
    the clean one."""
    rng = np.random.default_rng(seed)
    steps = [float(h) for h in rng.choice([1e-4, 1e-3, 5e-3, 2e-2], size=80)]
    clean, fuzzed = Inst(fmu3_dir, reals={"tolerance": 1e-8}), Inst(fmu3_dir, reals={"tolerance": 1e-8})
    kinds = set()
    try:
        for h in steps:
            clean.step(h)
            if rng.random() < 0.4:
                kinds.add(_bad_call(fuzzed, rng))
            fuzzed.step(h)
        assert fuzzed.outputs() == clean.outputs()
        assert len(kinds) >= 4
        # the host is an FMI 3.0 host: the messages name FMI 3.0's functions and statuses
        said = [m for _, m in fuzzed.s.messages]
        assert any("fmi3SetFMUState" in m or "fmi3SetFloat64" in m or "fmi3DoStep" in m for m in said), said
        assert not [m for m in said if re.search(r"\bfmi2", m)], [m for m in said if "fmi2" in m][:3]
    finally:
        clean.close()
        fuzzed.close()


def _early_slave(fmu_dir, event_mode=False):
    md = read_model_description(str(fmu_dir / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU3Slave(guid=md.guid, unzipDirectory=str(fmu_dir), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName="nr")
    s.instantiate(eventModeUsed=event_mode, earlyReturnAllowed=True)
    s.enterInitializationMode(startTime=0.0)
    for name, v in scene_start_values(impact_scene()).items():
        (s.setBoolean if isinstance(v, bool) else s.setFloat64)([vr[name]], [v])
    s.exitInitializationMode()
    if event_mode:
        s.updateDiscreteStates()
        s.enterStepMode()
    return s, [vr[n] for n in OUTS[:4]]


def _run_to(s, t, t_end):
    """Steps from t to t_end, on after each early return; the early-return times.  Every step
    advances time (an event reported at its start is not returned again)."""
    events = []
    while t < t_end:
        _, _, early, reached = s.doStep(t, t_end - t)
        assert reached > t, f"fmi3DoStep from {t!r} s did not advance"
        if early:
            events.append(reached)
        t = reached
    return events


def test_no_repeats_when_the_event_lies_on_the_communication_point(fmu3_dir):
    """Two ways to a communication point that is an event time: the early return (the event
    reported there) and, after a rollback, a step that ends exactly there.  From it every step
    advances time, the event is not reported again, and both ways end the same."""
    s, outs = _early_slave(fmu3_dir)
    try:
        t0 = 0.0
        while True:                    # steps of H, each after a saved state, to the first early return
            saved = s.getFMUState()
            _, _, early, te = s.doStep(t0, H)
            if early:
                break
            s.freeFMUState(saved)
            t0 = te
        assert t0 < te < t0 + H
        t_end = te + 5 * H
        # way 1: on from the reported event (currentCommunicationPoint = the event's time)
        after_1 = _run_to(s, te, t_end)
        assert all(t > te for t in after_1)
        y1 = s.getFloat64(outs)
        # way 2: back to t0, a step that ends at the event's time, then on
        s.setFMUState(saved)
        events_2 = _run_to(s, t0, te) + _run_to(s, te, t_end)
        assert len(events_2) <= 1 + len(after_1)           # each event reported once at most
        assert events_2.count(te) <= 1
        np.testing.assert_allclose(s.getFloat64(outs), y1, rtol=1e-9, atol=1e-15)
        s.freeFMUState(saved)
    finally:
        s.terminate()
        s.freeInstance()


@pytest.mark.parametrize("event_mode", [False, True])
def test_rollback_over_an_early_return_is_bit_identical(fmu3_dir, event_mode):
    """A state saved before a step that returns early, restored, and the step redone: the same
    event time and the same outputs, bit for bit; time advances at every step, over 0.5 s."""
    s, outs = _early_slave(fmu3_dir, event_mode)
    try:
        t, redone = 0.0, 0
        while t < 0.5:
            saved = s.getFMUState()
            need, _, early, reached = s.doStep(t, H)
            assert reached > t
            if early:
                y = s.getFloat64(outs)
                s.setFMUState(saved)
                again = s.doStep(t, H)
                assert again == (need, False, True, reached) and s.getFloat64(outs) == y
                redone += 1
                if event_mode:
                    s.enterEventMode()
                    s.updateDiscreteStates()
                    s.enterStepMode()
            s.freeFMUState(saved)
            t = reached
        assert redone >= 2                       # the scene has events in 0.5 s
    finally:
        s.terminate()
        s.freeInstance()
