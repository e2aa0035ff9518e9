"""One generic Runge–Kutta step for any tableau, its error norm and dense output (numba kernels)."""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import harmonic_shifted, rhs_forced
from .kernel_layouts import HOW_RESTEP, I_RHS, P_ETA, P_GAMMA, P_MU, P_PHI, P_RHO, X_BIT, X_HAMMER

@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def rk_stages(t, y, h, tableau, stage_range, stages, ytmp, act, n_act, field):
    """Stages ``s_from <= s < s_to`` (``stage_range``) of an explicit RK method into ``stages[s]``.

    ``tableau`` and ``field`` are the groups of :mod:`.kernel_layouts`.
    Returns sin and cos of the forcing phase at ``t`` (for the caller's FSAL stage).
    """
    rk_a = tableau[0]
    rk_c = tableau[2]
    p = field[0]
    s_from, s_to = stage_range
    for i in range(y.shape[0]):
        ytmp[i] = y[i]  # inactive components (a stuck bit) keep their values
    th0 = p[P_ETA] * t + p[P_PHI]
    s0 = math.sin(th0)
    c0 = math.cos(th0)
    n = y.shape[0]
    for s in range(s_from, s_to):
        if n_act == n:
            # every component active (a slipping bit): no index indirection
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += rk_a[s, j] * stages[j, i]
                ytmp[i] = y[i] + h * acc
        else:
            for q in range(n_act):
                i = act[q]
                acc = 0.0
                for j in range(s):
                    acc += rk_a[s, j] * stages[j, i]
                ytmp[i] = y[i] + h * acc
        rhs_forced(harmonic_shifted(t, rk_c[s] * h, s0, c0, p), ytmp, field, stages[s])
    return s0, c0


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def rk_step(t, y, h, tableau, stages, ynew, ytmp, act, n_act, field):
    """One step of any explicit ``tableau``; ``stages[0]`` must hold f(t, y).

    Writes the solution ``ynew`` and the FSAL stage ``stages[ns] = f(t + h, ynew)``.
    """
    rk_b = tableau[1]
    ns = tableau[3]
    s0, c0 = rk_stages(t, y, h, tableau, (1, ns), stages, ytmp, act, n_act, field)
    for i in range(y.shape[0]):
        ynew[i] = y[i]
    for q in range(n_act):
        i = act[q]
        acc = 0.0
        for j in range(ns):
            acc += rk_b[j] * stages[j, i]
        ynew[i] = y[i] + h * acc
    rhs_forced(harmonic_shifted(t, h, s0, c0, field[0]), ynew, field, stages[ns])


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def error_norm(y, ynew, h, stages, method, act, n_act, tols):
    """RMS norm of the embedded error estimate of ``method``, scaled by atol + rtol |y|
    (``tols = (rtol, atol, v4_peak)``).

    The bit velocity x4 is scaled by its peak in the current slip instead of
    its instantaneous value: as the bit decelerates to a stop, a scale that
    shrinks with x4 would demand ever smaller steps for no gain in the
    accuracy of the stop time (which depends on the absolute error of x4).

    ``err_kind`` 1: single estimate with weights E over ns + 1 stages;
    2: Hairer's DOP853 combination of the 5th (err_w) and 3rd (err_w3) order estimates.
    Returns inf when the estimate is not finite (the step is then rejected).
    """
    err_w, err_w3, ns, err_kind = method[3], method[4], method[6], method[7]
    rtol, atol, v4_peak = tols
    e5 = 0.0
    e3 = 0.0
    for q in range(n_act):
        i = act[q]
        if i == 0:
            # the hammer position matters relative to the bit (the dynamics is invariant
            # to a common shift): scale it by the relative displacement, not the drift
            sc = atol + rtol * max(abs(y[X_HAMMER] - y[X_BIT]), abs(ynew[X_HAMMER] - ynew[X_BIT]))
        else:
            sc = atol + rtol * max(abs(y[i]), abs(ynew[i]))
        if i == 3:
            sc = max(sc, atol + rtol * v4_peak)
        a5 = 0.0
        a3 = 0.0
        for j in range(ns + 1):
            a5 += err_w[j] * stages[j, i]
            if err_kind == 2:
                a3 += err_w3[j] * stages[j, i]
        a5 /= sc
        a3 /= sc
        e5 += a5 * a5
        e3 += a3 * a3
    if err_kind == 2:
        if e5 == 0.0 and e3 == 0.0:
            return 0.0
        den = e5 + 0.01 * e3
        r = abs(h) * e5 / math.sqrt(den * n_act)
    else:
        r = abs(h) * math.sqrt(e5 / n_act)
    if not math.isfinite(r):
        return math.inf
    return r


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def friction_layer_err(h, x4, f4, p, method, e_abs, n_act, sc):
    """Error norm a step of size h would get from the kinetic friction alone.

    As the bit decelerates to a stop, the friction term (1 - mu) exp(-gamma_hat x4)
    grows like exp(sigma t), sigma = -gamma_hat x4' > 0, and soon dominates the
    local error.  Feeding that exponential through the method's error weights
    gives the estimate the step will see, in closed form and beyond the
    asymptotic h -> 0 regime: a step that would run into the layer is shortened
    before it is tried and rejected.

    Parameters
    ----------
    h : float
        Candidate step.
    x4, f4 : float
        Bit velocity and acceleration at the step start (f4 < 0).
    method : tuple
        The tableau (:mod:`.kernel_layouts`): its nodes and error weights.
    e_abs : float
        sum(|E|), for a cheap upper bound.
    sc : float
        Error scale of x4 (atol + rtol * scale).

    Returns
    -------
    ef : float
        The friction part of the error norm (same normalisation as ``error_norm``).
    dlog : float
        d ln(ef) / d ln(h), for a Newton step on the step size.
    """
    rk_c, err_w, err_w3, ns, err_kind = method[2], method[3], method[4], method[6], method[7]
    sig = -p[P_GAMMA] * f4 * h
    if sig > 600.0:
        return math.inf, 9.0
    amp = (1.0 - p[P_MU]) / p[P_RHO] * math.exp(-p[P_GAMMA] * x4) / sc
    # cheap bound first: the estimate is at most h amp exp(sig) sum|E| / sqrt(n)
    bound = abs(h) * amp * math.exp(max(sig, 0.0)) * e_abs
    if bound <= 1e-3 * math.sqrt(n_act):
        return bound / math.sqrt(n_act), 9.0
    # the weighted sums and their logarithmic derivatives h d/dh (sig is proportional to h)
    a5 = 0.0
    a3 = 0.0
    d5 = 0.0
    d3 = 0.0
    for j in range(ns + 1):
        if err_w[j] == 0.0 and err_w3[j] == 0.0:
            continue
        c = rk_c[j] if j < ns else 1.0
        e = math.exp(sig * c)
        a5 += err_w[j] * e
        a3 += err_w3[j] * e
        d5 += err_w[j] * sig * c * e
        d3 += err_w3[j] * sig * c * e
    if err_kind == 2:
        den = a5 * a5 + 0.01 * a3 * a3
        if den == 0.0 or a5 == 0.0:
            return 0.0, 9.0
        dlog = 1.0 + 2.0 * d5 / a5 - (a5 * d5 + 0.01 * a3 * d3) / den
        return abs(h) * amp * a5 * a5 / math.sqrt(den * n_act), dlog
    if a5 == 0.0:
        return 0.0, 9.0
    return abs(h) * amp * abs(a5) / math.sqrt(n_act), 1.0 + d5 / a5


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def dense_prepare(step, ynew, tableau, dense_w, stages, ytmp, field):
    """Extra stages (if the method has them) and nested coefficients ``interp`` of the dense output
    of ``step`` (the groups: :mod:`.kernel_layouts`)."""
    t, y, h, _, interp, act, n_act = step
    rk_a, ns = tableau[0], tableau[3]
    n_ext = rk_a.shape[0]
    if n_ext > ns + 1:
        rk_stages(t, y, h, tableau, (ns + 1, n_ext), stages, ytmp, act, n_act, field)
    nF = dense_w.shape[0]
    for q in range(n_act):
        i = act[q]
        interp[0, i] = ynew[i] - y[i]
        for k in range(1, nF):
            acc = 0.0
            for s in range(n_ext):
                w = dense_w[k, s]
                if w != 0.0:
                    acc += w * stages[s, i]
            interp[k, i] = h * acc


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def interpolant(ready, step, ynew, tableau, dense_w, stages, stages2, ytmp, istate, field):
    """Make the interpolant of ``step`` usable, once per step; returns True.

    Adaptive methods: the dense-output coefficients (and their extra stages).
    The fixed-step method re-steps instead, which needs f(t0, y0) in ``stages2[0]``.
    """
    if ready:
        return True
    if step[3] == HOW_RESTEP:  # the fixed-step method
        for i in range(step[1].shape[0]):
            stages2[0, i] = stages[0, i]
    else:
        dense_prepare(step, ynew, tableau, dense_w, stages, ytmp, field)
        istate[I_RHS] += tableau[0].shape[0] - tableau[3] - 1
    return True


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def dense_eval(x, y, interp, act, n_act, out):
    """State at fraction ``x`` of the step from the nested dense coefficients ``interp``."""
    nF = interp.shape[0]
    for i in range(y.shape[0]):
        out[i] = y[i]
    for q in range(n_act):
        i = act[q]
        acc = 0.0
        for k in range(nF - 1, -1, -1):
            acc += interp[k, i]
            if k % 2 == 0:
                acc *= x
            else:
                acc *= 1.0 - x
        out[i] = y[i] + acc


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def dense_eval_rate(x, y, interp, act, n_act, h, out, dout):
    """``dense_eval`` and the time derivative of the interpolant (into ``dout``)."""
    nF = interp.shape[0]
    for i in range(y.shape[0]):
        out[i] = y[i]
        dout[i] = 0.0
    for q in range(n_act):
        i = act[q]
        acc = 0.0
        dacc = 0.0
        for k in range(nF - 1, -1, -1):
            acc += interp[k, i]
            if k % 2 == 0:
                dacc = dacc * x + acc
                acc *= x
            else:
                dacc = dacc * (1.0 - x) - acc
                acc *= 1.0 - x
        out[i] = y[i] + acc
        dout[i] = dacc / h
