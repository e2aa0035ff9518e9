"""The driver of the hybrid integration, ``advance``, and its compiled entry points (numba kernels).

``advance`` is a loop over pieces with one job each, every one in a module
named for it: propose and try a Runge–Kutta step (:mod:`.kernel_step_trial`),
control its size (:mod:`.kernel_step_control`), find the step's first event
(:mod:`.kernel_event_search`, located by :mod:`.kernel_localise`), take the
step or move to its event and record (:mod:`.kernel_step_accept`,
:mod:`.kernel_recording`), the closed-form stick chunk
(:mod:`.kernel_stick_step`), and the transition at an event
(:mod:`.kernel_transition`, the reset map :mod:`.kernel_reset`).  All solver
state lives in plain arrays (layouts: :mod:`.kernel_layouts`), so a call that
returns early resumes where it stopped.

The entry points (``advance``, and ``advance_hammer``, ``advance_dp54`` and
``advance_rk4`` for a system of the hammer and the bit alone) allocate the work
arrays and run the loop, :func:`march`.  The pieces are compiled with
``inline='always'``: numba copies their code into ``march`` before typing it,
so the constants that :func:`.numba_partial.bind` gives the copies
``march_hammer``, ``march_dp54`` and ``march_rk4`` (the method, the empty
subsystem) reach into every piece, and the per-step state
(time, step size, drive tracker) stays in registers, as in one function.
``march`` runs without numba's reference counting (``_nrt=False``: it
allocates nothing), so the groups of arrays the pieces unpack cost nothing.
The kernels the pieces call (``rk_step``, ``locate_event``, ...) are ordinary
compiled functions, and so is the piece that runs once per event,
``step_to_event``: its code stays out of the loop every step runs through.

Besides the groups of :mod:`.kernel_layouts` (``method``, ``tableau``,
``sub``, ``field``, ``step``, ``rec``), the pieces share these, built once per
call (nothing is allocated inside the loop)::

    rk    = (tableau, method)
    sol   = (y, istate, fstate, opts)          the solver state and options
    work  = (stages, stages2, interp, ynew, ytmp, ys, fs, act)
        the stages of a step and of a re-step, the dense or stick-solution
        coefficients, four state-sized work vectors, the integrated indices
    watch = (kinds, w0s, w1s, s1s, wtols)
        the watched indicators: kinds, values at the step start and end, slopes
        at the end (NaN: not computed) and tolerances
    kit   = (fixed, how_rk, how_stick, how_dense, no_act, graze_stick, bisect,
             graze, period, stepcap)
        the method's kind (fixed step or not), the step kinds (``HOW_*``) and
        flags as plain integers (see ``plain``), the localisation options, the
        forcing period and the step cap per period
    ctl   = (rtol, atol, hmax, e_abs, err_exp)    the step-size control
    cf    = (chunk, chunk constants)              the closed-form stick chunk
    ctx   = (rk, sol, work, watch, kit, ctl, cf, rec)
    drive = (d_min, d_y, r_y, carried)
        the lowest drive on the bit so far, the drive at ``y`` and its rate along
        ``stages[0]``, and whether these and the indicators' values carry from
        the end of the last accepted step (an event starts afresh)
"""

import math

import numpy as np
from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from . import tableaux as _T
from .numba_partial import bind
from .kernel_event_search import open_watch, rk_step_events
from .kernel_forces import force_on_bit, rhs
from .kernel_layouts import (F_DRIVE_MIN, F_H, F_T, FREE, HOW_DENSE, HOW_RESTEP, HOW_STICK, I_CONTACT, I_NLOG,
                             I_RHS, I_STEPS, I_STICK, O_ATOL, O_BISECT, O_EVCAP, O_GRAZE, O_HFIXED, O_HMAX,
                             O_MAXSTEPS, O_RTOL, O_STEPCAP, P_ETA, P_XI, ST_BAD_INPUT, ST_DONE, ST_LOG_FULL,
                             ST_MAX_STEPS, ST_NONFINITE, ST_STEP_STORM, STICK, STICK_CHUNKS_PER_PERIOD,
                             TIME_RESOLUTION, TINY, V_BIT)
from .kernel_localise import plain
from .kernel_step_accept import accept_step, record_at_end, step_to_event
from .kernel_step_control import count_step, next_step_size
from .kernel_step_trial import adaptive_step, fixed_step
from .kernel_stick import stick_chunk_consts, stick_closed_form_ok
from .kernel_stick_step import stick_advance
from .kernel_transition import set_active, transition


@njit(inline="always")
def constants(p, opts, method, sub, n, chunk_c):
    """The constants of one call: ``kit`` (the method's kind, the step kinds and the
    localisation options), ``ctl`` (the step-size control) and ``cf`` (the stick chunk)."""
    _, _, _, err_w, _, dense_w, ns, err_kind, err_exp = method
    fixed = err_kind == 0
    # evaluation kinds and flags as plain integers, so each callee is compiled once (see ``plain``)
    kit = (fixed, plain(HOW_RESTEP if fixed else HOW_DENSE, n), plain(HOW_STICK, n), plain(HOW_DENSE, n),
           plain(0, n), plain(1, n) > 0, opts[O_BISECT], opts[O_GRAZE], 2.0 * math.pi / p[P_ETA], opts[O_STEPCAP])
    e_abs = 0.0
    for j in range(ns + 1):
        e_abs += abs(err_w[j])
    ctl = (opts[O_RTOL], opts[O_ATOL], opts[O_HMAX], e_abs, err_exp)
    # exact stick stepping (adaptive methods, hammer-only systems): see stick_prepare
    cf_ok = (not fixed) and sub[0] == 0 and sub[1] == 0 and dense_w.shape[0] >= 3 and stick_closed_form_ok(p)
    cf_chunk = min(2.0 * math.pi / p[P_ETA],
                   2.0 * math.pi / math.sqrt(max(1.0 - p[P_XI] * p[P_XI], TINY))) / STICK_CHUNKS_PER_PERIOD
    cf_chunk = min(cf_chunk, opts[O_HMAX])
    if cf_ok:
        stick_chunk_consts(cf_chunk, p, chunk_c)
    return kit, ctl, cf_ok, (cf_chunk, chunk_c)


@njit(inline="always")
def scratch(method, n):
    """The arrays of one call (allocated by the entry point, before the loop):
    ``(work, watch, the stick chunk's constants)``."""
    n_ext = method[0].shape[0]
    work = (np.empty((n_ext, n)), np.empty((n_ext, n)), np.empty((method[5].shape[0], n)), np.empty(n),
            np.empty(n), np.empty(n), np.empty(n), np.empty(n, dtype=np.int64))
    # indicator kinds, values at the step start and end, slopes at the end (NaN: not computed), tolerances
    watch = (np.empty(4, dtype=np.int64), np.empty(4), np.empty(4), np.empty(4), np.empty(4))
    return work, watch, np.empty(6)


@njit(inline="always")
def budget_left(istate, log_cap, maxsteps, steps_here):
    """ST_LOG_FULL or ST_MAX_STEPS when this call must return before its next step, else ST_DONE."""
    if log_cap > 0 and istate[I_NLOG] >= log_cap:
        return ST_LOG_FULL
    if maxsteps > 0 and steps_here >= maxsteps:
        return ST_MAX_STEPS
    return ST_DONE


@njit(inline="always")
def halt(fstate, t, h, d_min, status):
    """Store where the call stopped and return ``status``: a non-finite state keeps the step
    size of the last call (``fstate[F_H]``), the proposal that led there being worthless."""
    fstate[F_T] = t
    fstate[F_DRIVE_MIN] = d_min
    if status != ST_NONFINITE:
        fstate[F_H] = h
    return status


@njit(inline="always")
def rk_advance(t, h, t_end, refine, drive, nw, n_act, field, ctx):
    """One step of the Runge–Kutta method from ``t``, up to its first event.

    Returns ``(status, event kind or -1, the new time, the step size, drive, refine)``:
    the kind is -1 when the step was taken whole, or when it moved towards an
    event that a re-step has not confirmed yet.
    """
    rk, sol, work, _, kit, ctl, _, _ = ctx
    y, istate, fstate, opts = sol
    fixed, period, stepcap = kit[0], kit[8], kit[9]
    p, ms, mc, _ = field
    remaining = t_end - t
    h_next = h
    if fixed:
        h = min(opts[O_HFIXED], remaining)
        if not fixed_step(t, h, n_act, field, rk[0], sol, work):
            return ST_NONFINITE, -1, t, h, drive, refine
    else:
        status, h, err, rejected = adaptive_step(t, h, remaining, n_act, field, rk, sol, work, ctl)
        if status != ST_DONE:
            return status, -1, t, h, drive, refine
        stages, ynew = work[0], work[3]
        h_next = next_step_size(h, err, rejected, (ms, mc), (ynew[V_BIT], stages[rk[0][3], V_BIT]), p, fstate,
                                rk[1], ctl, n_act)
    istate[I_STEPS] += 1
    t1 = t + h
    if h >= remaining:
        t1 = t_end
    if count_step(t1, period, istate, stepcap):
        return ST_STEP_STORM, -1, t, h, drive, refine
    span = (t, t1, h)
    hit_kind, t_hit, wtol_hit, dense_ok, f_contact1, d1, r1 = rk_step_events(span, nw, n_act, field, ctx)
    if not fixed:
        h = h_next
    if hit_kind < 0:
        drive = accept_step(span, (f_contact1, d1, r1), dense_ok, drive, n_act, field, ctx)
        return ST_DONE, -1, t1, h, drive, refine
    confirmed, refine, drive = step_to_event(span, (hit_kind, t_hit, wtol_hit), dense_ok, refine, drive, n_act,
                                             field, ctx)
    return ST_DONE, hit_kind if confirmed else -1, t_hit, h, drive, refine

@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def march(y, istate, fstate, t_end, p, opts, method, sub, rec, buffers):
    """The loop of :func:`advance` over its pieces (``buffers``: :func:`scratch`).

    Compiled without numba's reference counting (``_nrt=False``): the groups of
    arrays the inlined pieces unpack at every step would otherwise cost a count
    per array and piece, several times a step's own work.
    """
    t, h = fstate[F_T], fstate[F_H]
    if not (math.isfinite(t_end) and math.isfinite(t) and t <= t_end):
        return ST_BAD_INPUT
    n = y.shape[0]
    for i in range(n):
        if not math.isfinite(y[i]):
            return ST_NONFINITE
    work, watch, chunk_c = buffers
    kit, ctl, cf_ok, cf = constants(p, opts, method, sub, n, chunk_c)
    ctx = ((method[0], method[1], method[2], method[6]), method), (y, istate, fstate, opts), work, watch, kit, \
        ctl, cf, rec
    n_act = set_active(istate, n, work[7])
    ms, mc = istate[I_STICK], istate[I_CONTACT]
    field = (p, ms, mc, sub)
    # the drive tracker and the watched indicators carry from the end of an accepted step to the
    # start of the next (recomputing them cost a tenth of the solver's time); an event starts afresh
    d_y = force_on_bit(y, p, mc)
    drive = (d_y if d_y < fstate[F_DRIVE_MIN] else fstate[F_DRIVE_MIN], d_y, 0.0, False)
    rhs(t, y, field, work[0][0])
    istate[I_RHS] += 1
    steps_here, refine = 0, 0
    log_cap, maxsteps, evcap = rec[3].shape[0], int(opts[O_MAXSTEPS]), opts[O_EVCAP]
    phase = (math.nan, 0.0, 0.0)  # the time and forcing phase a full stick chunk left behind
    while True:
        if t_end - t <= TIME_RESOLUTION * max(abs(t_end), 1.0):
            break  # a sliver below the time resolution is no dynamics: done
        status = budget_left(istate, log_cap, maxsteps, steps_here)
        if status != ST_DONE:
            return halt(fstate, t, h, drive[0], status)
        nw, hit_kind = open_watch(istate, y, p, mc, drive[3], watch)
        if hit_kind < 0:
            steps_here += 1
            if cf_ok and ms == STICK and mc == FREE:
                status, hit_kind, t, drive, phase = stick_advance(t, t_end, phase, drive, nw, n_act, field, ctx)
            else:
                status, hit_kind, t, h, drive, refine = rk_advance(t, h, t_end, refine, drive, nw, n_act, field,
                                                                   ctx)
            if status != ST_DONE:
                return halt(fstate, t, h, drive[0], status)
            if hit_kind < 0:
                continue
        status, h, d_min, d_y = transition(hit_kind, t, h, drive[0], field, ctx[1], kit, rec[3], evcap)
        if status != ST_DONE:
            return halt(fstate, t, h, d_min, status)
        drive = (d_min, d_y, drive[2], False)
        ms, mc = istate[I_STICK], istate[I_CONTACT]
        field = (p, ms, mc, sub)
        n_act = set_active(istate, n, work[7])
        rhs(t, y, field, work[0][0])
        istate[I_RHS] += 1
    halt(fstate, t_end, h, drive[0], ST_DONE)
    record_at_end(t_end, field, ctx)  # samples that sit exactly on t_end
    return ST_DONE


# Entry points, each compiled on its first call (or loaded from the cache): they
# allocate the work arrays and run the loop ``march``.  A system of the hammer and
# the bit alone (no linear subsystem, no energy block: a plain ``simulate``, the FMU,
# the sweeps) runs a copy of the loop with its method's tableau and the empty
# subsystem bound as constants (``numba_partial.bind``), so they fold into the loop
# and into every piece inlined there, without numba re-typing a copy of the driver:
# ``advance_hammer`` (DOP853), ``advance_dp54`` and ``advance_rk4``.  With the
# method given as an argument, RK4's fixed-step loop measured a quarter slower.
# ``advance`` serves every other combination (the linear subsystem, the energy
# block, the monolithic reference).

#: the empty linear subsystem and no energy block: the ``sub`` group of a hammer-only system
NO_SUB = (0, 0, np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 2)),
          np.zeros(0), np.zeros(2))
#: the methods of the hammer-only entry points
DOP853, DP54, RK4 = _T.METHODS["dop853"], _T.METHODS["dp54"], _T.METHODS["rk4"]
#: the entry point of a hammer-only system, by ``SolverOptions.method``
HAMMER_ENTRY = {"adaptive": "advance_hammer", "dp54": "advance_dp54", "rk4": "advance_rk4"}
#: the loop each entry point runs
ENTRY_LOOP = {"advance_hammer": "march_hammer", "advance_dp54": "march_dp54", "advance_rk4": "march_rk4",
              "advance": "march"}

#: ``march`` with a method, no linear subsystem and no energy block, all bound as constants
march_hammer = njit(cache=True, _nrt=False, no_cpython_wrapper=True)(bind(
    march, "march_hammer", method=DOP853, sub=NO_SUB))
march_dp54 = njit(cache=True, _nrt=False, no_cpython_wrapper=True)(bind(
    march, "march_dp54", method=DP54, sub=NO_SUB))
march_rk4 = njit(cache=True, _nrt=False, no_cpython_wrapper=True)(bind(
    march, "march_rk4", method=RK4, sub=NO_SUB))


@njit(cache=True, nogil=True)
def advance(y, istate, fstate, t_end, p, opts, method, sub, rec):
    """Advance the hybrid system from ``fstate[F_T]`` to ``t_end``; returns an ``ST_*`` code.

    Resumable: all solver state lives in ``y`` (shape (Z0 + nz + ne,), advanced
    in place), ``istate`` (int64, modes, counters and record cursors ``I_*``) and
    ``fstate`` (time, proposed step, contact bookkeeping ``F_*``), so a call that
    returns early (event log full, step cap) continues where it stopped, and an
    FMU saves and restores it as plain numbers.  ``p``: the kernel parameters
    (``P_*``), ``opts``: the solver options (``O_*``), ``method``: the
    Runge–Kutta method ``(rk_a, rk_b, rk_c, err_w, err_w3, dense_w, ns,
    err_kind, err_exp)`` (``tableaux.METHODS``), ``sub``: the linear subsystem
    and energy block ``(nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)`` (nz may be
    0; ne is 4 to accumulate energies, else 0), ``rec``: the record buffers
    ``(poin, samp_t, samp, log)`` (:mod:`.kernel_recording`; a log of 0 rows
    disables it).  The groups the pieces share: the module's docstring.
    """
    return march(y, istate, fstate, t_end, p, opts, method, sub, rec, scratch(method, y.shape[0]))


@njit(cache=True, nogil=True)
def advance_hammer(y, istate, fstate, t_end, p, opts, rec):
    """:func:`advance` with DOP853, no linear subsystem and no energy block (``march_hammer``)."""
    return march_hammer(y, istate, fstate, t_end, p, opts, rec, scratch(DOP853, y.shape[0]))


@njit(cache=True, nogil=True)
def advance_dp54(y, istate, fstate, t_end, p, opts, rec):
    """:func:`advance` with DP54, no linear subsystem and no energy block (``march_dp54``)."""
    return march_dp54(y, istate, fstate, t_end, p, opts, rec, scratch(DP54, y.shape[0]))


@njit(cache=True, nogil=True)
def advance_rk4(y, istate, fstate, t_end, p, opts, rec):
    """:func:`advance` with RK4, no linear subsystem and no energy block (``march_rk4``)."""
    return march_rk4(y, istate, fstate, t_end, p, opts, rec, scratch(RK4, y.shape[0]))
