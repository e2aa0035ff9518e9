"""FMU fuzzing: random and adversarial values and call sequences.

Every bad call gets a non-OK FMI status (fmpy raises FMICallException; never
fmi2Fatal) and an error log message; none crashes the process, and none changes
the outcome of the valid calls around it: the fuzzed instance ends bit-identical
to a clean instance that made only the valid calls.
"""
import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from test_fmu import FMI_DISCARD, FMI_ERROR, Instance, RIG

BAD_VALUES = [math.nan, math.inf, -math.inf]


def _bad_call(inst, rng):
    """One adversarial call; returns a label.  The instance's valid inputs are restored after."""
    kind = rng.integers(5)
    t = inst.t
    if kind == 0:                                   # non-finite or absurd input, then a step
        name = ["preload", "harmonic_force"][rng.integers(2)]
        inst.set(**{name: BAD_VALUES[rng.integers(len(BAD_VALUES))]})
        call = (t, 1e-3)
    elif kind == 1:
        call = (t, [0.0, -1e-3, math.nan, -math.inf][rng.integers(4)])    # bad step size
    elif kind == 2:
        call = (t + [1e-3, -1e-3, 0.5, math.nan][rng.integers(4)], 1e-3)  # wrong communication point
    elif kind == 3:                                 # a fixed parameter after initialisation
        inst.set(**{["hammer_mass", "stiffness", "mu_kinetic"][rng.integers(3)]: -1.0})
        call = (t, 1e-3)
    else:                                           # an invalid tolerance
        inst.set(tolerance=[-1.0, 0.0, math.nan][rng.integers(3)])
        call = (t, 1e-3)
    n_err = len(inst.errors())
    before = inst.outputs()
    with pytest.raises(FMICallException) as exc:
        inst.fmu.doStep(currentCommunicationPoint=call[0], communicationStepSize=call[1])
    assert exc.value.status in (FMI_DISCARD, FMI_ERROR)
    assert len(inst.errors()) > n_err, f"no error logged for kind {kind}"
    assert inst.outputs() == before
    # repair what the bad call set
    inst.set(preload=RIG.preload, harmonic_force=0.0)
    if kind == 3:
        inst.set(hammer_mass=RIG.hammer_mass, stiffness=RIG.stiffness, mu_kinetic=RIG.mu_kinetic)
    if kind == 4:
        inst.set(tolerance=1e-8)
    return kind


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_adversarial_sequences(built_fmu, seed):
    rng = np.random.default_rng(seed)
    steps = [float(h) for h in rng.choice([1e-4, 1e-3, 5e-3, 2e-2], size=120)]
    clean = Instance(built_fmu, "clean", reals={"tolerance": 1e-8})
    fuzzed = Instance(built_fmu, "fuzzed", reals={"tolerance": 1e-8})
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


def test_state_from_another_instance_and_terminate_twice(built_fmu):
    """A state taken from another instance is a complete, valid state: applying it makes this
    instance continue exactly like the other one (documented).  Terminating twice is harmless."""
    a = Instance(built_fmu, "a")
    b = Instance(built_fmu, "b")
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
        try:
            b.fmu.terminate()          # second terminate: an error status at worst, never a crash
        except FMICallException as e:
            assert e.status in (FMI_DISCARD, FMI_ERROR)
        b.fmu.freeInstance()
