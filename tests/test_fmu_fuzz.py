"""FMU fuzzing: random and adversarial values and call sequences.

Every bad call records fmi2Error in ``last_status`` (with the native front the
call returns it; never fmi2Fatal) and logs an error message; none crashes the
process or changes the state.  Both runtime flavours (pythonfmu, native) are fuzzed.  After each error the master restores the state
saved before it (FMI 2.0.4: the recovery from fmi2Error), and the fuzzed
instance ends bit-identical to a clean instance that made only the valid calls.
"""
import math

import numpy as np
import pytest

from test_fmu import FMI_ERROR, Instance, RIG

BAD_VALUES = [math.nan, math.inf, -math.inf, 1e12, -1e308]


def _bad_call(inst, rng):
    """One adversarial call; returns its kind."""
    kind = int(rng.integers(6))
    t = inst.t
    vr = inst.vr
    if kind == 0:                                   # non-finite or absurd input
        name = ["preload", "harmonic_force"][rng.integers(2)]
        call = (inst.fmu.setReal, [vr[name]], [BAD_VALUES[rng.integers(len(BAD_VALUES))]])
    elif kind == 1:                                 # bad step size
        call = (inst.fmu.doStep, t, [0.0, -1e-3, math.nan, -math.inf][rng.integers(4)])
    elif kind == 2:                                 # wrong communication point
        call = (inst.fmu.doStep, t + [1e-3, -1e-3, 0.5, math.nan][rng.integers(4)], 1e-3)
    elif kind == 3:                                 # a fixed parameter after initialisation
        name = ["hammer_mass", "stiffness", "mu_kinetic"][rng.integers(3)]
        call = (inst.fmu.setReal, [vr[name]], [-1.0])
    elif kind == 4:                                 # an invalid tolerance
        call = (inst.fmu.setReal, [vr["tolerance"]], [[-1.0, 0.0, math.nan][rng.integers(3)]])
    else:                                           # unknown value references, wrong types
        call = [(inst.fmu.setReal, [99999], [1.0]),
                (inst.fmu.setInteger, [vr["bit_position"]], [1]),
                (inst.fmu.setBoolean, [vr["slip_count"]], [True])][rng.integers(3)]
    n_err = len(inst.errors())
    before = inst.outputs()
    saved = inst.fmu.getFMUstate()
    inst.expect(FMI_ERROR, *call)
    assert len(inst.errors()) > n_err, f"no error logged for kind {kind}"
    assert inst.outputs() == before
    inst.fmu.setFMUstate(saved)          # after fmi2Error: back to the state saved before it
    inst.fmu.freeFMUstate(saved)
    return kind


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_adversarial_sequences(any_fmu, seed):
    rng = np.random.default_rng(seed)
    steps = [float(h) for h in rng.choice([1e-4, 1e-3, 5e-3, 2e-2], size=120)]
    clean = Instance(any_fmu, "clean", reals={"tolerance": 1e-8})
    fuzzed = Instance(any_fmu, "fuzzed", reals={"tolerance": 1e-8})
    kinds = set()
    try:
        for h in steps:
            clean.step(h)
            if rng.random() < 0.4:
                kinds.add(_bad_call(fuzzed, rng))
            fuzzed.step(h)
        assert fuzzed.outputs() == clean.outputs()
        assert len(kinds) >= 4
    finally:
        clean.close()
        fuzzed.close()


def test_state_from_another_instance_and_terminate_twice(any_fmu):
    """A state taken from another instance is a complete, valid state: applying it makes this
    instance continue exactly like the other one (documented).  A second fmi2Terminate is a call in
    the wrong state (FMI 2.0: Terminated allows only get, reset and free): fmi2Error, no crash."""
    a = Instance(any_fmu, "a")
    b = Instance(any_fmu, "b")
    try:
        for _ in range(50):
            a.step(2e-3)
        s = a.fmu.getFMUState()
        b.fmu.setFMUState(s)
        b.t = a.t
        a.fmu.freeFMUState(s)
        for _ in range(50):
            a.step(2e-3)
            b.step(2e-3)
        assert a.outputs() == b.outputs()
    finally:
        a.close()
        b.fmu.terminate()
        assert b.call(b.fmu.terminate) == 3          # fmi2Error, and the instance is still freed
        b.fmu.freeInstance()
