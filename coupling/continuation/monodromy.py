"""The period-n map of the relative motion and its Jacobian, the monodromy matrix (variational equations and saltation matrices).

The library's :class:`~hammerbit.model.stepping.Stepper` integrates the hybrid
system and logs every event (time, kind, state after the reset).  Between
events the flow is smooth in one mode and its sensitivity is integrated with
the variational equations (:mod:`.variational`); at an event the sensitivity
jumps by the saltation matrix

    S = G + (f+ - G f-) h_y^T / (h_y . f- + h_t)

of the event's indicator ``h``, the vector fields ``f-`` before and ``f+``
after and the reset map ``G`` (the identity on the continuous state here).
In this model ``f+ - f-`` vanishes at every event but one:

- stick -> slip (the drive reaches the static threshold 1): the slip
  acceleration is ``(F_d - f_f(0)) / rho = (1 - 1) / rho = 0`` there because
  friction is continuous at slip onset, and x3' = x4 = 0: ``S = I``;
- impact, separation, clamp and unclamp: the Hunt–Crossley force
  ``kc d^n (1 + lam d')`` is zero at d = 0 and at 1 + lam d' = 0: ``S = I``;
- a slip that touches v = 0 with the drive above the threshold (``slip_on``)
  changes no mode: ``S = I``;
- the bounce flag (the drive below -1 while stuck) changes no dynamics (the
  bit is held stuck either way): ``S = I``;
- slip -> stick (v_s falls to 0, ``h = x4``): the bit's acceleration
  ``f-_4 = a-`` drops to 0, so ``S = I - e4 e4^T``: the sensitivity of the bit
  velocity is erased, the sliding constraint x4 = 0 of the stuck bit.

The relative motion is invariant to a common shift of x1 and x3, so the
period-n map acts on ``s = (x1 - x3, x2, x4)`` at phase 0 (x3 = 0), or on
``s = (x1 - x3, x2)`` when the bit is stuck at phase 0 (x4 = 0 is then a
constraint, not a coordinate).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.kernel_forces import contact_mode_at_impact
from hammerbit.model.params import Groups
from hammerbit.model.solver_errors import SolverError
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import Stepper

from . import kernel_cache  # noqa: F401  (registers the cache locator before the kernels are decorated)
from .variational import DOP853, N_AUG, N_STATE, NO_SUBSYSTEM, SEG_OK, integrate_segment, segment_work

__all__ = ["MapResult", "ContinuationError", "period_map", "relative_state", "full_state", "ORBIT_SOLVER",
           "VARIATIONAL_RTOL", "VARIATIONAL_ATOL"]

#: the integration of an orbit: the library's DOP853 at the tolerance of the acceptance checks
ORBIT_SOLVER = SolverOptions(rtol=1e-12, atol=1e-13)
#: tolerances of the variational equations (state and sensitivity)
VARIATIONAL_RTOL = 1e-11
VARIATIONAL_ATOL = 1e-12
#: first event-log rows; the buffer doubles when full
LOG_ROWS = 256


class ContinuationError(RuntimeError):
    """An orbit could not be computed or followed; says at which parameter value and why."""


@njit(cache=True, _nrt=False)
def saltation(kind, phi):
    """Apply the saltation matrix of an event of ``kind`` to the sensitivity ``phi`` (in place).

    Only slip -> stick is not the identity (module docstring): ``S = I - e4 e4^T``.
    """
    if kind == KL.EV_STICK:
        for j in range(N_STATE):
            phi[N_STATE + KL.V_BIT * N_STATE + j] = 0.0


@njit(cache=True, _nrt=False)
def modes_after(kind, y, p, mode_s, mode_c):
    """The (stick/slip, contact) modes after an event of ``kind`` at ``y`` (as ``kernel_reset.apply_event``)."""
    if kind == KL.EV_SLIP_START:
        mode_s = KL.SLIP
    elif kind == KL.EV_STICK:
        mode_s = KL.STICK
    elif kind == KL.EV_IMPACT:
        mode_c = contact_mode_at_impact(y, p)
    elif kind == KL.EV_SEPARATION:
        mode_c = KL.FREE
    elif kind == KL.EV_CLAMP:
        mode_c = KL.CLAMPED
    elif kind == KL.EV_UNCLAMP:
        mode_c = KL.CONTACT
    return mode_s, mode_c


@njit(cache=True, _nrt=False)
def sensitivity_along(log, n_events, y0, t_end, p, modes0, work, w):
    """The sensitivity of the state at ``t_end`` to ``y0`` at time 0, along the logged events.

    ``log`` the Stepper's event rows (``L_*`` columns; the state after each
    reset), ``modes0`` the modes at time 0, ``work`` of :func:`.segment_work`;
    ``w`` (N_AUG,) receives the state and the 4 x 4 sensitivity.  Returns a
    ``SEG_*`` status.
    """
    for i in range(N_STATE):
        w[i] = y0[i]
    for i in range(N_STATE * N_STATE):
        w[N_STATE + i] = 0.0
    for i in range(N_STATE):
        w[N_STATE + i * N_STATE + i] = 1.0
    mode_s, mode_c = modes0[0], modes0[1]
    t = 0.0
    for r in range(n_events + 1):
        t1 = log[r, KL.L_T] if r < n_events else t_end
        if t1 > t:
            status = integrate_segment(t, t1, w, (p, mode_s, mode_c, NO_SUBSYSTEM), work, DOP853)
            if status != SEG_OK:
                return status
            t = t1
        if r < n_events:
            kind = int(log[r, KL.L_KIND])
            saltation(kind, w)
            # the segment restarts from the located event state: no drift of the integrated state
            for i in range(N_STATE):
                w[i] = log[r, KL.L_X1 + i]
            mode_s, mode_c = modes_after(kind, w[:N_STATE], p, mode_s, mode_c)
    return SEG_OK


@dataclass
class MapResult:
    """The period-n map at one state: where it goes, its Jacobian and what happened on the way.

    Attributes
    ----------
    y_end : ndarray (4,)
        The state after n periods, bit position included (the drift).
    s_end : ndarray
        The relative state after n periods (``relative_state``), in the
        coordinates of the start (2 if stuck at phase 0, else 3).
    jacobian : ndarray (k, k) or None
        d s_end / d s, the monodromy matrix of the period-n orbit when s_end = s.
    stuck_end : bool
        The bit is stuck at the end.
    events : ndarray (m, 8)
        The Stepper's event log (``kernel_layouts.L_*`` columns).
    """

    y_end: np.ndarray
    s_end: np.ndarray
    jacobian: np.ndarray | None
    stuck_end: bool
    events: np.ndarray


def relative_state(y, stuck: bool) -> np.ndarray:
    """The coordinates of the period-n map at a state ``y`` (x1..x4): (x1 - x3, x2[, x4])."""
    if stuck:
        return np.array([y[0] - y[2], y[1]])
    return np.array([y[0] - y[2], y[1], y[3]])


def full_state(s) -> np.ndarray:
    """The Stepper's state (x1, x2, x3 = 0, x4) of map coordinates ``s`` (x4 = 0 when ``s`` has 2)."""
    s = np.asarray(s, dtype=float)
    return np.array([s[0], s[1], 0.0, s[2] if s.shape[0] == 3 else 0.0])


def _embedding(k: int) -> tuple[np.ndarray, np.ndarray]:
    """(E, R): map coordinates -> state perturbation (x3 = 0), and state -> map coordinates."""
    E = np.zeros((N_STATE, k))
    E[0, 0] = 1.0
    E[1, 1] = 1.0
    R = np.zeros((k, N_STATE))
    R[0, 0], R[0, 2] = 1.0, -1.0
    R[1, 1] = 1.0
    if k == 3:
        E[3, 2] = 1.0
        R[2, 3] = 1.0
    return E, R


def period_map(groups: Groups, s, n: int, *, jacobian: bool = True,
               solver: SolverOptions = ORBIT_SOLVER) -> MapResult:
    """Integrate ``n`` forcing periods from the relative state ``s`` at phase 0.

    Parameters
    ----------
    groups : Groups
    s : array_like, shape (2,) or (3,)
        (x1 - x3, x2) with the bit stuck, or (x1 - x3, x2, x4) with x4 > 0.
    n : int
        Forcing periods.
    jacobian : bool
        Also integrate the variational equations (the monodromy matrix).

    Raises
    ------
    ContinuationError
        The Stepper or the variational integration could not go on.
    """
    y0 = full_state(s)
    k = len(s)
    try:
        st = Stepper(groups, solver=solver, y0=y0, compile_helper=False)
    except ValueError as e:
        raise ContinuationError(f"not a state of the model: {e}") from None
    modes0 = np.array([st.istate[KL.I_STICK], st.istate[KL.I_CONTACT]], dtype=np.int64)
    if (k == 2) != (modes0[0] == KL.STICK):
        raise ContinuationError("a stuck state has 2 map coordinates, a slipping one 3")
    t_end = n * groups.period
    log = np.zeros((LOG_ROWS, KL.N_LOG_COLS))
    try:
        while st.advance(t_end, log=log) == "log_full":
            log = np.concatenate([log, np.zeros_like(log)])
    except SolverError as e:
        raise ContinuationError(f"integration failed: {e}") from None
    n_ev = int(st.istate[KL.I_NLOG])
    y_end = st.y[:N_STATE].copy()
    stuck_end = bool(st.istate[KL.I_STICK] == KL.STICK)
    jac = None
    if jacobian:
        w = np.zeros(N_AUG)
        work = segment_work(VARIATIONAL_RTOL, VARIATIONAL_ATOL, 1e-3 * groups.period)
        status = sensitivity_along(log, n_ev, y0, t_end, st.p, modes0, work, w)
        if status != SEG_OK:
            raise ContinuationError(f"the variational equations could not be integrated (status {status})")
        phi = w[N_STATE:].reshape(N_STATE, N_STATE)
        E, R = _embedding(k)
        jac = R @ phi @ E
    s_end = relative_state(y_end, k == 2)
    return MapResult(y_end=y_end, s_end=s_end, jacobian=jac, stuck_end=stuck_end, events=log[:n_ev].copy())
