"""Tension onset (hammerbit.continuation.touch): the orbit's smallest drive on the bit, its zero located along
a branch and followed in a second parameter, against dense sampling and long runs from rest."""
import numpy as np
import pytest
from orbit_sampling import dense_orbit_samples, settled_events_per_period

from hammerbit.continuation import correct_orbit, orbit_from_simulation
from hammerbit.continuation.bifurcation import detect
from hammerbit.continuation.continuation import follow_branch
from hammerbit.continuation.parameter import Parameter
from hammerbit.continuation.touch import detect_touches, follow_touch, min_drive
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.presets import preset
from hammerbit.model.stepping import Stepper

#: paper-fig9's period-1 orbit: the spring starts to pull the bit near b = 0.446-0.449 over this range of a
A_RANGE = (0.18, 0.26)
B_RANGE = (0.40, 0.50)


@pytest.fixture(scope="module")
def tension_onset():
    """The period-1 branch of paper-fig9 at a = 0.2 followed in b from 0.55 to 0.4, and its tension points."""
    base = preset("paper-fig9").replace(a=0.2, b=0.55)
    n, s = orbit_from_simulation(base)
    param = Parameter.on("b", base)
    branch = follow_branch(param, base, correct_orbit(base, s, n), B_RANGE[0])
    return base, param, detect_touches(param, base, branch.points, 0)


def test_the_smallest_drive_is_that_of_a_dense_sampling():
    g = preset("paper-fig9").replace(a=0.2, b=0.4)
    orbit, samples = dense_orbit_samples(g)
    # no gap: the drive on the bit is the spring and the damper, (x1 - x3) + 2 xi (x2 - x4)
    dense = np.min(samples[:, 0] - samples[:, 2] + 2 * g.xi * (samples[:, 1] - samples[:, 3]))
    assert dense < 0
    assert abs(min_drive(orbit) - dense) < 1e-9


def test_tension_onset_is_located_where_the_smallest_drive_changes_sign(tension_onset):
    base, param, touches = tension_onset
    assert [t.kind for t in touches] == ["tension"]
    t = touches[0]
    assert abs(min_drive(t.orbit)) < 1e-10
    for side, sign in ((-1e-6, -1.0), (1e-6, 1.0)):  # the spring pulls the bit below b*
        g = base.replace(b=t.value + side)
        assert sign * min_drive(correct_orbit(g, t.orbit.s, 1)) > 0


def test_the_tension_curve_separates_settled_runs_from_rest(tension_onset):
    base, _, touches = tension_onset
    curve = follow_touch(base, touches[0], "b", "a", *A_RANGE, points=4)
    assert not curve.stopped
    pts = sorted((a, b) for b, a in curve.points)
    b_values = np.linspace(*B_RANGE, 11)
    b_cell = b_values[1] - b_values[0]
    assert b_values[0] < min(p[1] for p in pts) - 2 * b_cell and b_values[-1] > max(p[1] for p in pts) + 2 * b_cell
    wrong = []
    for a in np.linspace(*A_RANGE, 5):
        b_star = np.interp(a, [p[0] for p in pts], [p[1] for p in pts])
        for b in b_values:
            # the settled motion's smallest drive: 300 periods from rest, then 400 more
            g = base.replace(a=a, b=b)
            st = Stepper(g, compile_helper=False)
            st.advance(300 * g.period)
            st.fstate[KL.F_DRIVE_MIN] = np.inf
            st.advance(700 * g.period)
            pulls = st.fstate[KL.F_DRIVE_MIN] < 0
            if pulls != (b < b_star) and abs(b - b_star) > b_cell:
                wrong.append((a, b, pulls, b_star))
    assert not wrong


@pytest.fixture(scope="module")
def sliding_point():
    """paper-fig9's stable period-2 orbit (one stick phase per two periods) followed in a from 0.16 up to where a
    second stick phase appears (a stick phase splits by a short slip), located."""
    base = preset("paper-fig9").replace(a=0.16)
    n, s = orbit_from_simulation(base)
    param = Parameter.on("a", base)
    branch = follow_branch(param, base, correct_orbit(base, s, n), 0.27)
    sliding = [b for b in detect(param, base, branch.points, 0) if b.kind == "sliding"]
    assert n == 2 and len(sliding) == 1
    return base, sliding[0]


def _sticks_per_period(g, state, periods=60):
    """Stick phases per forcing period of a long run of the library's Stepper from ``state`` (its second half)."""
    return settled_events_per_period(g, state, KL.EV_STICK, periods)


def test_the_sliding_curve_separates_one_stick_phase_from_two(sliding_point):
    base, bif = sliding_point
    curve = follow_touch(base, bif, "a", "eta", 1.0, 1.04, points=3)
    assert not curve.stopped and len(curve.points) == 4
    for (a, eta), orbit in zip(curve.points, curve.orbits):
        g = base.replace(eta=eta)
        below = correct_orbit(g.replace(a=a - 1e-5), orbit.s, 2)
        assert _sticks_per_period(g.replace(a=a - 1e-5), below.state) == pytest.approx(0.5)
        # just past the curve the same family (a few 1e-5 away) has a second stick phase
        above = correct_orbit(g.replace(a=a + 1e-5), orbit.s, 2)
        assert np.max(np.abs(above.s - below.s)) < 1e-3
        assert _sticks_per_period(g.replace(a=a + 1e-5), above.state) == pytest.approx(1.0)
