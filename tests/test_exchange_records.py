"""The exchange kernel on its records: what it returns, and the held force the lane takes from it.

The kernel returns ``(F, residual, defect, held)``; the lane uses ``held`` as the force the
hammer holds over the next step when that step has the same length, and computes it afresh
otherwise or after a roll-back.  The oracle of the held force is numpy's polynomial through
the history (``polyfit``), integrated over the step (``polyint``), computed here.
"""
import math

import numpy as np
import pytest

from hammerbit.cosim.config import CosimConfig
from hammerbit.cosim.exchange import (EXCHANGE_OUT_DEFECT, EXCHANGE_OUT_ENERGY_RESIDUAL, EXCHANGE_OUT_FORCE,
                                      DenseForm, ExchangeHistory, ExchangeScheme, HammerStep, Interface,
                                      ModalForm, exchange_step)
from hammerbit.cosim.lane import Lane
from hammerbit.cosim.string_side import StringSide
from hammerbit.drillstring import load_string
from hammerbit.model.string_step import ExactStep, StringState

#: the step lengths of the runs below [s]: uneven, with repeats (the lane's cached held force)
STEPS = [1e-3, 1e-3, 5e-4, 5e-4, 1e-3, 2e-3, 2e-3, 1e-3]


def mean_of_polynomial(order, th, Fh, h):
    """Mean over [t_n, t_n + h] of the polynomial of degree ``order`` through the newest
    ``order + 1`` points of the history (numpy's fit: an oracle independent of held_weights)."""
    s = th[:order + 1] - th[0]
    prim = np.polyint(np.polyfit(s, Fh[:order + 1], order))
    return (np.polyval(prim, h) - np.polyval(prim, 0.0)) / h


def _small_side(dense: bool) -> ExactStep:
    """A stable four-state string side (random, seeded): the exchange does not care about physics."""
    rng = np.random.default_rng(7)
    n = 4
    A1 = rng.normal(size=(n, n)) - 6.0 * np.eye(n)
    E = rng.normal(size=(n, 2))
    frow = rng.normal(size=n) * 1e3
    return ExactStep(A1, E, frow, 2e6, 2e3, rng.normal(size=(3, n)), 5e4, dense=dense)


@pytest.mark.parametrize("dense", [False, True], ids=["modal", "dense"])
@pytest.mark.parametrize("order", [0, 1, 2])
def test_exchange_returns_its_outputs_and_the_held_force_of_a_next_step(dense, order):
    side = _small_side(dense)
    state = StringState(side, STEPS[0])
    assert state.modal is (not dense)
    th = np.array([0.0, -1e-3, -2.5e-3])
    wh = np.zeros((3, 2))
    Fh = np.array([5.0e4, 5.2e4, 4.9e4])
    out = np.zeros(4)
    hist = ExchangeHistory(th, wh, Fh, out, np.zeros(6))
    scheme = ExchangeScheme(False, order, False)
    iface = Interface(side.ki, side.ci, 5e4, np.zeros(2))
    rng = np.random.default_rng(3)
    for h in STEPS:
        d = side.discretisation(h)
        if state.modal:
            form = ModalForm(d.m_d, d.m_G, d.m_irow, d.m_icol, state.v, side.m_frow)
        else:
            form = DenseForm(d.P, state.v, state.buf, state.tmp, side.frow)
        F_held = 5e4 + 1e3 * rng.normal()
        F, residual, defect, held = exchange_step(scheme, h, form, iface, hist,
                                                  HammerStep(1e-5 * rng.normal(), 1e-3 * rng.normal(), F_held))
        assert (F, residual, defect) == (out[EXCHANGE_OUT_FORCE], out[EXCHANGE_OUT_ENERGY_RESIDUAL],
                                         out[EXCHANGE_OUT_DEFECT])
        assert F == Fh[0]                          # the history took the step's force
        assert held == pytest.approx(mean_of_polynomial(order, th, Fh, h), rel=1e-12)


@pytest.mark.parametrize("fmi", [False, True], ids=["library", "fmi-form"])
def test_a_short_step_is_a_point_of_the_history_except_as_a_leftover_in_the_fmi_form(fmi):
    """A step far shorter than the last (the adaptive master's step after a rejection) adds a
    point to the history, so the next extrapolation goes through its new input; only the FMI
    form (a user's master landing on an output point) takes it as a leftover that moves the
    newest point instead."""
    side = _small_side(False)
    state = StringState(side, 1e-3)
    th = np.array([0.0, -1e-3, -2e-3])
    hist = ExchangeHistory(th, np.zeros((3, 2)), np.array([5.0e4, 5.2e4, 4.9e4]), np.zeros(4), np.zeros(6))
    scheme = ExchangeScheme(False, 2, fmi)
    iface = Interface(side.ki, side.ci, 5e4, np.zeros(2))
    t = 0.0
    for h in [1e-3, 1e-3, 2e-6, 1e-3]:
        d = side.discretisation(h)
        form = ModalForm(d.m_d, d.m_G, d.m_irow, d.m_icol, state.v, side.m_frow)
        newest = th[0]
        exchange_step(scheme, h, form, iface, hist, HammerStep(1e-6, 1e-4, 5e4))
        t += h
        assert th[0] == pytest.approx(t, abs=1e-15)           # the newest point is the step's end
        leftover = fmi and h < 1e-5
        if leftover:                                          # the newest point moved: spacings that a
            assert th[1] < newest and th[0] - th[1] > 1e-3    # divided difference can take
        else:
            assert th[1] == newest                            # a point added


class _Hammer:
    """A hammer side on a prescribed smooth trajectory, with a state (its time) to roll back."""

    x_eq = 0.0
    master_harmonic = None

    def __init__(self):
        self.t = 0.0
        self.held = []

    def step(self, t, h, force):
        self.t = t + h
        self.held.append(force)

    def read(self):
        w = 2 * math.pi * 17.0
        return [1e-4 * math.sin(w * self.t), 1e-4 * w * math.cos(w * self.t), 0.0, 0.0, 0.0]

    def get_state(self):
        return self.t

    def set_state(self, t):
        self.t = t

    def free_state(self, t):
        pass


@pytest.fixture(scope="module")
def side():
    return StringSide(load_string("field-2200m"), CosimConfig(estimate=False, f_max=100.0))


@pytest.mark.parametrize("order", [1, 2])
def test_the_lane_holds_the_polynomial_mean_over_every_step(side, order):
    """Uneven steps: the force handed to the hammer is the mean of the extrapolation
    polynomial over the step about to be taken, whether the step repeats the last length
    (the kernel's value) or not."""
    cfg = CosimConfig(scheme="jacobi", extrapolation=order, estimate=False, f_max=100.0)
    hammer = _Hammer()
    lane = Lane(side, hammer, cfg, 1e-3)
    t = 0.0
    for h in STEPS:
        want = mean_of_polynomial(order, lane.th.copy(), lane.Fh.copy(), h)
        lane.step(t, h)
        assert hammer.held[-1] == pytest.approx(want, rel=1e-12), (t, h)
        t += h


def test_a_rolled_back_step_takes_the_held_force_of_the_restored_history(side):
    """Step, roll back, take the same step again: the same held force and the same result
    (not the held force the rolled-back step left for its successor)."""
    cfg = CosimConfig(scheme="jacobi", extrapolation=2, estimate=False, f_max=100.0)
    hammer = _Hammer()
    lane = Lane(side, hammer, cfg, 1e-3)
    t = 0.0
    for h in STEPS[:4]:
        lane.step(t, h)
        t += h
    h = STEPS[3]
    snap = lane.snapshot()
    lane.step(t, h)
    first = (hammer.held[-1], lane.F, lane.residual, lane.defect, lane.hist.copy())
    lane.restore(snap)
    assert (lane.F, lane.residual, lane.defect) == (lane.sc[EXCHANGE_OUT_FORCE],
                                                    lane.sc[EXCHANGE_OUT_ENERGY_RESIDUAL],
                                                    lane.sc[EXCHANGE_OUT_DEFECT])
    lane.step(t, h)
    again = (hammer.held[-1], lane.F, lane.residual, lane.defect, lane.hist.copy())
    assert again[:4] == first[:4]
    np.testing.assert_array_equal(again[4], first[4])


@pytest.mark.parametrize("order", [0, 2])
def test_the_dense_and_the_modal_form_give_the_same_exchange(order):
    """Two independent discretisations of one side (``expm`` of the augmented system; the
    eigenbasis) through their two kernels: the same forces, residuals, defects and held forces."""
    got = {}
    for dense in (False, True):
        side = _small_side(dense)
        state = StringState(side, STEPS[0])
        hist = ExchangeHistory(np.array([0.0, -1e-3, -2.5e-3]), np.zeros((3, 2)),
                               np.array([5.0e4, 5.2e4, 4.9e4]), np.zeros(4), np.zeros(6))
        scheme, iface = ExchangeScheme(False, order, False), Interface(side.ki, side.ci, 5e4, np.zeros(2))
        rng = np.random.default_rng(11)
        rows = []
        for h in STEPS:
            d = side.discretisation(h)
            form = (DenseForm(d.P, state.v, state.buf, state.tmp, side.frow) if dense else
                    ModalForm(d.m_d, d.m_G, d.m_irow, d.m_icol, state.v, side.m_frow))
            rows.append(exchange_step(scheme, h, form, iface, hist,
                                      HammerStep(1e-5 * rng.normal(), 1e-3 * rng.normal(), 5e4 + 1e3 * rng.normal())))
        got[dense] = np.array(rows)
    modal, dense = got[False], got[True]
    scale = np.max(np.abs(modal), axis=0)
    assert np.all(np.abs(dense - modal) <= 1e-9 * scale), (dense - modal) / scale


def test_the_recorded_interface_and_held_forces_are_their_own_columns():
    """Extrapolation order 0: the hammer holds, over each step, the interface force of the
    step before (so a swap of the two recorded columns shows)."""
    from hammerbit.cosim.master import cosimulate
    c = CosimConfig(stop=0.03, step=1e-3, extrapolation=0, estimate=False, check_step=False, f_max=100.0,
                    record=("interface_force", "hammer_force"), progress=False)
    d = cosimulate(load_string("field-2200m"), c).data
    assert np.ptp(d["interface_force"]) > 1.0          # the force moves
    np.testing.assert_array_equal(d["hammer_force"][1:], d["interface_force"][:-1])


def test_the_stability_watch_sums_its_window_of_steps():
    """The largest window sum of |residual| over windows of ``stability_window`` steps, against
    the sums computed here."""
    from hammerbit.cosim.stability import StabilityWatch
    c = CosimConfig(estimate=False, stability_window=10, energy_tol=1e9)
    side = type("Side", (), {"wob": 5e4, "ki": 2e6})()
    watch = StabilityWatch(c, side, t_steady=0.0)
    r = np.sin(np.arange(35) * 0.7) ** 2 * np.arange(35) * 1e-6
    for k, rk in enumerate(r):
        watch.update((k + 1) * 1e-3, k, 1e-3, 5e4, [0.0, 0.0, 0.0, 0.0, 0.0], float(rk))
    want = max(np.abs(r[i:i + 10]).sum() for i in range(0, 30, 10))
    assert watch.max_win == pytest.approx(want, rel=1e-12)
    assert watch.total == pytest.approx(r.sum(), rel=1e-12)
