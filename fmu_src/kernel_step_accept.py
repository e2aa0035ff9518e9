"""Taking a Runge–Kutta step: the whole step, or up to its first event; what it records on the way (numba kernels).

An accepted step records the samples and Poincaré rows it passes
(:mod:`.kernel_recording`), the contact-force peak and the lowest drive on the
bit, then moves the state to its end.  A step with an event moves the state to
the event, from a real step of the method that ends there.  The groups
``ctx`` (``rk``, ``sol``, ``work``, ``kit``, ``rec``) and ``drive`` are those of
:func:`.kernel_driver.advance`.
"""

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_events import drive_rate, watch_value
from .kernel_forces import force_on_bit
from .kernel_layouts import CONTACT, EV_STICK, F_PEAK, F_V4_PEAK, I_RHS, V_BIT, V_HAMMER, X_BIT
from .kernel_localise import drive_before_event, drive_dips, drive_inside, peak_in_step, state_at
from .kernel_recording import needs_record, record_until
from .kernel_runge_kutta import dense_eval, interpolant, rk_step


@njit(inline="always")
def accept_step(span, ends, dense_ok, drive, n_act, field, ctx):
    """Accept the step ``span = (t, t1, h)`` to ``ynew`` (no event inside): record, track the
    contact peak and the lowest drive (``ends``: contact force, drive and its rate at ``t1``),
    move ``y`` and ``stages[0]`` to the step end.  Returns the new ``drive`` group."""
    t, t1, h = span
    f_contact1, d1, r1 = ends
    d_min, d_y, r_y, carried = drive
    (tableau, method), sol, work, _, kit, _, _, rec = ctx
    y, istate, fstate, opts = sol
    stages, stages2, interp, ynew, ytmp, ys, fs, act = work
    fixed, how_rk = kit[0], kit[1]
    p, _, mc, _ = field
    ns = tableau[3]
    if needs_record(t1, istate, opts, rec[0], rec[1]):
        dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                               ynew, tableau, method[5], stages, stages2, ytmp, istate, field)
        record_until(t1, ynew, (t, y, h, how_rk, interp, act, n_act),
                     tableau, field, (stages2, ytmp, ys, fs), istate, opts, rec)
    if mc == CONTACT:
        if not fixed and y[V_HAMMER] - y[V_BIT] > 0.0 and ynew[V_HAMMER] - ynew[V_BIT] <= 0.0:
            dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                                   ynew, tableau, method[5], stages, stages2, ytmp, istate, field)
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
                                   ynew, tableau, method[5], stages, stages2, ytmp, istate, field)
            d_min = drive_inside(t1, (t, y, h, how_rk, interp, act, n_act), field, ys, fs, d_min)
        r_y = r1
    for i in range(y.shape[0]):
        y[i] = ynew[i]
        stages[0, i] = stages[ns, i]
    if y[V_BIT] > fstate[F_V4_PEAK]:
        fstate[F_V4_PEAK] = y[V_BIT]
    return d_min, d1, r_y, True


# an ordinary call, not inlined: once per event, and kept out of the loop's code its
# steps run through
@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def step_to_event(span, hit, dense_ok, refine, drive, n_act, field, ctx):
    """Move ``y`` from ``t`` to the event ``hit = (kind, t_hit, wtol)`` inside the step
    ``span = (t, t1, h)``.  Returns ``(confirmed, refine, drive)``.

    The event state comes from a real step of the method from t to t_hit (the
    dense output near a nonsmooth switch is less accurate than a step that ends
    on it).  If that state has not crossed yet (not confirmed), the driver
    locates again from there (``refine`` counts the retries, at most two;
    ``stages[0]`` is then the rate there).
    """
    t, _, h = span
    hit_kind, t_hit, wtol_hit = hit
    d_min, d_y, r_y, _ = drive
    (tableau, method), sol, work, _, kit, _, _, rec = ctx
    y, istate, fstate, opts = sol
    stages, stages2, interp, ynew, ytmp, ys, fs, act = work
    fixed, how_rk, _, how_dense = kit[0], kit[1], kit[2], kit[3]
    p, _, mc, _ = field
    ns = tableau[3]
    n = y.shape[0]
    if not fixed:
        # a dip of the drive before the event (the fixed-step method tracks the step ends only)
        dense_ok = interpolant(dense_ok, (t, y, h, how_rk, interp, act, n_act),
                               ynew, tableau, method[5], stages, stages2, ytmp, istate, field)
        d_min = drive_before_event(t_hit, (t, y, h, how_dense, interp, act, n_act), field,
                                   (d_y, drive_rate(y, stages[0], p, mc)), ys, fs, d_min)
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
    if needs_record(t_hit, istate, opts, rec[0], rec[1]):
        record_until(t_hit, ys, (t, y, h, how_rk, interp, act, n_act),
                     tableau, field, (stages2, ytmp, ynew, fs), istate, opts, rec)
    for i in range(n):
        y[i] = ys[i]
    if not confirmed:
        for i in range(n):
            stages[0, i] = stages2[ns, i]
    # (stages[0] changes above, or the reset map follows: nothing carries)
    return confirmed, refine, (d_min, d_y, r_y, False)


@njit(inline="always")
def record_at_end(t_end, field, ctx):
    """Record the samples that sit exactly on ``t_end`` (``y`` is there)."""
    (tableau, _), sol, work, _, kit, _, _, rec = ctx
    y, istate, _, opts = sol
    _, stages2, interp, ynew, ytmp, ys, fs, act = work
    if needs_record(t_end, istate, opts, rec[0], rec[1]):
        for i in range(y.shape[0]):
            ynew[i] = y[i]
        record_until(t_end, ynew, (t_end, y, 1.0, kit[3], interp, act, kit[4]), tableau, field,
                     (stages2, ytmp, ys, fs), istate, opts, rec)
