"""The in-process hammer side of the co-simulation: the FMU's kernels and stepper, called directly."""
from __future__ import annotations

from typing import Optional

import numpy as np

from hammerbit.model.kernel_layouts import F_T, FREE, I_CONTACT, I_STICK, P_A, P_B, P_FEXT, STICK
from hammerbit.model.params import RigParameters

from hammerbit.cosim.config import CosimConfig, event_counts
from hammerbit.cosim.hammer_interface import (OUT_BIT_POSITION, OUT_BIT_VELOCITY, OUT_HAMMER_POSITION,
                                              OUT_HAMMER_VELOCITY, OUT_WOB)

__all__ = ["StepperHammer"]


class StepperHammer:
    """The hammer–bit–rock model in process (the FMU's kernels, same stepper).

    Starts in static equilibrium under the WOB ``W``: hammer at ``x_h = W/K``
    (its spring compressed by ``W/K``), bit stuck at 0, both at rest.  The
    ``preload`` (interface force) is held over each step as in the FMU.
    With ``ramp`` (a :class:`CosimConfig` with ``ramp > 0``) the harmonic
    amplitude is set per step to its ramped value at the step's midpoint.
    """

    def __init__(self, rig: RigParameters, wob: float, *, rtol: float = 1e-10, t0: float = 0.0,
                 ramp: Optional[CosimConfig] = None):
        from hammerbit.model.kernel_forces import force_on_bit
        from hammerbit.model.solver_options import SolverOptions
        from hammerbit.model.stepping import Stepper
        self.rig = rig
        s = rig.scales
        self.F0, self.x0, self.Om, self.v0 = s.friction_force, s.length, s.omega, s.velocity
        g = rig.to_groups().replace(b=0.0)
        self.groups = g
        self._force_on_bit = force_on_bit
        self.st = Stepper(g, solver=SolverOptions(rtol=rtol, atol=rtol * 1e-2),
                          y0=[wob / self.F0, 0.0, 0.0, 0.0])
        self.st.fstate[F_T] = self.Om * t0
        self.x_eq = wob / rig.stiffness
        self._ramp = ramp
        self._a = float(g.a)

    master_harmonic = None

    def step(self, t: float, H: float, force: float) -> None:
        p = self.st.p
        p[P_B] = force / self.F0
        if self.master_harmonic is not None:
            p[P_FEXT] = self.master_harmonic.mean(t, H) / self.F0
        elif self._ramp is not None:
            p[P_A] = self._a * self._ramp.ramp_factor(t + 0.5 * H)
        self.st.advance(self.Om * (t + H))

    def get_state(self):
        """Snapshot of the whole hammer state (for rollback)."""
        return self.st.get_state()

    def set_state(self, state) -> None:
        """Restore a snapshot of :meth:`get_state`."""
        self.st.set_state(state)

    def free_state(self, state) -> None:
        pass

    def read(self) -> np.ndarray:
        """(x_h [m], v_h [m/s], x_bit [m], v_bit [m/s], drive on bit [N])."""
        y = self.st.y
        fd = self._force_on_bit(y, self.st.p, self.st.istate[I_CONTACT])
        out = np.empty(5)
        out[OUT_HAMMER_POSITION], out[OUT_HAMMER_VELOCITY] = y[0] * self.x0, y[1] * self.v0
        out[OUT_BIT_POSITION], out[OUT_BIT_VELOCITY] = y[2] * self.x0, y[3] * self.v0
        out[OUT_WOB] = fd * self.F0
        return out

    def flags(self) -> tuple:
        """(stick, contact): 1.0 while the bit sticks / while the gap is closed."""
        ist = self.st.istate
        return (1.0 if ist[I_STICK] == STICK else 0.0, 0.0 if ist[I_CONTACT] == FREE else 1.0)

    def counts(self) -> dict:
        """Event counts (:func:`~hammerbit.cosim.config.event_counts` names)."""
        return event_counts(self.st.counts)

    def close(self):
        pass
