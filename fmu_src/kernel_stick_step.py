"""A step of the stuck hammer in closed form: one chunk of the exact solution, its events and what it records (numba kernels).

While the bit sticks and the gap is open, the hammer is a forced linear
oscillator (:mod:`.kernel_stick`): adaptive runs of hammer-only systems step
it in chunks of a fixed fraction of the shorter of the forcing and natural
periods, exact whatever their length, instead of Runge–Kutta steps.  A full
chunk hands the forcing phase at its end to the next chunk (no sine or cosine
recomputed).  The groups ``ctx`` and ``drive`` are those of
:func:`.kernel_driver.advance`.
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_event_search import stick_chunk_events
from .kernel_events import drive_rate
from .kernel_forces import force_on_bit
from .kernel_layouts import (CHUNK_SLIVER, I_RHS, I_STEPS, ST_DONE, ST_NONFINITE, ST_STEP_STORM, V_HAMMER,
                             X_HAMMER)
from .kernel_localise import drive_before_event, drive_dips, drive_inside
from .kernel_recording import needs_record, record_until
from .kernel_stick import stick_prepare, stick_prepare_phase, stick_rate, stick_state, stick_state_chunk
from .kernel_step_control import count_step


@njit(inline="always")
def stick_chunk(t, t_end, y, p, interp, ynew, cf, phase):
    """The exact state at the end of the chunk from ``t`` in ``ynew`` (``cf = (chunk, its
    constants)``, ``phase = (t, sin, cos)`` left by the last full chunk).  Returns
    ``(h, t1, full, sin, cos)`` of the chunk: a short last chunk reaches ``t_end``."""
    cf_chunk, chunk_c = cf
    sc_t, sc_s, sc_c = phase
    remaining = t_end - t
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
    if full:
        sn1, cs1 = stick_state_chunk(t1, y, interp, p, chunk_c, ynew)
    else:
        sn1 = stick_state(t1, y, interp, p, ynew)
        cs1 = 0.0
    return h_chunk, t1, full, sn1, cs1


@njit(inline="always")
def stick_advance(t, t_end, phase, drive, nw, n_act, field, ctx):
    """One chunk of the exact stick solution from ``t``, up to its first event.

    Returns ``(status, event kind or -1, the new time, drive, phase)``: ST_DONE, or
    ST_NONFINITE / ST_STEP_STORM with ``y`` left at ``t``.
    """
    (tableau, _), sol, work, _, kit, _, cf, rec = ctx
    y, istate, _, opts = sol
    stages, stages2, interp, ynew, ytmp, ys, fs, act = work
    how_stick, period, stepcap = kit[2], kit[8], kit[9]
    p, _, mc, _ = field
    d_min, d_y, r_y, carried = drive
    h_chunk, t1, full, sn1, cs1 = stick_chunk(t, t_end, y, p, interp, ynew, cf, phase)
    no_phase = (math.nan, phase[1], phase[2])
    if not (math.isfinite(ynew[X_HAMMER]) and math.isfinite(ynew[V_HAMMER])):
        return ST_NONFINITE, -1, t, drive, no_phase
    stick_rate(ynew, sn1, p, fs)  # = rhs(t1, ynew) in stick with the gap open
    istate[I_RHS] += 1
    istate[I_STEPS] += 1
    if count_step(t1, period, istate, stepcap):
        return ST_STEP_STORM, -1, t, drive, no_phase
    hit_kind, t_hit, d1, r1 = stick_chunk_events((t, t1, h_chunk), nw, n_act, field, ctx)
    if hit_kind < 0:
        if not carried:
            r_y = drive_rate(y, stages[0], p, mc)
        if d1 < d_min:
            d_min = d1
        if drive_dips(d_y, r_y * h_chunk, d1, r1 * h_chunk, d_min):
            d_min = drive_inside(t1, (t, y, h_chunk, how_stick, interp, act, n_act), field, ys, ytmp, d_min)
        if needs_record(t1, istate, opts, rec[0], rec[1]):
            record_until(t1, ynew, (t, y, h_chunk, how_stick, interp, act, n_act), tableau, field,
                         (stages2, ytmp, ys, fs), istate, opts, rec)
        for i in range(y.shape[0]):
            y[i] = ynew[i]
            stages[0, i] = fs[i]
        return ST_DONE, -1, t1, (d_min, d1, r1, True), (t1, sn1, cs1) if full else no_phase
    d_min = drive_before_event(t_hit, (t, y, h_chunk, how_stick, interp, act, n_act), field,
                               (d_y, r_y if carried else drive_rate(y, stages[0], p, mc)), ys, fs, d_min)
    stick_state(t_hit, y, interp, p, ys)
    d_y = force_on_bit(ys, p, mc)
    if d_y < d_min:
        d_min = d_y
    if needs_record(t_hit, istate, opts, rec[0], rec[1]):
        record_until(t_hit, ys, (t, y, h_chunk, how_stick, interp, act, n_act), tableau, field,
                     (stages2, ytmp, ynew, fs), istate, opts, rec)
    for i in range(y.shape[0]):
        y[i] = ys[i]
    return ST_DONE, hit_kind, t_hit, (d_min, d_y, r_y, carried), no_phase
