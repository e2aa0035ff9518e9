"""Recording of what a scene asked for: samples at requested times and Poincaré sections (numba kernels)."""

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import contact_force, link_force, overlap, relative_velocity
from .kernel_layouts import (EPS, I_CONTACT, I_POIN_NEXT, I_SAMP_NEXT, I_STICK, O_POIN_DT, O_POIN_T0, V_BIT,
                             V_HAMMER, X_BIT, X_HAMMER)
from .kernel_localise import state_at

@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def write_sample(row, y, p, istate, nz, sub_out, link_x):
    """One sample row: x1..x4, contact force, link force, stick/slip, contact mode."""
    row[0] = y[X_HAMMER]
    row[1] = y[V_HAMMER]
    row[2] = y[X_BIT]
    row[3] = y[V_BIT]
    d = overlap(y, p)
    # the physical force: zero out of contact and never tensile
    row[4] = max(contact_force(d, relative_velocity(y), p, istate[I_CONTACT]), 0.0) if d > 0.0 else 0.0
    row[5] = link_force(y, nz, sub_out, link_x) if nz > 0 else 0.0
    row[6] = istate[I_STICK]
    row[7] = istate[I_CONTACT]


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def record_until(t_stop, y_stop, step, tableau, field, scratch, istate, opts, rec):
    """Record Poincaré samples and requested samples with times in (t0, t_stop] of ``step``.

    ``field`` holds the modes of ``istate``; ``scratch = (stages2, ytmp, ys, _)``;
    ``rec = (poin, samp_t, samp, log)`` (the log is not written here); the groups:
    :mod:`.kernel_layouts`.
    """
    tol = 8.0 * EPS * max(abs(t_stop), 1.0)
    t0 = step[0]
    p, sub = field[0], field[3]
    nz, sub_out, link_x = sub[0], sub[6], sub[7]
    stages2, ytmp, ys, _ = scratch
    poin, samp_t, samp, _ = rec
    npoin = poin.shape[0]
    k = istate[I_POIN_NEXT]
    while k < npoin:
        tk = opts[O_POIN_T0] + k * opts[O_POIN_DT]
        if tk > t_stop + tol:
            break
        if tk >= t_stop:
            for i in range(ys.shape[0]):
                ys[i] = y_stop[i]
        else:
            state_at(tk, step, tableau, field, stages2, ytmp, ys)
        poin[k, 0] = tk
        poin[k, 1] = ys[X_HAMMER]
        poin[k, 2] = ys[V_HAMMER]
        # the drift only moves forward: a sample from the dense output (exact within the
        # tolerance) never reads below the previous one where the bit barely moves
        poin[k, 3] = max(ys[X_BIT], poin[k - 1, 3]) if k > 0 else ys[X_BIT]
        poin[k, 4] = ys[V_BIT]
        k += 1
    istate[I_POIN_NEXT] = k
    j = istate[I_SAMP_NEXT]
    nsamp = samp_t.shape[0]
    while j < nsamp:
        tj = samp_t[j]
        if tj > t_stop + tol:
            break
        if tj >= t_stop:
            for i in range(ys.shape[0]):
                ys[i] = y_stop[i]
        else:
            state_at(max(tj, t0), step, tableau, field, stages2, ytmp, ys)
        if j > 0 and ys[X_BIT] < samp[j - 1, 2]:
            ys[X_BIT] = samp[j - 1, 2]  # monotone drift, as for the Poincaré samples
        write_sample(samp[j], ys, p, istate, nz, sub_out, link_x)
        j += 1
    istate[I_SAMP_NEXT] = j


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def needs_record(t_stop, istate, opts, poin, samp_t):
    """True if a Poincaré or requested sample falls in the step ending at t_stop."""
    tol = 8.0 * EPS * max(abs(t_stop), 1.0)
    k = istate[I_POIN_NEXT]
    if k < poin.shape[0] and opts[O_POIN_T0] + k * opts[O_POIN_DT] <= t_stop + tol:
        return True
    j = istate[I_SAMP_NEXT]
    if j < samp_t.shape[0] and samp_t[j] <= t_stop + tol:
        return True
    return False
