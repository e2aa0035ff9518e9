"""Periodic orbits and their monodromy (hammerbit.continuation): the variational monodromy against a
finite-difference monodromy of the library's own integration, and every orbit against a fresh Stepper."""
import math

import numpy as np
import pytest
import scipy.linalg

from hammerbit.continuation import ContinuationError, correct_orbit, orbit_from_simulation, period_map
from hammerbit.continuation.monodromy import full_state
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.presets import preset
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper

#: the oracle's integration: the library's Stepper at rtol 1e-12
ORACLE = SolverOptions(rtol=1e-12, atol=1e-12)
#: central-difference steps of the finite-difference monodromy, largest first: a large step truncates
#: (in a stiff contact the force's higher derivatives grow like d^(n-3)), a small one amplifies the
#: integration's own noise (~rtol / h)
FD_STEPS = (1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7)


def _fig9(a, **kw):
    return preset("paper-fig9").replace(a=a, **kw)


def _fig12(a, **kw):
    return preset("paper-fig12").replace(a=a, **kw)


def _random_periodic(seed):
    """Random groups around the paper's (with or without gap) whose run from rest settles to a period <= 8."""
    rng = np.random.default_rng(seed)
    while True:
        g = preset("paper-fig9").replace(
            eta=float(rng.uniform(0.8, 1.2)), b=float(rng.uniform(0.4, 0.6)), xi=float(rng.uniform(0.05, 0.1)),
            mu=float(rng.uniform(0.7, 0.9)), r=float(rng.choice([math.inf, rng.uniform(0.6, 1.0)])))
        g = g.replace(a=float(rng.uniform(0.3, 0.9)) * g.b)
        guess = orbit_from_simulation(g)
        if guess is not None and guess[0] <= 8 and _events_per_period(g, guess) > 0:
            return g


def _events_per_period(g, guess):
    n, s = guess
    return period_map(g, s, n, jacobian=False).events.shape[0]


#: 10 periodic scenes across regimes: stick-slip without gap (P1, P2, P3, the lab rig), with impacts
#: (P1, P2), the section moved into a slip (3 map coordinates) and into a contact, random ones.
#: The phase shifts put phase 0 mid-slip (fig9, a = 0.2: slip over tau in [0.78, 2.49]) and
#: mid-contact (fig12, a = 0.11: contact over tau in [0.950, 0.972]).
SCENES = {
    "fig9-P1": lambda: _fig9(0.2),
    "fig9-P2": lambda: _fig9(0.11),
    "fig9-P3": lambda: _fig9(0.083),
    "lab": lambda: preset("lab"),
    "fig12-P1-impact": lambda: _fig12(0.11),
    "fig12-P2-impact": lambda: _fig12(0.06),
    "fig9-P1-slipping-at-phase-0": lambda: _fig9(0.2, phi=math.pi / 2 + 1.6),
    "fig12-P1-in-contact-at-phase-0": lambda: _fig12(0.11, phi=math.pi / 2 + 0.96),
    "random-1": lambda: _random_periodic(1),
    "random-2": lambda: _random_periodic(2),
}


def _orbit(name):
    g = SCENES[name]()
    n, s = orbit_from_simulation(g)
    return g, correct_orbit(g, s, n)


def fd_monodromy(g, s, n):
    """Central differences of the period-n map of a plain Stepper at rtol 1e-12 (no variational equations).

    Each pair of neighbouring steps is Richardson-extrapolated (the h^2 term cancelled); the answer is
    the extrapolation that agrees best with the next one (the step selection of numerical
    differentiation libraries), chosen without looking at the monodromy under test.
    """
    cd = [_central_differences(g, s, n, h) for h in FD_STEPS]
    rich = [(cd[i + 1] * FD_STEPS[i] ** 2 - cd[i] * FD_STEPS[i + 1] ** 2) / (FD_STEPS[i] ** 2 - FD_STEPS[i + 1] ** 2)
            for i in range(len(cd) - 1)]
    spread = [np.max(np.abs(rich[i + 1] - rich[i])) for i in range(len(rich) - 1)]
    return rich[int(np.argmin(spread))]


def _central_differences(g, s, n, step):
    k = len(s)
    M = np.zeros((k, k))
    for j in range(k):
        h = step * max(1.0, abs(s[j]))
        ends = []
        for sign in (1.0, -1.0):
            sj = np.array(s, dtype=float)
            sj[j] += sign * h
            st = Stepper(g, solver=ORACLE, y0=full_state(sj), compile_helper=False)
            st.advance(n * g.period)
            y = st.y[:4]
            ends.append(np.array([y[0] - y[2], y[1], y[3]][:k]))
        M[:, j] = (ends[0] - ends[1]) / (2 * h)
    return M


@pytest.mark.parametrize("name", list(SCENES))
def test_monodromy_equals_finite_differences_of_the_library_integration(name):
    g, orb = _orbit(name)
    M_fd = fd_monodromy(g, orb.s, orb.period)
    assert np.max(np.abs(orb.monodromy - M_fd)) <= 1e-6 * np.max(np.abs(M_fd)), (orb.monodromy, M_fd)
    # each multiplier within 1e-6 of the matrix norm times its condition number 1 / |l^H r|
    mu_fd, left, right = scipy.linalg.eig(M_fd, left=True, right=True)
    norm = np.linalg.norm(M_fd, 2)
    for mu in orb.multipliers:
        i = int(np.argmin(np.abs(mu_fd - mu)))
        kappa = 1.0 / abs(np.vdot(left[:, i], right[:, i]))
        assert abs(mu_fd[i] - mu) <= 1e-6 * kappa * norm


@pytest.mark.parametrize("name", list(SCENES))
def test_orbit_restarted_in_a_stepper_returns_to_its_state(name):
    g, orb = _orbit(name)
    st = Stepper(g, solver=ORACLE, y0=orb.state, compile_helper=False)
    st.advance(orb.period * g.period)
    y = st.y[:4].copy()
    back = np.array([y[0] - y[2], y[1], 0.0, y[3]])
    assert np.max(np.abs(back - orb.state)) <= 1e-9 * max(1.0, orb.max_multiplier)
    assert orb.drift == pytest.approx(y[2], abs=1e-9)


def test_the_scenes_cover_the_regimes():
    """Stuck and slipping sections, orbits with and without impacts, several periods."""
    kinds = {}
    for name in SCENES:
        g, orb = _orbit(name)
        ev = orb.events[:, KL.L_KIND].astype(int)
        kinds[name] = (orb.period, orb.stuck, bool(np.any(ev == KL.EV_IMPACT)), bool(np.any(ev == KL.EV_STICK)))
    assert {k[0] for k in kinds.values()} >= {1, 2, 3}
    assert not kinds["fig9-P1-slipping-at-phase-0"][1] and kinds["fig9-P1"][1]
    assert kinds["fig12-P1-impact"][2] and not kinds["fig9-P1"][2]
    assert all(k[3] for k in kinds.values())


def test_a_stick_phase_collapses_the_bit_velocity_direction():
    """Sections in slip (3 coordinates) of orbits with a stick phase: the stop forgets the bit velocity
    (the sliding constraint x4 = 0), so one multiplier is zero, as the finite differences say too."""
    for name in ("fig9-P1-slipping-at-phase-0", "fig12-P1-in-contact-at-phase-0"):
        g, orb = _orbit(name)
        assert orb.s.shape == (3,)
        assert np.min(np.abs(orb.multipliers)) < 1e-9
        M_fd = fd_monodromy(g, orb.s, orb.period)
        assert np.min(np.abs(np.linalg.eigvals(M_fd))) < 1e-6 * np.linalg.norm(M_fd, 2)


def test_a_state_and_its_coordinates_must_agree():
    g = _fig9(0.2)
    with pytest.raises(ContinuationError):
        period_map(g, [0.5, 0.1, 0.0], 1)  # x4 = 0 is a stuck bit: 2 coordinates
