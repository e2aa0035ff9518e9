"""HammerBitRock.fmu's ``regime`` output against the library's own verdict (``simulate``'s flags):
the same bits at the end of the same run, one warning per change, and restored with the FMU state."""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest
from fmu_slave import Slave

from hammerbit.model.presets import preset
from hammerbit.model.regime_codes import REGIME_RUNAWAY, REGIME_TRANSIENT
from hammerbit.scene.simulate import simulate

#: scenes from rest that set each bit the FMU computes, and their horizons [forcing periods]
SCENES = {
    "runaway": (preset("paper-fig9").replace(mu=0.7, b=0.7062, a=0.2073), 60),
    "bounce": (preset("paper-fig9").replace(a=0.9, b=0.3, eta=0.2), 10),
    "tension": (preset("chaos"), 40),
    "stall": (preset("paper-fig9").replace(a=0.1, b=0.4, xi=0.5), 30),
    "none": (preset("lab"), 40),
}
_RIG_FIELDS = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic", "friction_decay",
               "normal_force", "contact_stiffness", "contact_exponent", "contact_damping", "amplitude",
               "frequency", "phase")


def _slave(groups):
    """The pythonfmu slave in process, initialised with the scene's SI parameters, from rest."""
    from hammerbit.model.slave import HammerBitRock
    rig = groups.to_rig()
    s = HammerBitRock(instance_name="regime")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    for name in _RIG_FIELDS:
        setattr(s, name, float(getattr(rig, name)))
    if groups.has_gap:
        s.gap, s.impact_enabled = float(rig.gap), True
    s.preload = float(rig.preload)
    s.exit_initialization_mode()
    return s, 1.0 / rig.frequency


def _regime(s) -> int:
    return s._output_getters()["regime"]()


def _regime_warnings(s) -> list:
    return [m.msg for m in s.log_queue if m.msg.startswith("regime at t")]


def _run(s, h, periods, t=0.0):
    """Step one forcing period at a time; the regime after each step."""
    seen = []
    for _ in range(periods):
        assert s.do_step(t, h), s.log_queue[-1].msg
        t += h
        seen.append(_regime(s))
    return seen


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_regime_at_the_end_is_simulates_verdict(scene):
    """The FMU's bits after the run are simulate's (transient aside: it needs the whole horizon),
    each change is logged once, and a runaway is proved at the period simulate proves it."""
    groups, periods = SCENES[scene]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = simulate(groups, periods)
    expected = r.flags.code & ~REGIME_TRANSIENT
    s, h = _slave(groups)
    seen = _run(s, h, periods)
    assert seen[-1] == expected
    if scene != "none":
        assert expected != 0                     # each scene shows what it is named for
    changes = sum(1 for a, b in zip([0] + seen, seen) if a != b)
    assert len(_regime_warnings(s)) == changes
    if scene == "runaway":
        first = next(k for k, c in enumerate(seen) if c & REGIME_RUNAWAY) + 1     # periods done
        assert abs(first - r.flags.certified_at) <= 1


def test_regime_is_part_of_the_fmu_state():
    """A state saved before the runaway is proved brings back the verdict of its time; stepping
    on from it proves the runaway again, with a warning again."""
    groups, periods = SCENES["runaway"]
    s, h = _slave(groups)
    seen = _run(s, h, 10)
    saved, t_saved = s._get_fmu_state(), 10 * h
    seen += _run(s, h, periods - 10, t_saved)
    assert seen[9] == 0 and seen[-1] & REGIME_RUNAWAY
    warned = len(_regime_warnings(s))
    s._set_fmu_state(saved)
    assert _regime(s) == seen[9]
    again = _run(s, h, periods - 10, t_saved)
    assert again == seen[10:]
    assert len(_regime_warnings(s)) == 2 * warned
    # the bytes of a state carry it as well
    data = s._fmu_state_to_bytes(s._get_fmu_state())
    s._set_fmu_state(saved)
    s._set_fmu_state(s._fmu_state_from_bytes(data))
    assert _regime(s) == again[-1]


def test_runaway_needs_the_preload_held():
    """With the preload input lowered below the friction floor, the proof no longer holds: the bit cleared."""
    groups, periods = SCENES["runaway"]
    s, h = _slave(groups)
    seen = _run(s, h, periods)
    assert seen[-1] & REGIME_RUNAWAY
    s.preload = 0.5 * s.preload                    # b = 0.35 < mu: friction wins at every speed
    s.do_step(periods * h, h)
    assert not _regime(s) & REGIME_RUNAWAY
    assert math.isfinite(s._t)


# ---------------------------------------------------------------------------------------------
# the built FMUs, through fmpy
# ---------------------------------------------------------------------------------------------
def _scene_values(groups):
    rig = groups.to_rig()
    reals = {f: float(getattr(rig, f)) for f in _RIG_FIELDS}
    reals["preload"] = float(rig.preload)
    booleans = {"impact_enabled": True} if groups.has_gap else {}
    if groups.has_gap:
        reals["gap"] = float(rig.gap)
    return reals, booleans, 1.0 / rig.frequency


@pytest.mark.parametrize("scene", ["runaway", "bounce"])
def test_built_fmus_report_the_slaves_regime_and_restore_it(any_fmu, tmp_path, scene):
    """Each flavour through fmpy: the regime after every step and the warnings are the in-process
    slave's; fmi2SetFMUstate brings back the regime of the state's time."""
    import fmpy
    groups, periods = SCENES[scene]
    fmu_dir = Path(fmpy.extract(str(any_fmu), unzipdir=str(tmp_path / "fmu")))
    reals, booleans, h = _scene_values(groups)
    s = Slave(fmu_dir, logging=True, reals=reals, booleans=booleans)
    vr = s.vr["regime"]
    seen, t, state = [], 0.0, None
    for k in range(periods):
        s.fmu.doStep(t, h)
        t += h
        seen.append(s.fmu.getInteger([vr])[0])
        if k == 1:
            state = s.fmu.getFMUstate()
    ref_slave, _ = _slave(groups)
    assert seen == _run(ref_slave, h, periods)
    assert [m for _, m in s.messages if m.startswith("regime at t")] == _regime_warnings(ref_slave)
    s.fmu.setFMUstate(state)
    assert s.fmu.getInteger([vr])[0] == seen[1]
    s.fmu.freeFMUstate(state)
    s.fmu.terminate()
    s.fmu.freeInstance()


def test_the_outputs_description_names_the_rules_numbers():
    """The description of ``regime`` (written in the one description, which cannot import the
    rules) says the bits and the stall's period count the kernel uses."""
    from hammerbit.model.fmu_description import OUTPUTS
    from hammerbit.model.regime import STALL_PERIODS
    from hammerbit.model.regime_codes import REGIME_BITS
    text = {v.name: v.description for v in OUTPUTS}["regime"]
    assert f"{STALL_PERIODS} forcing periods" in text
    for name, bit in REGIME_BITS.items():
        if name != "transient":                   # never set by the FMU
            assert f"{bit} {name}" in text, name
