"""Kernel pieces against independent oracles: the event indicators' slopes against finite differences
of their values, and the kinetic friction law beyond the stop (v < 0)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from hammerbit.model import kernel_events as KE
from hammerbit.model import kernel_forces as KF
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.presets import preset


@njit(cache=False)
def _value(kind, y, p, mc):
    return KE.watch_value(kind, y, p, mc)


@njit(cache=False)
def _slope(kind, y, f, p, mc):
    return KE.watch_slope(kind, y, f, p, mc)


@njit(cache=False)
def _value_given_drive(kind, y, p, mc):
    return KE.watch_value_drive(kind, y, p, mc, KF.force_on_bit(y, p, mc))


@njit(cache=False)
def _slope_given_rate(kind, y, f, p, mc):
    return KE.watch_slope_drive(kind, y, f, p, mc, KE.drive_rate(y, f, p, mc))


KINDS = [KL.EV_SLIP_START, KL.EV_BOUNCE, KL.EV_BOUNCE_END, KL.EV_STICK, KL.EV_IMPACT, KL.EV_SEPARATION,
         KL.EV_CLAMP, KL.EV_UNCLAMP]


@pytest.mark.parametrize("mc", [KL.FREE, KL.CONTACT, KL.CLAMPED], ids=["free", "contact", "clamped"])
@pytest.mark.parametrize("kind", KINDS, ids=[KL.EVENT_NAMES[k] for k in KINDS])
def test_watch_slope_is_the_time_derivative_of_watch_value(kind, mc):
    """d/dt w(y(t)) along a motion with state derivative f (positions moving with the velocities,
    any accelerations), by central differences of ``watch_value``, equals ``watch_slope(y, f)``, at
    states with the gap closed (d > 0) and the hammer moving either way; so does the slope the solver
    forms from the drive's rate (``watch_slope_drive``), and ``watch_value_drive`` equals ``watch_value``."""
    p = preset("paper-fig12").replace(a=0.06, xi=0.07, lam_hat=0.3).to_kernel()
    rng = np.random.default_rng(kind * 7 + mc)
    for _ in range(5):
        y = np.array([p[KL.P_R] + 0.3 + rng.random(), rng.normal(), 0.2 * rng.random(), rng.normal()])
        f = rng.normal(size=4)
        f[KL.X_HAMMER], f[KL.X_BIT] = y[KL.V_HAMMER], y[KL.V_BIT]      # kinematics: x' = v
        eps = 1e-6
        fd = (_value(kind, y + eps * f, p, mc) - _value(kind, y - eps * f, p, mc)) / (2 * eps)
        slope = _slope(kind, y, f, p, mc)
        assert slope == pytest.approx(fd, rel=1e-6, abs=1e-7), (y, f)
        # the solver's forms given the drive and its rate at a step end: the same numbers
        assert _slope_given_rate(kind, y, f, p, mc) == pytest.approx(fd, rel=1e-6, abs=1e-7), (y, f)
        assert _value_given_drive(kind, y, p, mc) == _value(kind, y, p, mc)


def test_kinetic_friction_beyond_the_stop_is_a_smooth_continuation():
    """For v < 0 (trial stages past a stop) the law is exp(-gamma_hat v) down to gamma_hat v = -4,
    then a parabola that joins it with the same value and slope and curves upward (no blow-up)."""
    g = preset("paper-fig9").replace(mu=0.8, gamma_hat=5.0)
    p = g.to_kernel()
    mu, gh = 0.8, 5.0
    v = -0.3                                             # gamma_hat v = -1.5: the exponential itself
    assert KF.kinetic_friction(v, p) == pytest.approx(mu + (1 - mu) * math.exp(1.5), rel=1e-14)
    v_join = -4.0 / gh
    h = 1e-7
    left = KF.kinetic_friction(v_join - h, p)
    right = KF.kinetic_friction(v_join + h, p)
    exact = mu + (1 - mu) * math.exp(4.0)
    assert KF.kinetic_friction(v_join, p) == pytest.approx(exact, rel=1e-14)
    slope_exact = -(1 - mu) * gh * math.exp(4.0)
    assert (right - left) / (2 * h) == pytest.approx(slope_exact, rel=1e-5)
    assert (KF.kinetic_friction(v_join - 2 * h, p) - left) / -h == pytest.approx(slope_exact, rel=1e-5)
    # far past the join: the second-order Taylor polynomial of exp at gamma_hat v = -4, by hand
    u = -2.0                                             # gamma_hat v = -6
    taylor = math.exp(4.0) * (1.0 - u + 0.5 * u * u)
    assert KF.kinetic_friction(-6.0 / gh, p) == pytest.approx(mu + (1 - mu) * taylor, rel=1e-14)
    assert KF.kinetic_friction(-6.0 / gh, p) < mu + (1 - mu) * math.exp(6.0)
