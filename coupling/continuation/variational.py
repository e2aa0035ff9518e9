"""The variational equations of the hammer–bit–rock model in one hybrid mode, integrated over a smooth segment (numba kernels).

Between two events the mode (stick/slip, contact) is fixed and the flow is
smooth, so the sensitivity ``Phi = d y(t) / d y(t0)`` obeys ``Phi' = J(t, y) Phi``
with ``J`` the Jacobian of the library's vector field
(:func:`hammerbit.model.kernel_forces.rhs_forced`).  The state and ``Phi``
are integrated together by the library's DOP853 tableau with Hairer's error
estimate over all 20 components; the events themselves (where a segment ends)
come from the library's :class:`~hammerbit.model.stepping.Stepper`, which
locates them to a few ulp.  The jumps at the events are the saltation
matrices of :mod:`.monodromy`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.kernel_forces import (contact_damping, contact_stiffness, harmonic, kinetic_friction, overlap,
                                           rhs_forced)
from hammerbit.model.tableaux import METHODS

from . import kernel_cache  # noqa: F401  (registers the cache locator before the kernels are decorated)

__all__ = ["N_STATE", "N_AUG", "NO_SUBSYSTEM", "DOP853", "jacobian", "integrate_segment", "segment_work",
           "SEG_OK", "SEG_MAX_STEPS", "SEG_NONFINITE", "SEG_STEP_TOO_SMALL"]

#: the hammer and the bit: x1, x2, x3, x4
N_STATE = 4
#: the state and its 4 x 4 sensitivity, row-major
N_AUG = N_STATE + N_STATE * N_STATE
#: the vector field's "no linear subsystem, no energy block" (the layout of ``sub`` in kernel_layouts)
NO_SUBSYSTEM = (0, 0, np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 2)),
                np.zeros(0), np.zeros(2))
#: the library's DOP853 tableau: A, B, C, E, E3, W, stages, error kind, controller exponent
DOP853 = METHODS["dop853"]

# The kernels are cached on disk by :mod:`.kernel_cache`, keyed on this file, monodromy.py and the model's
# kernels they call (numba's own key, this file alone, would keep stale copies of the vector field).

SEG_OK = 0
SEG_MAX_STEPS = 1
SEG_NONFINITE = 2
SEG_STEP_TOO_SMALL = 3

#: accepted steps in one segment before the integration gives up (a segment is a fraction of a period)
MAX_SEGMENT_STEPS = 200_000


@njit(cache=True, _nrt=False)
def jacobian(y, p, mode_s, mode_c, jac):
    """Jacobian d f / d y of the vector field in one mode at ``y``, into ``jac`` (4 x 4).

    Stuck (``mode_s`` STICK), the bit rows are zero: x3 and x4 do not move.
    The contact force's derivatives are the law's own (``contact_stiffness``,
    ``contact_damping`` in :mod:`hammerbit.model.kernel_forces`).
    """
    for i in range(N_STATE):
        for j in range(N_STATE):
            jac[i, j] = 0.0
    xi2 = 2.0 * p[KL.P_XI]
    # the spring-damper force and the contact force, d/d(x1, x2, x3, x4)
    dk_dd = 1.0
    dk_dr = xi2
    if mode_c == KL.CONTACT:
        d = overlap(y, p)
        if abs(d) > 0.0:
            dk_dd += contact_stiffness(d, y[KL.V_HAMMER] - y[KL.V_BIT], p)
            dk_dr += contact_damping(d, p)
    jac[0, 1] = 1.0
    jac[1, 0] = -dk_dd
    jac[1, 1] = -dk_dr
    jac[1, 2] = dk_dd
    jac[1, 3] = dk_dr
    if mode_s == KL.SLIP:
        gv = p[KL.P_GAMMA] * y[KL.V_BIT]
        # the derivative of kinetic_friction, on both sides of its Taylor continuation
        if gv >= KL.FRICTION_TAYLOR_FROM:
            de = -math.exp(-gv)
        else:
            de = KL.EXP_FRICTION_TAYLOR * (-1.0 + (gv - KL.FRICTION_TAYLOR_FROM))
        dff = (1.0 - p[KL.P_MU]) * de * p[KL.P_GAMMA]
        inv_rho = 1.0 / p[KL.P_RHO]
        jac[2, 3] = 1.0
        jac[3, 0] = dk_dd * inv_rho
        jac[3, 1] = dk_dr * inv_rho
        jac[3, 2] = -dk_dd * inv_rho
        jac[3, 3] = (-dk_dr - dff) * inv_rho


@njit(cache=True, _nrt=False)
def augmented_rhs(t, w, field, jac, out):
    """d/dt of (y, Phi): the vector field and ``J Phi``; ``field = (p, mode_s, mode_c, sub)``."""
    p, mode_s, mode_c = field[0], field[1], field[2]
    rhs_forced(harmonic(t, p), w[:N_STATE], field, out[:N_STATE])
    jacobian(w[:N_STATE], p, mode_s, mode_c, jac)
    for i in range(N_STATE):
        for j in range(N_STATE):
            acc = 0.0
            for k in range(N_STATE):
                acc += jac[i, k] * w[N_STATE + k * N_STATE + j]
            out[N_STATE + i * N_STATE + j] = acc


@njit(cache=True, _nrt=False)
def dop853_trial(t, w, h, field, work, method):
    """One DOP853 trial step of (y, Phi) from ``w``: the new value in ``work[2]``, its error norm returned."""
    stages, wtmp, wnew, jac, tols = work
    rk_a, rk_b, rk_c, err_w, err_w3, ns = method[0], method[1], method[2], method[3], method[4], method[6]
    rtol, atol = tols[0], tols[1]
    m = w.shape[0]
    for s in range(1, ns):
        for i in range(m):
            acc = 0.0
            for j in range(s):
                acc += rk_a[s, j] * stages[j, i]
            wtmp[i] = w[i] + h * acc
        augmented_rhs(t + rk_c[s] * h, wtmp, field, jac, stages[s])
    for i in range(m):
        acc = 0.0
        for j in range(ns):
            acc += rk_b[j] * stages[j, i]
        wnew[i] = w[i] + h * acc
    augmented_rhs(t + h, wnew, field, jac, stages[ns])
    e5 = 0.0
    e3 = 0.0
    for i in range(m):
        sc = atol + rtol * max(abs(w[i]), abs(wnew[i]))
        a5 = 0.0
        a3 = 0.0
        for j in range(ns + 1):
            a5 += err_w[j] * stages[j, i]
            a3 += err_w3[j] * stages[j, i]
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    r = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * m)
    return r if math.isfinite(r) else math.inf


@njit(cache=True, _nrt=False)
def integrate_segment(t0, t1, w, field, work, method):
    """Integrate (y, Phi) in ``w`` (in place) from ``t0`` to exactly ``t1`` in one mode.

    ``work = (stages, wtmp, wnew, jac, tols)`` (:func:`segment_work`), ``tols =
    [rtol, atol, h0]``; ``method`` the library's DOP853 tableau.  Returns a
    ``SEG_*`` status and leaves the proposed next step in ``tols[2]``.
    """
    stages, wtmp, wnew, jac, tols = work
    m = w.shape[0]
    t = t0
    h = min(tols[2], t1 - t0)
    steps = 0
    augmented_rhs(t, w, field, jac, stages[0])
    while t < t1:
        last = t + h >= t1
        if last:
            h = t1 - t
        if h <= KL.TIME_RESOLUTION * max(abs(t), 1.0) and not last:
            return SEG_STEP_TOO_SMALL
        err = dop853_trial(t, w, h, field, work, method)
        if err <= 1.0:
            t = t1 if last else t + h
            for i in range(m):
                w[i] = wnew[i]
                stages[0, i] = stages[method[6], i]
            steps += 1
            if steps > MAX_SEGMENT_STEPS:
                return SEG_MAX_STEPS
            fac = KL.MAX_FACTOR if err == 0.0 else min(KL.MAX_FACTOR, KL.SAFETY * err ** (-method[8]))
            if not last:
                tols[2] = h * fac
            h = h * fac
        else:
            if not math.isfinite(err):
                h *= KL.MIN_FACTOR
            else:
                h *= max(KL.MIN_FACTOR, KL.SAFETY * err ** (-method[8]))
    for i in range(m):
        if not math.isfinite(w[i]):
            return SEG_NONFINITE
    return SEG_OK


def segment_work(rtol: float, atol: float, h0: float):
    """Preallocated work arrays of :func:`integrate_segment` for the DOP853 tableau."""
    n_ext = DOP853[0].shape[0]
    return (np.zeros((n_ext, N_AUG)), np.zeros(N_AUG), np.zeros(N_AUG), np.zeros((N_STATE, N_STATE)),
            np.array([rtol, atol, h0]))
