"""One lane of the co-simulation: a hammer side, a string state and their exchange histories.

The run and its half-step companion are two lanes on one
:class:`~hammerbit.cosim.string_side.StringSide`.
"""
from __future__ import annotations

import numpy as np
from numba import typeof

from hammerbit.model.numba_dispatch import entry_point

from hammerbit.cosim.amplitude import StepLog
from hammerbit.cosim.config import CosimConfig
from hammerbit.cosim.exchange import (EXCHANGE_OUT_DEFECT, EXCHANGE_OUT_ENERGY_RESIDUAL, EXCHANGE_OUT_FORCE,
                                      EXCHANGE_OUT_STRING_FORCE, HAMMER_ARG, DenseForm, ExchangeHistory,
                                      ExchangeScheme, HammerStep, Interface, ModalForm, exchange_kernel, held_force)
from hammerbit.cosim.hammer_interface import OUT_HAMMER_POSITION, OUT_HAMMER_VELOCITY
from hammerbit.cosim.string_side import StringSide, StringState

__all__ = ["Lane"]


class Lane:
    """A run of the coupled system: its hammer side, its string state, its histories.

    The run and its half-step companion are two lanes on one :class:`StringSide`.
    """

    def __init__(self, side: StringSide, hammer, config: CosimConfig, H_hist: float):
        c = config
        self.side, self.hammer, self.c = side, hammer, c
        self.gs = c.scheme == "gauss-seidel"
        self.order = c.extrapolation
        self.fmi = c.exchange == "fmi"
        self.string = StringState(side)
        self.x_eq = hammer.x_eq
        self.out = hammer.read()
        # the exchange histories and scalars in one array (one copy per snapshot): th (3,)
        # communication times, wh (3, 2) hammer (x deviation, v), Fh (3,) interface forces,
        # sc (4,) the exchange's outputs
        self.hist = np.zeros(16)
        self.th, self.wh = self.hist[0:3], self.hist[3:9].reshape(3, 2)
        self.Fh, self.sc = self.hist[9:12], self.hist[12:16]
        self.th[:] = (c.start, c.start - H_hist, c.start - 2 * H_hist)
        self.wh[:] = (self.out[OUT_HAMMER_POSITION] - self.x_eq, self.out[OUT_HAMMER_VELOCITY])
        self.sc[EXCHANGE_OUT_STRING_FORCE] = self.string.f_xi()
        F = (side.wob + self.sc[EXCHANGE_OUT_STRING_FORCE] - side.ki * self.wh[0, 0]
             - side.ci * (self.wh[0, 1] - side.feed[0]))
        self.sc[EXCHANGE_OUT_FORCE] = F
        self.Fh[:] = F
        self.F_held = F
        # the exchange's outputs as floats (the kernel returns them; hist holds them for a snapshot):
        # the interface force [N], the step's energy residual [J] and force defect [N]
        self.F, self.residual, self.defect = float(F), 0.0, 0.0
        # the held force over a next step of length _next_h (the exchange computes it for its own h)
        self._next_held, self._next_h = F, None
        self.w = np.zeros(3)
        self.frow = side.m_frow if self.string.modal else side.frow.astype(np.float64)
        # the hammer's output derivatives as the string's input derivatives (CosimConfig.output_derivatives)
        self.given = c.output_derivatives
        if self.given and getattr(hammer, "output_derivative_order", 0) < 2:
            raise ValueError("output_derivatives: the hammer side gives no output derivatives of order 2 (the "
                             "native HammerBitRock.fmu has them; maxOutputDerivativeOrder = "
                             f"{getattr(hammer, 'output_derivative_order', 0)})")
        self.scheme = ExchangeScheme(self.gs, self.order, self.fmi, self.given)
        self.iface = Interface(side.ki, side.ci, side.wob, side.feed)
        self.exchange_hist = ExchangeHistory(self.th, self.wh, self.Fh, self.sc, np.zeros(6))
        self._h = None                           # the last step length
        # per step length: [the exchange (its compiled entry point after the first call), its
        # arguments (exchange_args), its dispatcher]; the held force's entry point after the first step
        self._calls, self._call = {}, None
        self._held = held_force
        rig = c.rig
        self.steps = StepLog(self.out, hammer_mass=rig.hammer_mass, amplitude=rig.amplitude,
                             frequency=rig.frequency, phase=rig.phase,
                             master_harmonic=getattr(hammer, "master_harmonic", None),
                             ramp=c if c.ramp > 0.0 else None)
        """Every step of the lane, for the WOB within the steps (:meth:`wob_amplitude`)."""

    def load_kernels(self, h: float) -> None:
        """Load (or compile) the exchange and held-force kernels for steps of length ``h`` now,
        in the run's set-up, rather than inside its first step (the stepping time would count it)."""
        args = self.exchange_args(h, self.side.discretisation(h))
        args[HAMMER_ARG] = HammerStep(0.0, 0.0, 0.0)
        exchange_kernel(args[2]).compile(tuple(typeof(a) for a in args))
        held_force.compile(tuple(typeof(a) for a in (self.order, self.th, self.Fh, h, self.w)))

    def step(self, t: float, h: float) -> None:
        """One macro step [t, t + h]: hammer first, then the string (both schemes;
        Jacobi's string input does not use the new hammer value)."""
        F_held = self._next_held if h == self._next_h else self._held(self.order, self.th, self.Fh, h, self.w)
        self.F_held = F_held
        if self.given:   # x', v', x'', v'' of the hammer at t with its new input: the string's polynomial
            self.exchange_hist.coeffs[2:] = self.hammer.motion_derivatives(t, h, F_held)
        self.hammer.step(t, h, F_held)
        out = self.out = self.hammer.read()
        self.steps.add(t, h, F_held, out)
        if h != self._h:
            self._h = h
            call = self._calls.get(h)
            if call is None:  # a new step length: its arrays, typed by the dispatcher once
                args = self.exchange_args(h, self.side.discretisation(h))
                kernel = exchange_kernel(args[2])
                call = self._calls[h] = [kernel, args, kernel]
            self._call = call
        call = self._call
        args = call[1]
        args[HAMMER_ARG] = HammerStep(out[OUT_HAMMER_POSITION] - self.x_eq, out[OUT_HAMMER_VELOCITY], F_held)
        self.F, self.residual, self.defect, self._next_held = call[0](*args)
        self._next_h = h
        if call[0] is call[2]:  # compiled by now: later steps of this length skip the type dispatch
            call[0] = entry_point(call[2], args)
            if self._held is held_force:
                self._held = entry_point(held_force, (self.order, self.th, self.Fh, h, self.w))

    def exchange_args(self, h: float, d) -> list:
        """The arguments of the exchange kernel for steps of length ``h`` (discretisation ``d``);
        the hammer's step (at ``HAMMER_ARG``) is set per step."""
        s = self.string
        if s.modal:
            form = ModalForm(d.m_d, d.m_G, d.m_irow, d.m_icol, s.v, self.frow)
        else:
            form = DenseForm(d.P, s.v, s.buf, s.tmp, self.frow)
        return [self.scheme, h, form, self.iface, self.exchange_hist, None]

    def wob_amplitude(self, t_from: float) -> float:
        """The WOB amplitude of the lane [N]: the fundamental harmonic at the forcing frequency over
        the last whole forcing periods after ``t_from`` [s], from the WOB within each step."""
        return self.steps.wob_harmonic(t_from)[0]

    def wob_phasor(self, t_from: float) -> complex:
        """The lane's first harmonic of the WOB at the forcing frequency, ``a + i b`` [N]
        (:meth:`~hammerbit.cosim.amplitude.StepLog.wob_phasor`)."""
        return self.steps.wob_phasor(t_from)[2]

    def snapshot(self):
        return (self.hammer.get_state(), self.string.copy_state(), self.hist.copy(), self.out.copy(),
                len(self.steps))

    def restore(self, snap) -> None:
        hs, v, hist, out, n_steps = snap
        self.steps.truncate(n_steps)
        self.hammer.set_state(hs)
        self.string.restore(v)
        self.hist[:] = hist
        self.out = out.copy()
        self.F = float(self.sc[EXCHANGE_OUT_FORCE])
        self.residual = float(self.sc[EXCHANGE_OUT_ENERGY_RESIDUAL])
        self.defect = float(self.sc[EXCHANGE_OUT_DEFECT])
        self._next_h = None

    def free(self, snap) -> None:
        self.hammer.free_state(snap[0])
