"""HammerBitRock.fmu's ``regime`` output against the library's own verdict (``simulate``'s flags):
the same bits at the end of the same run, one warning per change, and restored with the FMU state."""
from __future__ import annotations

import math
import warnings

import pytest

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
