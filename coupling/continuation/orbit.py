"""A periodic orbit of the relative motion: found from a simulation, corrected by Newton's method on the period-n map, its Floquet multipliers.

The forcing fixes the phase, so a period-n orbit is a fixed point of the
period-n map (:func:`.monodromy.period_map`) at phase 0, in the relative
coordinates ``s = (x1 - x3, x2, x4)`` (``(x1 - x3, x2)`` with the bit stuck
at phase 0).  Its Floquet multipliers are the eigenvalues of the monodromy
matrix, the map's Jacobian.  The bit's common drift is one more, trivial,
multiplier 1 that these coordinates leave out.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.stepping import Stepper
from hammerbit.scene.analysis import detect_period

from .monodromy import ORBIT_SOLVER, ContinuationError, MapResult, full_state, period_map, relative_state

__all__ = ["PeriodicOrbit", "orbit_from_simulation", "correct_orbit", "make_orbit", "NEWTON_TOL", "NEWTON_MAX_ITER",
           "SETTLE_PERIODS", "MAX_PERIOD"]

#: Newton's residual |P^n(s) - s| (max norm) at which an orbit is accepted, relative to max(1, |s|)
NEWTON_TOL = 1e-11
NEWTON_MAX_ITER = 25
#: periods run from rest before the period is read off the Poincaré section
SETTLE_PERIODS = 400
#: the longest period looked for
MAX_PERIOD = 16
#: the Poincaré rows compared when reading the period off a simulation
PERIOD_ROWS = 4 * MAX_PERIOD
#: relative tolerance of a repeat at the Poincaré section
PERIOD_TOL = 1e-6


@dataclass
class PeriodicOrbit:
    """A period-n orbit at phase 0 with its Floquet multipliers.

    Attributes
    ----------
    groups : Groups
    period : int
        n, in forcing periods.
    s : ndarray
        Map coordinates at phase 0: (x1 - x3, x2, x4), or (x1 - x3, x2) stuck.
    monodromy : ndarray (k, k)
    multipliers : ndarray of complex
        Eigenvalues of the monodromy, largest modulus first.
    drift : float
        Bit advance over the n periods [x0] (the ROP is drift / n per period).
    residual : float
        |P^n(s) - s| in the max norm.
    events : ndarray
        The event log over one period n (``kernel_layouts.L_*`` columns).
    """

    groups: Groups
    period: int
    s: np.ndarray
    monodromy: np.ndarray
    multipliers: np.ndarray
    drift: float
    residual: float
    events: np.ndarray = field(repr=False, default=None)

    @property
    def stuck(self) -> bool:
        """The bit is stuck at phase 0."""
        return self.s.shape[0] == 2

    @property
    def state(self) -> np.ndarray:
        """The Stepper's state (x1, x2, x3 = 0, x4) at phase 0."""
        return full_state(self.s)

    @property
    def modes(self) -> tuple[int, int]:
        """(stick/slip, contact) modes at phase 0, as the Stepper sets them from :attr:`state`."""
        st = Stepper(self.groups, solver=ORBIT_SOLVER, y0=self.state, compile_helper=False)
        return int(st.istate[KL.I_STICK]), int(st.istate[KL.I_CONTACT])

    @property
    def rop_x0_per_period(self) -> float:
        """Bit advance per forcing period [x0]."""
        return self.drift / self.period

    @property
    def max_multiplier(self) -> float:
        return float(np.max(np.abs(self.multipliers))) if self.multipliers.size else 0.0

    @property
    def stable(self) -> bool:
        return self.max_multiplier < 1.0


def orbit_from_simulation(groups: Groups, *, periods: int = SETTLE_PERIODS, y0=None):
    """A first guess of the periodic orbit a run reaches: (n, s), or None when no period <= MAX_PERIOD repeats.

    Runs ``periods`` forcing periods from ``y0`` (rest by default) and reads
    the period off the last Poincaré rows.
    """
    st = Stepper(groups, solver=ORBIT_SOLVER, y0=y0, compile_helper=False)
    poin = np.zeros((periods + 1, 5))
    try:
        st.advance(periods * groups.period, poincare=poin)
    except SolverError as e:
        raise ContinuationError(f"the settling run failed: {e}") from None
    rows = poin[-PERIOD_ROWS:]
    n = detect_period(rows, max_period=MAX_PERIOD, tol=PERIOD_TOL)
    if n is None:
        return None
    y = rows[-1, 1:5]
    return n, relative_state(y, y[3] == 0.0)


def _coordinates_after(s_new: np.ndarray, res: MapResult) -> np.ndarray:
    """Newton's new iterate in the coordinates its stick/slip state needs at phase 0."""
    if s_new.shape[0] == 3 and s_new[2] <= 0.0:
        return s_new[:2].copy()  # the bit velocity cannot go negative: the bit is stuck at phase 0
    if s_new.shape[0] == 2 and not res.stuck_end and res.y_end[3] > 0.0:
        return np.array([s_new[0], s_new[1], res.y_end[3]])  # the orbit slips through phase 0
    return s_new


def correct_orbit(groups: Groups, s, n: int, *, tol: float = NEWTON_TOL,
                  max_iter: int = NEWTON_MAX_ITER) -> PeriodicOrbit:
    """Newton's method on P^n(s) - s = 0 from the guess ``s``; the orbit and its multipliers.

    Raises
    ------
    ContinuationError
        No convergence in ``max_iter`` iterations.
    """
    s = np.array(s, dtype=float)
    for _ in range(max_iter):
        res = period_map(groups, s, n)
        r = res.s_end - s
        err = float(np.max(np.abs(r)))
        if err <= tol * max(1.0, float(np.max(np.abs(s)))):
            return make_orbit(groups, n, s, res)
        J = res.jacobian - np.eye(s.shape[0])
        try:
            ds = np.linalg.solve(J, -r)
        except np.linalg.LinAlgError:
            raise ContinuationError(f"period-{n} orbit: singular Newton matrix (a multiplier 1)") from None
        s = _coordinates_after(s + ds, res)
    raise ContinuationError(f"period-{n} orbit: Newton did not converge in {max_iter} iterations "
                            f"(residual {err:.3g})")


def make_orbit(groups: Groups, n: int, s: np.ndarray, res: MapResult) -> PeriodicOrbit:
    """The orbit at a converged fixed point ``s`` of the period-n map, from the map's result there."""
    err = float(np.max(np.abs(res.s_end - s)))
    mu = np.linalg.eigvals(res.jacobian)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    return PeriodicOrbit(groups=groups, period=n, s=s, monodromy=res.jacobian, multipliers=mu,
                         drift=float(res.y_end[2]), residual=err, events=res.events)
