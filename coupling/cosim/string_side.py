"""The string side of the co-simulation: the drillstring and the interface spring, stepped exactly.

Over a macro step ``[t_n, t_n + h]`` the hammer motion seen by the string is
a polynomial (degree 0, 1 or 2) given by its Taylor coefficients
``c = (x, v, x', v', x'', v'')`` at ``t_n``.  The string state ``xi``
(deviation from static equilibrium) obeys ``xi' = A' xi + E w(s)``,
``A' = A - B (k_i C_u + c_i C_v)``, ``E = B [k_i, c_i]``.  Appending the
polynomial's coefficients as a nilpotent chain and the time integral of the
interface force as one more state gives one linear autonomous system whose
matrix exponential ``expm(Z h)`` (:func:`scipy.linalg.expm`, once per step
length) maps ``[xi_n, c]`` exactly to ``[xi_{n+1}, int (F_i - W) dt]``.

When the eigenvectors of ``A'`` reproduce that step to 1e-10 the state is
kept in modal coordinates (``eta <- exp(lam h) eta + G c``, one of each
conjugate pair kept: O(n) per step); otherwise the dense mat-vec is used.
:class:`StringSide` holds the model and the discretisations (cached per step
length, shared by a run and its half-step companion); :class:`StringState`
holds one run's state.  The step itself is
:class:`hammerbit.model.string_step.ExactStep`, the one source the
Drillstring FMU carries too; this module builds it from the string's model and
remembers decompositions and exponentials across sides.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from hammerbit.memo import digest, memo
from hammerbit.model.string_kernels import string_step_dense, string_step_modal
from hammerbit.model.string_step import ExactStep, one_blas_thread
from hammerbit.model.string_step import StringState as RunState

__all__ = ["StringSide", "StringState", "string_step_dense", "string_step_modal"]


class StringSide(ExactStep):
    """The drillstring plus interface spring and its exact step over any macro step.

    Holds the model and the discretisations (one per step length, cached;
    :class:`hammerbit.model.string_step.ExactStep`, the step the Drillstring FMU
    takes too); the state of a run lives in :class:`StringState` (a run and its
    companion share one side).

    Parameters
    ----------
    string : DrillString
    config : CosimConfig

    Attributes
    ----------
    ss : StateSpace
        Exported model (``hammerbit.drillstring.state_space``) at the WOB.
    A1, E : ndarray
        Closed-interface state matrix and the input matrix of ``(x_h, v_h)``.
    Cu, Cv, Ct : ndarray
        Output rows: bit displacement, bit velocity, top tension.
    """

    def __init__(self, string, config):
        from hammerbit.drillstring import Boundary, state_space
        from hammerbit.drillstring.top import top_matrices
        self.config = config
        ki, ci = config.interface_stiffness, config.interface_damping
        self.wob = config.weight_on_bit
        with one_blas_thread():
            ss = state_space(string, None, Boundary.hammer(ki, ci), mass=config.mass,
                             wob=self.wob, f_max=config.f_max)
        if ss.x0 is None:
            raise ValueError("the string has a rigid-body mode: the top must hold it (fixed or spring hook)")
        self.ss = ss
        m = top_matrices(string, ss, config.top, interface_stiffness=ki, interface_damping=ci,
                         hammer_stiffness=config.rig.stiffness, mass=config.mass)
        self.matrices = m
        self.top = m.top
        self.gains = m.gains
        self.Cu, self.Cv, self.Ct = m.Cu, m.Cv, m.Ct
        rows3 = np.vstack((self.Cu, self.Cv, self.Ct))  # bit u, v; top tension
        # F_i - W = frow.xi - ki x_dev - ci v; the feed's (velocity [m/s], start time [s]): the block
        # is at V (t - t0)
        super().__init__(m.A1, m.E, m.frow, ki, ci, rows3, float(ss.hook_load),
                         dense=config.string_step == "dense",
                         feed=np.array([m.feed_velocity, float(config.start)]))
        self.xi = np.zeros(self.n)    # state of :meth:`step` (the single-run helper)

    @classmethod
    def from_arrays(cls, arrays: dict, info: dict, values: dict, config) -> "StringSide":
        """The side of a Drillstring FMU's arrays (:mod:`hammerbit.model.string_model`; ``info`` its
        description) at the parameter ``values`` (damping ratio, gains) with ``config.top``: the
        matrices the FMU steps with (``ss`` and ``matrices`` are None)."""
        from hammerbit.model.string_model import TOP_CONDITIONS, form_of, string_matrices
        self = cls.__new__(cls)
        self.config = config
        self.wob = config.weight_on_bit
        self.ss = self.matrices = self.gains = None
        self.top = config.top
        A1, E, frow, rows = string_matrices(arrays, form_of(TOP_CONDITIONS.index(config.top.kind)), values)
        rows3 = rows[:3]
        sc = info["scalars"]
        self.Cu, self.Cv, self.Ct = (np.array(r) for r in rows3)
        ExactStep.__init__(self, A1, E, frow, sc["interface_stiffness"], sc["interface_damping"], rows3,
                           sc["buoyed_weight"] - self.wob, dense=config.string_step == "dense",
                           feed=np.array([config.top.feed_velocity, float(config.start)]))
        self.xi = np.zeros(self.n)
        return self

    # -- the library remembers decompositions and exponentials across sides --
    def decompose(self):
        return memo(digest("eig", self.A1), super().decompose)

    def exponential(self, Z: np.ndarray, h: float) -> np.ndarray:
        return memo(digest("expm", Z, extra=h), lambda: ExactStep.exponential(self, Z, h))

    def _eigen(self):
        return self.eigen()

    def exchange_frequency(self, share: float = 1e-3) -> float:
        """Highest mode [Hz] of the string side carrying at least ``share`` of the
        interface's static compliance (the string modes the exchange sees)."""
        key = ("exchange_frequency", share)
        if key not in self._phi:
            self._phi[key] = self._exchange_frequency(share)
        return self._phi[key]

    def _exchange_frequency(self, share: float) -> float:
        eig = self.eigen()
        if eig is False:
            return float(np.max(np.abs(np.linalg.eigvals(self.A1).imag)) / (2 * math.pi))
        lam, V, Vinv = eig
        r = np.abs((self.frow @ V) * (Vinv @ self.E[:, 0]) / np.where(lam == 0, 1.0, lam))
        if not np.any(r > 0):
            return 0.0
        keep = r >= share * r.sum()
        return float(np.max(np.abs(lam.imag[keep])) / (2 * math.pi))

    # -- single-run helper (tests, one step from xi) -------------------------
    def step(self, coeffs: np.ndarray, h: float) -> float:
        """Advance ``self.xi`` over ``h`` with hammer-motion Taylor coefficients
        (6,) = (x, v, x', v', x'', v''); x as deviation from equilibrium.
        Returns the integral of (F_i - W) over the step [N s].  The same kernels
        as the master (modal form when available)."""
        st = StringState(self, self.xi)
        imp = st.advance(self.discretisation(h), np.asarray(coeffs, dtype=float))
        self.xi = st.xi()
        return imp


class StringState(RunState):
    """The string's state in one run (the first step length of the config decides the form)."""

    def __init__(self, side: StringSide, xi0: Optional[np.ndarray] = None):
        super().__init__(side, side.config.step, xi0)

