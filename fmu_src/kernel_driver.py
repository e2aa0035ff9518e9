"""The driver of the hybrid integration, ``advance``, and its compiled entry points (numba kernels).

``advance`` ties the pieces together: Runge–Kutta steps
(:mod:`.kernel_runge_kutta`) or the closed-form stick solution
(:mod:`.kernel_stick`), event detection and localisation
(:mod:`.kernel_localise`), the reset map (:mod:`.kernel_reset`) and the
recording (:mod:`.kernel_recording`).  All solver state lives in plain arrays
(layouts: :mod:`.kernel_layouts`), so a call that returns early resumes where it
stopped.
"""

import math

import numpy as np
from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from . import tableaux as _T
from .numba_partial import bind
from .kernel_events import drive_rate, watch_tol, watch_value, watch_value_drive, watched
from .kernel_forces import contact_force_at, force_on_bit, overlap, rhs, spring_damper_force
from .kernel_layouts import (CHUNK_SLIVER, CONTACT, CONTACT_STABILITY_LIMIT, EPS, ERRACC_FLOOR, EV_SEPARATION,
                             EV_STICK, F_DRIVE_MIN, F_ERRACC, F_H, F_H_MODE, F_HACC, F_PEAK, F_T, F_T_STICK,
                             F_V4_PEAK, FREE, HOW_DENSE, HOW_RESTEP, HOW_STICK, I_CONTACT, I_NLOG, I_REJECTS,
                             I_RHS, I_STEPS, I_STICK, I_SWIN, I_SWIN_STEPS, I_WIN, I_WIN_EVENTS, L_KIND,
                             L_PEAK, L_T, L_VREL, L_X1, L_X2, L_X3, L_X4, LAYER_TARGET, MAX_FACTOR,
                             MIN_FACTOR, O_ATOL, O_BISECT, O_EVCAP, O_GRAZE, O_HFIXED, O_HMAX, O_MAXSTEPS,
                             O_RTOL, O_STEPCAP, P_ETA, P_KC, P_LAM, P_MU, P_N, P_RHO, P_XI, SAFETY, SLIP,
                             SLIVER_FLOORS, ST_BAD_INPUT, ST_DONE, ST_EVENT_STORM, ST_LOG_FULL, ST_MAX_STEPS,
                             ST_NONFINITE, ST_STEP_STORM, ST_STEP_TOO_SMALL, STICK, STICK_CHUNKS_PER_PERIOD,
                             STOP_OVERSHOOT, STOP_SHRINK_FLOOR, TIME_RESOLUTION, TINY, V_BIT, V_HAMMER, X_BIT,
                             X_HAMMER)
from .kernel_localise import (drive_dips, drive_inside, locate_event, peak_in_step, plain, sign_change,
                              state_at)
from .kernel_recording import needs_record, record_until
from .kernel_reset import apply_event
from .kernel_runge_kutta import dense_eval, error_norm, friction_layer_err, interpolant, rk_step
from .kernel_stick import (stick_chunk_consts, stick_closed_form_ok, stick_prepare, stick_prepare_phase,
                           stick_rate, stick_state, stick_state_chunk)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def err_root(x, e):
    """x ** e for the controller; DOP853's e = 1/8 as three square roots (cheaper than pow)."""
    if e == 0.125:
        return math.sqrt(math.sqrt(math.sqrt(x)))
    return x ** e


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def count_step(t1, period, istate, cap):
    """Count an accepted step in its forcing period; True when the cap is exceeded."""
    w = int(math.floor(t1 / period))
    if w != istate[I_SWIN]:
        istate[I_SWIN] = w
        istate[I_SWIN_STEPS] = 0
    istate[I_SWIN_STEPS] += 1
    return cap > 0.0 and istate[I_SWIN_STEPS] > cap


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def step_slot(ms, mc):
    """Regime whose last step size is remembered: 0 stick, 1 slip, 2 contact."""
    if mc != FREE:
        return 2
    return ms


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def set_active(istate, n, act):
    """Indices of the integrated components: m2 is not integrated while it sticks."""
    k = 0
    for i in range(n):
        if istate[I_STICK] == STICK and (i == 2 or i == 3):
            continue
        act[k] = i
        k += 1
    return k


@njit(cache=True, nogil=True)
def advance(y, istate, fstate, t_end, p, opts, method, sub, rec):
    """Advance the hybrid system from ``fstate[F_T]`` to ``t_end``.

    Resumable: all solver state lives in ``y``, ``istate`` and ``fstate``, so a
    call that returns early (event log full, step cap) continues where it
    stopped, and an FMU saves and restores it as plain numbers.

    Parameters
    ----------
    y : ndarray, shape (Z0 + nz + ne,)
        State, advanced in place.
    istate : ndarray of int64, shape (N_ISTATE,)
        Modes, counters and record cursors (``I_*``).
    fstate : ndarray, shape (N_FSTATE,)
        Time, proposed step and contact bookkeeping (``F_*``).
    t_end : float
        Final time tau.
    p : ndarray, shape (N_P,)
        Kernel parameters.
    opts : ndarray, shape (N_OPTS,)
        Solver options (``O_*``).
    method : tuple
        The Runge–Kutta method ``(rk_a, rk_b, rk_c, err_w, err_w3, dense_w, ns,
        err_kind, err_exp)`` (``tableaux.METHODS``; :mod:`.kernel_layouts` lists the groups).
    sub : tuple
        The linear subsystem and the energy block ``(nz, ne, Ap, Ai, Ax, sub_in,
        sub_out, link_x)``; nz = sub_in.shape[0] may be 0, ne is 4 to accumulate
        energies, else 0.
    rec : tuple
        The record buffers ``(poin, samp_t, samp, log)``: Poincaré samples
        [tau, x1, x2, x3, x4] at O_POIN_T0 + k O_POIN_DT, shape (n_poin, 5);
        requested sample times, sorted, shape (n_samp,), and their samples
        (written), shape (n_samp, N_SAMPLE_COLS); the event log (written while rows
        remain; cap 0 disables it), shape (cap, N_LOG_COLS).

    Returns
    -------
    status : int
        ``ST_*`` code.
    """
    rk_a, rk_b, rk_c, err_w, err_w3, dense_w, ns, err_kind, err_exp = method
    tableau = (rk_a, rk_b, rk_c, ns)  # what a step needs (fewer arguments to the calls per step)
    nz, ne = sub[0], sub[1]
    poin, samp_t, _, log = rec
    n = y.shape[0]
    n_ext = rk_a.shape[0]
    fixed = err_kind == 0
    how_rk = plain(HOW_RESTEP if fixed else HOW_DENSE, n)
    # evaluation kinds and flags as plain integers, so each callee is compiled once (see ``plain``)
    how_stick = plain(HOW_STICK, n)
    how_dense = plain(HOW_DENSE, n)
    no_act = plain(0, n)
    graze_stick = plain(1, n) > 0
    # exact stick stepping (adaptive methods, hammer-only systems): see stick_prepare
    cf_ok = (not fixed) and nz == 0 and ne == 0 and dense_w.shape[0] >= 3 and stick_closed_form_ok(p)
    cf_chunk = min(2.0 * math.pi / p[P_ETA],
                   2.0 * math.pi / math.sqrt(max(1.0 - p[P_XI] * p[P_XI], TINY))) / STICK_CHUNKS_PER_PERIOD
    cf_chunk = min(cf_chunk, opts[O_HMAX])
    chunk_c = np.empty(6)
    e_abs = 0.0
    for j in range(ns + 1):
        e_abs += abs(err_w[j])
    if cf_ok:
        stick_chunk_consts(cf_chunk, p, chunk_c)
    rtol = opts[O_RTOL]
    atol = opts[O_ATOL]
    hmax = opts[O_HMAX]
    evcap = opts[O_EVCAP]
    maxsteps = int(opts[O_MAXSTEPS])
    graze = opts[O_GRAZE]
    stepcap = opts[O_STEPCAP]
    period = 2.0 * math.pi / p[P_ETA]
    log_cap = log.shape[0]

    stages = np.empty((n_ext, n))
    stages2 = np.empty((n_ext, n))
    interp = np.empty((dense_w.shape[0], n))
    ynew = np.empty(n)
    ytmp = np.empty(n)
    ys = np.empty(n)
    fs = np.empty(n)
    act = np.empty(n, dtype=np.int64)
    kinds = np.empty(4, dtype=np.int64)
    w0s = np.empty(4)
    w1s = np.empty(4)
    s1s = np.empty(4)   # their slopes at the step end (NaN: not computed)
    wtols = np.empty(4)

    t = fstate[F_T]
    h = fstate[F_H]
    if not (math.isfinite(t_end) and math.isfinite(t) and t <= t_end):
        return ST_BAD_INPUT
    for i in range(n):
        if not math.isfinite(y[i]):
            return ST_NONFINITE
    n_act = set_active(istate, n, act)
    ms = istate[I_STICK]
    mc = istate[I_CONTACT]
    field = (p, ms, mc, sub)
    # the lowest drive on the bit, kept in a register and stored at every return.  The drive at
    # y in mode mc, its rate along stages[0] and the watched indicators carry from the end of an
    # accepted step to the start of the next (``carried``; recomputing them cost a tenth of the
    # solver's time); an event or a reset starts afresh
    d_min = fstate[F_DRIVE_MIN]
    d_y = force_on_bit(y, p, mc)
    if d_y < d_min:
        d_min = d_y
    r_y = 0.0
    carried = False
    rhs(t, y, field, stages[0])
    istate[I_RHS] += 1
    steps_here = 0
    refine = 0
    sc_t = math.nan  # time whose forcing phase (sc_s, sc_c) a full stick chunk left behind
    sc_s = 0.0
    sc_c = 0.0

    while True:
        remaining = t_end - t
        # a sliver below the time resolution is no dynamics: done
        if remaining <= TIME_RESOLUTION * max(abs(t_end), 1.0):
            break
        if log_cap > 0 and istate[I_NLOG] >= log_cap:
            fstate[F_T] = t
            fstate[F_DRIVE_MIN] = d_min
            fstate[F_H] = h
            return ST_LOG_FULL
        if maxsteps > 0 and steps_here >= maxsteps:
            fstate[F_T] = t
            fstate[F_DRIVE_MIN] = d_min
            fstate[F_H] = h
            return ST_MAX_STEPS

        # -- an indicator already positive at the start: immediate event --------
        nw = watched(istate, p, kinds)
        immediate = -1
        for q in range(nw):
            w0s[q] = w1s[q] if carried else watch_value(kinds[q], y, p, mc)
            if not carried:
                s1s[q] = math.nan
            wtols[q] = watch_tol(kinds[q], y, p)
            if w0s[q] > wtols[q]:
                immediate = kinds[q]
                break

        hit_kind = -1
        t_hit = 0.0
        wtol_hit = 0.0
        h_next = h
        if immediate < 0 and cf_ok and ms == STICK and mc == FREE:
            # -- one chunk of the exact stick solution -------------------------
            h_chunk = cf_chunk
            t1 = t + h_chunk
            full = True
            if h_chunk >= remaining or remaining - h_chunk < CHUNK_SLIVER * max(abs(t), 1.0):
                h_chunk = remaining
                t1 = t_end
                full = False
            if t == sc_t:
                stick_prepare_phase(t, y, p, interp, sc_s, sc_c)  # phase carried from the last chunk
            else:
                stick_prepare(t, y, p, interp)
            sc_t = math.nan
            if full:
                sn1, cs1 = stick_state_chunk(t1, y, interp, p, chunk_c, ynew)
            else:
                sn1 = stick_state(t1, y, interp, p, ynew)
                cs1 = 0.0
            if not (math.isfinite(ynew[X_HAMMER]) and math.isfinite(ynew[V_HAMMER])):
                fstate[F_T] = t
                fstate[F_DRIVE_MIN] = d_min
                return ST_NONFINITE
            stick_rate(ynew, sn1, p, fs)  # = rhs(t1, ynew) in stick with the gap open
            istate[I_RHS] += 1
            istate[I_STEPS] += 1
            steps_here += 1
            if count_step(t1, period, istate, stepcap):
                fstate[F_T] = t
                fstate[F_DRIVE_MIN] = d_min
                fstate[F_H] = h
                return ST_STEP_STORM
            # (this loop mirrors the RK step's detection below on purpose: one loop shared
            # by both paths measured 5-7 % slower, the per-path constants no longer fold)
            d1 = force_on_bit(ynew, p, mc)
            r1 = drive_rate(ynew, fs, p, mc)
            for q in range(nw):
                kd = kinds[q]
                w1s[q] = watch_value_drive(kd, ynew, p, mc, d1)
                code, s1s[q] = sign_change(kd, y, ynew, stages[0], fs, p, mc, (w0s[q], w1s[q], wtols[q], s1s[q], r1),
                                           h_chunk, graze_stick)
                if code == 0:
                    continue
                te = locate_event(kd, code, t1, (t, y, h_chunk, how_stick, interp, act, n_act),
                                  (opts[O_BISECT], graze, wtols[q]), tableau, field,
                                  (stages2, ytmp, ys, ytmp))
                if te > 0.0 and (hit_kind < 0 or te < t_hit):
                    hit_kind = kd
                    t_hit = te
            if hit_kind < 0:
                if not carried:
                    r_y = drive_rate(y, stages[0], p, mc)
                if d1 < d_min:
                    d_min = d1
                if drive_dips(d_y, r_y * h_chunk, d1, r1 * h_chunk, d_min):
                    d_min = drive_inside(t1, (t, y, h_chunk, how_stick, interp, act, n_act), field, ys, ytmp, d_min)
                d_y = d1
                r_y = r1
                carried = True
                if needs_record(t1, istate, opts, poin, samp_t):
                    record_until(t1, ynew, (t, y, h_chunk, how_stick, interp, act, n_act),
                                 tableau, field, (stages2, ytmp, ys, fs), istate, opts, rec)
                for i in range(n):
                    y[i] = ynew[i]
                    stages[0, i] = fs[i]
                t = t1
                if full:
                    sc_t = t1
                    sc_s = sn1
                    sc_c = cs1
                continue
            stick_state(t_hit, y, interp, p, ys)
            d_y = force_on_bit(ys, p, mc)
            if d_y < d_min:
                d_min = d_y
            if needs_record(t_hit, istate, opts, poin, samp_t):
                record_until(t_hit, ys, (t, y, h_chunk, how_stick, interp, act, n_act),
                             tableau, field, (stages2, ytmp, ynew, fs), istate, opts, rec)
            for i in range(n):
                y[i] = ys[i]
            t = t_hit
        elif immediate < 0:
            # -- one accepted step -------------------------------------------
            if fixed:
                h = min(opts[O_HFIXED], remaining)
                rk_step(t, y, h, tableau, stages, ynew, ytmp, act, n_act, field)
                istate[I_RHS] += ns
                for i in range(n):
                    if not math.isfinite(ynew[i]):
                        fstate[F_T] = t
                        fstate[F_DRIVE_MIN] = d_min
                        return ST_NONFINITE
            else:
                hmin = TIME_RESOLUTION * max(abs(t), 1.0)
                rejected = False
                if mc != FREE:
                    # stiff contact: keep h within the explicit method's
                    # stability region, h omega_c <= 1.5, omega_c^2 = dF_c/dd / m_eff
                    dpen = overlap(y, p)
                    if dpen > 0.0:
                        kcl = p[P_KC] * p[P_N] * dpen ** (p[P_N] - 1.0)
                        if mc == CONTACT:
                            kcl *= 1.0 + p[P_LAM] * max(y[V_HAMMER] - y[V_BIT], 0.0)
                        minv = 1.0 + (1.0 / p[P_RHO] if ms == SLIP else 0.0)
                        hcap = CONTACT_STABILITY_LIMIT / math.sqrt(kcl * minv + TINY)
                        if h > hcap:
                            h = hcap
                if ms == SLIP and stages[0, V_BIT] < 0.0 and y[V_BIT] > 0.0:
                    # the bit decelerates to a stop: do not step far past the
                    # predicted stop, where the friction law is extrapolated
                    t_stop = -y[V_BIT] / stages[0, V_BIT]
                    if h > STOP_OVERSHOOT * t_stop:
                        h = max(STOP_OVERSHOOT * t_stop, STOP_SHRINK_FLOOR * h)
                while True:
                    if h > hmax:
                        h = hmax
                    if h >= remaining or (not rejected and remaining - h < SLIVER_FLOORS * hmin):
                        # never leave a sliver behind; after a rejection the step only
                        # shrinks (snapping back to the whole remainder would retry the
                        # rejected step forever when hmin is coarse, e.g. at a late start)
                        h = remaining
                    if h < hmin:
                        fstate[F_T] = t
                        fstate[F_DRIVE_MIN] = d_min
                        fstate[F_H] = h
                        return ST_STEP_TOO_SMALL
                    rk_step(t, y, h, tableau, stages, ynew, ytmp, act, n_act, field)
                    istate[I_RHS] += ns
                    err = error_norm(y, ynew, h, stages, method, act, n_act, (rtol, atol, fstate[F_V4_PEAK]))
                    finite = math.isfinite(err)
                    if finite:
                        for i in range(n):
                            if not math.isfinite(ynew[i]):
                                finite = False
                                break
                    if finite and err <= 1.0:
                        break
                    istate[I_REJECTS] += 1
                    if not finite:
                        h *= MIN_FACTOR
                    else:
                        h *= max(MIN_FACTOR, SAFETY / err_root(err, err_exp))
                    rejected = True
                # next step proposal
                if err == 0.0:
                    fac = MAX_FACTOR
                else:
                    fac = min(MAX_FACTOR, SAFETY / err_root(err, err_exp))
                    if fstate[F_ERRACC] > 0.0:
                        # Gustafsson's predictive controller (as in Radau5), used
                        # only to shrink: an error that grows from step to step
                        # (the bit nearing its stop) is met before it rejects
                        fg = fac * (h / fstate[F_HACC]) * err_root(fstate[F_ERRACC] / err, err_exp)
                        fac = min(fac, max(fg, MIN_FACTOR))
                if rejected:
                    fac = min(1.0, fac)
                if ms == SLIP and mc == FREE and fstate[F_ERRACC] == 0.0:
                    # first step of a slip: the next slip starts with this step's successor
                    # (the step that ended the slip came from the stop layer: far too small)
                    fstate[F_H_MODE + SLIP] = h * fac
                fstate[F_HACC] = h
                fstate[F_ERRACC] = max(err, ERRACC_FLOOR)
                h_next = h * fac
                if ms == SLIP and stages[ns, V_BIT] < 0.0 and ynew[V_BIT] > 0.0 and p[P_MU] < 1.0:
                    # the bit decelerates: keep the next step out of the friction layer
                    sc4 = atol + rtol * max(ynew[V_BIT], fstate[F_V4_PEAK])
                    # a step whose friction error stays below the target: Newton steps on
                    # ln h aimed a little below it (ln ef is convex in ln h, so they approach
                    # from above and stop as soon as the target is met)
                    for _ in range(8):
                        ef, dlog = friction_layer_err(h_next, ynew[V_BIT], stages[ns, V_BIT], p, method, e_abs, n_act,
                                                      sc4)
                        if ef <= LAYER_TARGET:
                            break
                        h_next *= max(MIN_FACTOR, math.exp(math.log(0.5 * LAYER_TARGET / ef) / max(dlog, 1.0)))
            istate[I_STEPS] += 1
            steps_here += 1
            t1 = t + h
            if h >= remaining:
                t1 = t_end
            if count_step(t1, period, istate, stepcap):
                fstate[F_T] = t
                fstate[F_DRIVE_MIN] = d_min
                fstate[F_H] = h
                return ST_STEP_STORM

            # -- detection over [t, t1] ------------------------------------
            # (the step group (t, y, h, how, interp, act, n_act) is built where it is passed, not once
            # per step: its arrays' reference counts cost about 3 % of a step that passes it nowhere)
            dense_ok = no_act > 0  # False, as a plain bool (see ``plain``)
            # the drive on the bit at the step end, for the drive indicators and the drive tracker
            f_contact1 = contact_force_at(ynew, p, mc)  # 0 out of contact
            d1 = spring_damper_force(ynew, p) + f_contact1  # = force_on_bit(ynew, p, mc)
            r1 = 0.0 if fixed else drive_rate(ynew, stages[ns], p, mc)  # (no grazing search in fixed steps)
            for q in range(nw):
                kd = kinds[q]
                w1s[q] = watch_value_drive(kd, ynew, p, mc, d1)
                code, s1s[q] = sign_change(kd, y, ynew, stages[0], stages[ns], p, mc, (w0s[q], w1s[q], wtols[q], s1s[q], r1),
                                           h, not fixed)
                if code == 0:
                    continue
                dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                                       ynew, tableau, dense_w, stages, stages2, ytmp, istate, field)
                te = locate_event(kd, code, t1, (t, y, h, how_rk, interp, act, n_act),
                                  (opts[O_BISECT], graze, wtols[q]), tableau, field,
                                  (stages2, ytmp, ys, fs))
                if te > 0.0 and (hit_kind < 0 or te < t_hit):
                    hit_kind = kd
                    t_hit = te
                    wtol_hit = wtols[q]

            if hit_kind < 0:
                # -- no event: record and accept ----------------------------
                if needs_record(t1, istate, opts, poin, samp_t):
                    dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                                           ynew, tableau, dense_w, stages, stages2, ytmp, istate, field)
                    record_until(t1, ynew, (t, y, h, how_rk, interp, act, n_act),
                                 tableau, field, (stages2, ytmp, ys, fs), istate, opts, rec)
                if mc == CONTACT:
                    if not fixed and y[V_HAMMER] - y[V_BIT] > 0.0 and ynew[V_HAMMER] - ynew[V_BIT] <= 0.0:
                        dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                                               ynew, tableau, dense_w, stages, stages2, ytmp, istate, field)
                        peak_in_step(t1, (t, y, h, how_rk, interp, act, n_act), field, ys, fs, fstate)
                    if f_contact1 > fstate[F_PEAK]:
                        fstate[F_PEAK] = f_contact1
                if d1 < d_min:
                    d_min = d1
                if not fixed:
                    # (the fixed-step method tracks the drive at the step ends only)
                    if not carried:
                        r_y = drive_rate(y, stages[0], p, mc)
                    if drive_dips(d_y, r_y * h, d1, r1 * h, d_min):
                        dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                                               ynew, tableau, dense_w, stages, stages2, ytmp, istate, field)
                        d_min = drive_inside(t1, (t, y, h, how_rk, interp, act, n_act), field, ys, fs, d_min)
                    r_y = r1
                d_y = d1
                carried = True
                for i in range(n):
                    y[i] = ynew[i]
                    stages[0, i] = stages[ns, i]
                if y[V_BIT] > fstate[F_V4_PEAK]:
                    fstate[F_V4_PEAK] = y[V_BIT]
                t = t1
                if not fixed:
                    h = h_next
                continue

            # -- event inside the step: move to it ------------------------
            # The event state comes from a real step of the method from t to
            # t_hit (the dense output near a nonsmooth switch is less accurate
            # than a step that ends on it).  If that state has not crossed
            # yet, move there and locate again from nearer (at most twice).
            for i in range(n):
                stages2[0, i] = stages[0, i]
            rk_step(t, y, t_hit - t, tableau, stages2, ys, ytmp, act, n_act, field)
            istate[I_RHS] += ns
            confirmed = fixed or watch_value(hit_kind, ys, p, mc) > wtol_hit
            if not confirmed and refine >= 2:
                # give up refining: take the dense-output state, crossed by construction
                state_at(t_hit, (t, y, h, how_dense, interp, act, n_act), tableau, field, stages2, ytmp, ys)
                confirmed = True
            if not confirmed:
                refine += 1
            else:
                refine = 0
            if hit_kind == EV_STICK and not fixed:
                # samples of this step came from the dense output: the drift must not step
                # back from them to the re-stepped state (they differ within tolerance)
                dense_eval((t_hit - t) / h, y, interp, act, n_act, ynew)
                if ynew[X_BIT] > ys[X_BIT]:
                    ys[X_BIT] = ynew[X_BIT]
            if mc == CONTACT and not fixed and y[V_HAMMER] - y[V_BIT] > 0.0 and ys[V_HAMMER] - ys[V_BIT] <= 0.0 and dense_ok:
                peak_in_step(t_hit, (t, y, h, how_rk, interp, act, n_act), field, ynew, fs, fstate)
            d_y = force_on_bit(ys, p, mc)
            if d_y < d_min:
                d_min = d_y
            carried = False  # stages[0] changes below, or the reset map follows
            if needs_record(t_hit, istate, opts, poin, samp_t):
                record_until(t_hit, ys, (t, y, h, how_rk, interp, act, n_act),
                             tableau, field, (stages2, ytmp, ynew, fs), istate, opts, rec)
            for i in range(n):
                y[i] = ys[i]
            t = t_hit
            if not fixed:
                h = h_next
            if not confirmed:
                for i in range(n):
                    stages[0, i] = stages2[ns, i]
                continue
        else:
            hit_kind = immediate

        # -- reset map, bookkeeping ------------------------------------------
        if mc == CONTACT:
            f_contact1 = contact_force_at(y, p, mc)
            if f_contact1 > fstate[F_PEAK]:
                fstate[F_PEAK] = f_contact1
        vrel = y[V_HAMMER] - y[V_BIT]
        if step_slot(ms, mc) != SLIP:
            fstate[F_H_MODE + step_slot(ms, mc)] = h
        taken = apply_event(hit_kind, y, istate, fstate, p)
        fstate[F_ERRACC] = 0.0  # the new regime starts its own step-size history
        if taken == EV_STICK:
            fstate[F_T_STICK] = t
        d_y = force_on_bit(y, p, istate[I_CONTACT])
        if d_y < d_min:
            d_min = d_y
        carried = False
        if log_cap > 0:
            r = istate[I_NLOG]
            log[r, L_T] = t
            log[r, L_KIND] = taken
            log[r, L_X1] = y[X_HAMMER]
            log[r, L_X2] = y[V_HAMMER]
            log[r, L_X3] = y[X_BIT]
            log[r, L_X4] = y[V_BIT]
            log[r, L_VREL] = vrel
            log[r, L_PEAK] = fstate[F_PEAK] if taken == EV_SEPARATION else 0.0
            istate[I_NLOG] = r + 1
        win = int(math.floor(t / period))
        if win != istate[I_WIN]:
            istate[I_WIN] = win
            istate[I_WIN_EVENTS] = 0
        istate[I_WIN_EVENTS] += 1
        if istate[I_WIN_EVENTS] > evcap:
            fstate[F_T] = t
            fstate[F_DRIVE_MIN] = d_min
            fstate[F_H] = h
            return ST_EVENT_STORM
        ms = istate[I_STICK]
        mc = istate[I_CONTACT]
        field = (p, ms, mc, sub)
        if not fixed and fstate[F_H_MODE + step_slot(ms, mc)] > 0.0:
            h = fstate[F_H_MODE + step_slot(ms, mc)]
        n_act = set_active(istate, n, act)
        rhs(t, y, field, stages[0])
        istate[I_RHS] += 1

    # final: samples that sit exactly on t_end
    t = t_end
    fstate[F_T] = t
    fstate[F_DRIVE_MIN] = d_min
    fstate[F_H] = h
    if needs_record(t, istate, opts, poin, samp_t):
        for i in range(n):
            ynew[i] = y[i]
        record_until(t, ynew, (t, y, 1.0, how_dense, interp, act, no_act), tableau, field, (stages2, ytmp, ys, fs),
                     istate, opts, rec)
    return ST_DONE


# Entry points, each compiled on its first call (or loaded from the cache):
# ``advance_hammer`` (DOP853, no linear subsystem, no energy block: a plain
# ``simulate``, the FMU, the sweeps) binds the tableau and the empty subsystem as
# constants (``partial.bind``), so they fold into one function as an IR-inlined
# call would, without numba re-typing a copy of the driver; ``advance`` serves
# every other combination (DP54, RK4, the energy block, the monolithic reference).

#: the empty linear subsystem and no energy block: the ``sub`` group of a hammer-only system
NO_SUB = (0, 0, np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 2)),
          np.zeros(0), np.zeros(2))


#: ``advance`` with DOP853, no linear subsystem and no energy block, all bound as constants
advance_hammer = njit(cache=True, nogil=True)(bind(
    advance, "advance_hammer", method=_T.METHODS["dop853"],
    sub=NO_SUB))
