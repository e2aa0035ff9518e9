"""numba kernels of the hybrid hammer–bit–rock dynamics.

Pure functions on arrays and floats, nopython mode, no Python objects in
inner loops.  They are split into small named pieces:

* the vector field in one hybrid mode (``rhs``);
* the signed event indicators of a mode and their time derivatives
  (``watch_value``, ``watch_slope``);
* sign-change and grazing detection over a step (``sign_change``);
* localisation of the event time by safeguarded Newton on the dense output or
  the exact stick solution (``localise_newton``), bisection for the paper's
  fixed-step method (``localise_bisect``);
* the reset map at an event (``apply_event``);
* one generic Runge–Kutta step for any tableau (``rk_step``) and its dense
  output (``dense_prepare``, ``dense_eval``);
* the driver ``advance`` that ties them together and records only what the
  scene asked for.

State layout (nondimensional, see ``model.md``)::

    y = [x1, x2, x3, x4,  z[0:nz],  e[0:ne]]

``x1, x2`` hammer position and velocity, ``x3, x4`` bit position
(penetration) and velocity; ``z`` the states of an optional linear subsystem
(the drillstring of the monolithic reference) that obeys
``z' = A z + H[:, 0] x1 + H[:, 1] x2`` (``A`` in CSR form ``Ap, Ai, Ax``;
``H`` is ``sub_in``) and pushes on the hammer with
``f_link = G . z + g[0] x1 + g[1] x2`` (``sub_out``, ``link_x``); ``e`` four optional energy
accumulators (external work, damper, contact and friction dissipation).

Each watched indicator ``w`` is signed so that its event happens when ``w``
crosses from ``w <= 0`` to ``w > 0``.
"""
import math

import numpy as np
from numba import njit

from . import _numba_cache  # noqa: F401  (registers the content-hash cache locator)

from .params import (P_A, P_B, P_CONTACT, P_ETA, P_FEXT, P_GAMMA, P_KC, P_LAM, P_MU,  # noqa: F401
                     P_N, P_PHI, P_R, P_RHO, P_XI)

# ---------------------------------------------------------------------------
# Layouts
# ---------------------------------------------------------------------------
# state offsets: y = [x1, x2, x3, x4, z[0:nz], e[0:ne]]
X_HAMMER = 0      # x1, hammer position
V_HAMMER = 1      # x2, hammer velocity
X_BIT = 2         # x3, bit position (penetration)
V_BIT = 3         # x4, bit velocity
Z0 = 4            # first state of the linear subsystem (then the energy block)

# hybrid modes
STICK = 0
SLIP = 1
FREE = 0
CONTACT = 1
CLAMPED = 2

# event kinds (= watched indicators)
EV_SLIP_START = 0     # stick -> slip: drive F_d rises through the static threshold
EV_STICK = 1          # slip -> stick: v_s falls to 0 with F_d <= F_s
EV_SLIP_ON = 2        # v_s touches 0 but F_d > F_s: slip goes on
EV_IMPACT = 3         # contact onset (gap closes)
EV_SEPARATION = 4     # contact end
EV_CLAMP = 5          # Hunt–Crossley tensile clamp engages (1 + lam d' falls to 0)
EV_UNCLAMP = 6        # clamp releases
EV_BOUNCE = 7         # bounce violation starts: F_d < -F_s while stuck (rock would pull)
EV_BOUNCE_END = 8     # bounce violation ends
N_EVENT_KINDS = 9
EVENT_NAMES = ("slip_start", "stick", "slip_on", "impact", "separation",
               "clamp", "unclamp", "bounce", "bounce_end")

# integer state
I_STICK = 0       # STICK / SLIP
I_CONTACT = 1     # FREE / CONTACT / CLAMPED
I_BOUNCE = 2      # 1 while the bounce condition holds
I_WIN = 3         # index of the forcing period of the event-storm window
I_WIN_EVENTS = 4  # events counted in that window
I_POIN_NEXT = 5   # index of the next Poincaré sample
I_SAMP_NEXT = 6   # index of the next requested sample time
I_NLOG = 7        # rows written in the event log
I_STEPS = 8       # accepted steps
I_REJECTS = 9     # rejected steps
I_RHS = 10        # right-hand-side evaluations
I_COUNT0 = 11     # first of N_EVENT_KINDS event counters
I_SWIN = I_COUNT0 + N_EVENT_KINDS        # forcing period of the step-count window
I_SWIN_STEPS = I_SWIN + 1                # accepted steps counted in that window
N_ISTATE = I_SWIN_STEPS + 1

# float state
F_T = 0           # current time
F_H = 1           # proposed next step
F_PEAK = 2        # peak contact force of the current contact
F_IMPACT_V = 3    # relative velocity of the last impact
F_H_MODE = 4      # first step of each regime: stick, slip, contact (3 slots)
F_V4_PEAK = 7     # peak bit velocity of the current slip (error scale of x4)
F_X3_SLIP = 8     # bit position at the start of the current slip
F_HACC = 9        # last accepted step of the current regime (predictive controller)
F_ERRACC = 10     # its error, floored at ERRACC_FLOOR (0: no history since the last event)
F_DRIVE_MIN = 11  # lowest drive on the bit f_k + f_c so far (inf before the first call)
F_T_STICK = 12    # last time the bit was stuck: its last stick event (-1: never stuck)
F_PEAK_RUN = 13   # peak contact force of the contacts ended so far (the run's, start-up included)
N_FSTATE = 14

# options
O_RTOL = 0
O_ATOL = 1
O_HMAX = 2
O_HFIXED = 3      # > 0: fixed-step method with this step (the paper's RK4)
O_EVCAP = 4       # max events per forcing period before EventStorm
O_BISECT = 5      # time tolerance of the fixed-step bisection (paper: 1e-6)
O_MAXSTEPS = 6    # max accepted steps in one call (0: unlimited)
O_POIN_T0 = 7     # time of Poincaré sample 0
O_POIN_DT = 8     # Poincaré sampling interval (the forcing period)
O_GRAZE = 9       # extremum value above which a grazing event counts
O_STEPCAP = 10    # max accepted steps per forcing period before ST_STEP_STORM (0: none)
N_OPTS = 11

# status codes of advance()
ST_DONE = 0
ST_LOG_FULL = 1
ST_EVENT_STORM = 2
ST_STEP_TOO_SMALL = 3
ST_NONFINITE = 4
ST_MAX_STEPS = 5
ST_STEP_STORM = 6
ST_BAD_INPUT = 7      # t_end not finite or before the current time (the Stepper checks first)

# event log columns
L_T, L_KIND, L_X1, L_X2, L_X3, L_X4, L_VREL, L_PEAK = range(8)
N_LOG_COLS = 8

# sample columns: x1, x2, x3, x4, contact force, link force, stick/slip, contact mode
N_SAMPLE_COLS = 8

EPS = 2.220446049250313e-16  # double precision unit round-off (ulp of 1)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ERRACC_FLOOR = 1e-4  # floor of the remembered error in the predictive controller
LAYER_TARGET = 0.3   # friction-layer error norm a proposed step may reach (friction_layer_err)
DRIVE_GATE = 1e-2    # drive_low: the exact search runs when the Hermite minimum is this close (x |rate| h)


# ---------------------------------------------------------------------------
# Forces and vector field
# ---------------------------------------------------------------------------
@njit(cache=True, _nrt=False)
def contact_force(d, d_rate, p, contact_mode):
    """Hunt–Crossley force / F0, kc d^n (1 + lam d'), in the CONTACT mode, else 0.

    ``d`` is the overlap (``overlap``) [x0], ``d_rate`` its rate d' [x0 Omega].

    The power is extended oddly to d < 0 so the force is smooth across the
    event inside a step (the event itself is located, never skipped).
    """
    if contact_mode != CONTACT:
        return 0.0
    ad = abs(d)
    dn = ad ** p[P_N] if ad > 0.0 else 0.0
    if d < 0.0:
        dn = -dn
    return p[P_KC] * dn * (1.0 + p[P_LAM] * d_rate)


@njit(cache=True, _nrt=False)
def kinetic_friction(v, p):
    """Kinetic friction over F0: mu + (1 - mu) exp(-gamma_hat v) for v >= 0.

    Trial stages of a step that crosses the slip -> stick event see v < 0.
    The exponential is kept (analytic, so the error estimate of a step across
    the stop stays honest) down to gamma_hat v = -4, and continued by its
    second-order Taylor polynomial beyond, so a long overshoot cannot blow up.
    The solution beyond the event is never used.
    """
    gv = p[P_GAMMA] * v
    if gv >= -4.0:
        e = math.exp(-gv)
    else:
        u = gv + 4.0  # < 0
        e = 54.598150033144236 * (1.0 - u + 0.5 * u * u)
    return p[P_MU] + (1.0 - p[P_MU]) * e


@njit(cache=True, _nrt=False)
def contact_mode_at_impact(y, p):
    """Contact mode that a closed gap starts in: CLAMPED if the Hunt–Crossley
    damping term 1 + lam d' is not positive (the force would pull), else CONTACT."""
    return CONTACT if 1.0 + p[P_LAM] * (y[V_HAMMER] - y[V_BIT]) > 0.0 else CLAMPED


@njit(cache=True, _nrt=False)
def force_on_bit(y, p, contact_mode):
    """F_d / F0 = spring + damper + contact force on the bit (the drive the friction resists)."""
    return spring_damper_force(y, p) + contact_force_at(y, p, contact_mode)


@njit(cache=True, _nrt=False)
def overlap(y, p):
    """Contact overlap d = x1 - x3 - r (> 0: the gap is closed) [x0]."""
    return y[X_HAMMER] - y[X_BIT] - p[P_R]


@njit(cache=True, _nrt=False)
def spring_damper_force(y, p):
    """F_k / F0 = (x1 - x3) + 2 xi (x2 - x4): spring and damper between hammer and bit."""
    return (y[X_HAMMER] - y[X_BIT]) + 2.0 * p[P_XI] * (y[V_HAMMER] - y[V_BIT])


@njit(cache=True, _nrt=False)
def relative_velocity(y):
    """d' = x2 - x4, hammer velocity relative to the bit [x0 Omega]."""
    return y[V_HAMMER] - y[V_BIT]


@njit(cache=True, _nrt=False)
def contact_force_at(y, p, contact_mode):
    """F_c / F0 at the state ``y`` in ``contact_mode`` (``contact_force``)."""
    return contact_force(overlap(y, p), relative_velocity(y), p, contact_mode)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def link_force(y, nz, sub_out, link_x):
    """Force of the linear subsystem on the hammer, G . z + g1 x1 + g2 x2."""
    f = link_x[0] * y[X_HAMMER] + link_x[1] * y[V_HAMMER]
    for i in range(nz):
        f += sub_out[i] * y[Z0 + i]
    return f


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def sincos_small(d):
    """(sin d, cos d) for |d| <= 0.5 by their Taylor polynomials (error < 1e-19)."""
    d2 = d * d
    sn = d * (1.0 + d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0 + d2 * (
        1.0 / 362880.0 + d2 * (-1.0 / 39916800.0 + d2 * (1.0 / 6227020800.0 + d2 * (
            -1.0 / 1307674368000.0))))))))
    cs = 1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0 + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0 + d2 * (
        -1.0 / 3628800.0 + d2 * (1.0 / 479001600.0 + d2 * (-1.0 / 87178291200.0 + d2 * (
            1.0 / 20922789888000.0))))))))
    return sn, cs


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def harmonic(t, p):
    """Harmonic force / F0 at time t: a sin(eta t + phi)."""
    return p[P_A] * math.sin(p[P_ETA] * t + p[P_PHI])


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def harmonic_shifted(t, dt, s0, c0, p):
    """a sin(eta (t + dt) + phi) from s0, c0 = sin, cos(eta t + phi).

    The RK stages of a step share the step's start phase, so a stage needs
    only the rotation by eta dt (a short polynomial when eta |dt| <= 0.5)
    instead of a full sine with argument reduction.
    """
    d = p[P_ETA] * dt
    if abs(d) <= 0.5:
        sd, cd = sincos_small(d)
        return p[P_A] * (s0 * cd + c0 * sd)
    return p[P_A] * math.sin(p[P_ETA] * (t + dt) + p[P_PHI])


# The vector field is the one piece inlined into its callers at numba's IR level: as a
# call, the Runge-Kutta stages are slower (the mode branches no longer fold).  Every other
# helper is an ordinary call, which LLVM inlines where it pays; IR-inlining them too only
# lengthens the compile.
@njit(cache=True, inline="always", _nrt=False, no_cpython_wrapper=True)
def rhs(t, y, p, mode_s, mode_c, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, out):
    """Vector field of one hybrid mode at time t (see ``rhs_forced``)."""
    rhs_forced(harmonic(t, p), y, p, mode_s, mode_c, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, out)


@njit(cache=True, inline="always", _nrt=False, no_cpython_wrapper=True)
def rhs_forced(fh, y, p, mode_s, mode_c, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, out):
    """Vector field of one hybrid mode; writes dy/dtau into ``out``.

    Parameters
    ----------
    fh : float
        Harmonic force / F0 at the evaluation time, a sin(eta tau + phi)
        (``harmonic``); the field depends on time only through it.
    y : ndarray, shape (Z0 + nz + ne,)
        State.
    p : ndarray, shape (N_P,)
        Kernel parameters (``params.P_*`` layout).
    mode_s, mode_c : int
        Stick/slip mode and contact mode.
    nz, ne : int
        Sizes of the linear subsystem and of the energy block (0 or 4).
    Ap, Ai, Ax : ndarray
        The subsystem matrix A in CSR form (indptr, indices, data).
    sub_in : ndarray, shape (nz, 2)
        Input matrix of (x1, x2) into the subsystem (H in ``LinearSubsystem``).
    sub_out : ndarray, shape (nz,), link_x : ndarray, shape (2,)
        The link force on the hammer, sub_out . z + link_x . (x1, x2)
        (G and g in ``LinearSubsystem``).
    out : ndarray, shape like y
        Derivative (written).
    """
    x2 = y[V_HAMMER]
    x4 = y[V_BIT]
    d = overlap(y, p)
    dd = relative_velocity(y)
    f_spring = spring_damper_force(y, p)
    f_contact = contact_force(d, dd, p, mode_c)
    hammer_drive = p[P_B] + p[P_FEXT] + fh
    if nz > 0:
        hammer_drive += link_force(y, nz, sub_out, link_x)
    out[X_HAMMER] = x2
    out[V_HAMMER] = hammer_drive - f_spring - f_contact
    f_friction = 0.0
    if mode_s == SLIP:
        f_friction = kinetic_friction(x4, p)
        out[X_BIT] = x4
        out[V_BIT] = (f_spring + f_contact - f_friction) / p[P_RHO]
    else:
        out[X_BIT] = 0.0
        out[V_BIT] = 0.0
    for i in range(nz):
        acc = sub_in[i, 0] * y[X_HAMMER] + sub_in[i, 1] * x2
        for k in range(Ap[i], Ap[i + 1]):
            acc += Ax[k] * y[Z0 + Ai[k]]
        out[Z0 + i] = acc
    if ne > 0:
        j = Z0 + nz
        out[j] = hammer_drive * x2
        out[j + 1] = 2.0 * p[P_XI] * dd * dd
        if mode_c != FREE and d > 0.0:
            # dissipated contact power: actual contact power minus elastic power
            out[j + 2] = (f_contact - p[P_KC] * d ** p[P_N]) * dd
        else:
            out[j + 2] = 0.0
        out[j + 3] = f_friction * x4


# ---------------------------------------------------------------------------
# Event indicators
# ---------------------------------------------------------------------------
@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watched(istate, p, out):
    """Event kinds watched in the current mode; returns how many (<= 3) in ``out``."""
    n = 0
    if istate[I_STICK] == STICK:
        if istate[I_BOUNCE] == 0:
            out[n] = EV_SLIP_START
            n += 1
            out[n] = EV_BOUNCE
            n += 1
        else:
            out[n] = EV_BOUNCE_END
            n += 1
    else:
        out[n] = EV_STICK
        n += 1
    if p[P_CONTACT] > 0.0:
        mc = istate[I_CONTACT]
        if mc == FREE:
            out[n] = EV_IMPACT
            n += 1
        else:
            out[n] = EV_SEPARATION
            n += 1
            if p[P_LAM] > 0.0:
                out[n] = EV_CLAMP if mc == CONTACT else EV_UNCLAMP
                n += 1
    return n


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_value(kind, y, p, mode_c):
    """Signed indicator of ``kind``: the event happens when it becomes > 0."""
    if kind == EV_SLIP_START:
        return force_on_bit(y, p, mode_c) - 1.0
    if kind == EV_BOUNCE:
        return -(force_on_bit(y, p, mode_c) + 1.0)
    if kind == EV_BOUNCE_END:
        return force_on_bit(y, p, mode_c) + 1.0
    if kind == EV_STICK:
        return -y[V_BIT]
    if kind == EV_IMPACT:
        return overlap(y, p)
    if kind == EV_SEPARATION:
        return -overlap(y, p)
    if kind == EV_CLAMP:
        return -(1.0 + p[P_LAM] * (y[V_HAMMER] - y[V_BIT]))
    if kind == EV_UNCLAMP:
        return 1.0 + p[P_LAM] * (y[V_HAMMER] - y[V_BIT])
    return -1.0


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_tol(kind, y, p):
    """Round-off level of ``watch_value``: an indicator counts as crossed only above it.

    The indicators subtract positions of order of the penetration (x1 - x3),
    so near a switch their computed value is noise of a few ulp of |x1| + |x3|.
    Without this threshold a separation followed by a re-impact inside the
    next step could chatter on that noise.
    """
    if kind == EV_STICK:
        return 0.0
    if kind == EV_CLAMP or kind == EV_UNCLAMP:
        return 8.0 * EPS * (1.0 + p[P_LAM] * (abs(y[V_HAMMER]) + abs(y[V_BIT])))
    r = p[P_R] if (kind == EV_IMPACT or kind == EV_SEPARATION) else 1.0
    return 8.0 * EPS * (abs(y[X_HAMMER]) + abs(y[X_BIT]) + abs(r))


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def watch_slope(kind, y, f, p, mode_c):
    """Time derivative of ``watch_value`` from the state ``y`` and its derivative ``f``."""
    dd = y[V_HAMMER] - y[V_BIT]
    ddd = f[V_HAMMER] - f[V_BIT]
    if kind == EV_SLIP_START or kind == EV_BOUNCE or kind == EV_BOUNCE_END:
        s = (f[X_HAMMER] - f[X_BIT]) + 2.0 * p[P_XI] * ddd
        if mode_c == CONTACT:
            ad = abs(overlap(y, p))
            if ad > 0.0:
                n = p[P_N]
                dn = ad ** n
                dn1 = n * ad ** (n - 1.0)
                s += p[P_KC] * (dn1 * dd * (1.0 + p[P_LAM] * dd) + dn * p[P_LAM] * ddd)
        return -s if kind == EV_BOUNCE else s
    if kind == EV_STICK:
        return -f[V_BIT]
    if kind == EV_IMPACT:
        return dd
    if kind == EV_SEPARATION:
        return -dd
    if kind == EV_CLAMP:
        return -p[P_LAM] * ddd
    if kind == EV_UNCLAMP:
        return p[P_LAM] * ddd
    return 0.0


# ---------------------------------------------------------------------------
# Runge–Kutta step and dense output (one routine for every tableau)
# ---------------------------------------------------------------------------
@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def rk_stages(t, y, h, rk_a, rk_c, s_from, s_to, stages, ytmp, act, n_act,
              p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """Stages ``s_from <= s < s_to`` of an explicit RK method into ``stages[s]``.

    Returns sin and cos of the forcing phase at ``t`` (for the caller's FSAL stage).
    """
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
        rhs_forced(harmonic_shifted(t, rk_c[s] * h, s0, c0, p), ytmp, p, ms, mc, nz, ne,
                   Ap, Ai, Ax, sub_in, sub_out, link_x, stages[s])
    return s0, c0


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def rk_step(t, y, h, rk_a, rk_b, rk_c, ns, stages, ynew, ytmp, act, n_act,
            p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """One step of any explicit tableau; ``stages[0]`` must hold f(t, y).

    Writes the solution ``ynew`` and the FSAL stage ``stages[ns] = f(t + h, ynew)``.
    """
    s0, c0 = rk_stages(t, y, h, rk_a, rk_c, 1, ns, stages, ytmp, act, n_act, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
    for i in range(y.shape[0]):
        ynew[i] = y[i]
    for q in range(n_act):
        i = act[q]
        acc = 0.0
        for j in range(ns):
            acc += rk_b[j] * stages[j, i]
        ynew[i] = y[i] + h * acc
    rhs_forced(harmonic_shifted(t, h, s0, c0, p), ynew, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, stages[ns])


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def error_norm(y, ynew, h, stages, err_w, err_w3, err_kind, ns, act, n_act, rtol, atol, v4_peak):
    """RMS norm of the embedded error estimate, scaled by atol + rtol |y|.

    The bit velocity x4 is scaled by its peak in the current slip instead of
    its instantaneous value: as the bit decelerates to a stop, a scale that
    shrinks with x4 would demand ever smaller steps for no gain in the
    accuracy of the stop time (which depends on the absolute error of x4).

    ``err_kind`` 1: single estimate with weights E over ns + 1 stages;
    2: Hairer's DOP853 combination of the 5th (err_w) and 3rd (err_w3) order estimates.
    Returns inf when the estimate is not finite (the step is then rejected).
    """
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
def friction_layer_err(h, x4, f4, p, rk_c, err_w, err_w3, e_abs, ns, err_kind, n_act, sc):
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
    rk_c, err_w, err_w3 : ndarray
        Nodes and error weights of the tableau (``advance``).
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
def dense_prepare(t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, interp, ytmp, act, n_act,
                  p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """Extra stages (if the method has them) and nested coefficients ``interp`` of the dense output."""
    if n_ext > ns + 1:
        rk_stages(t, y, h, rk_a, rk_c, ns + 1, n_ext, stages, ytmp, act, n_act, p, ms, mc, nz, ne,
                  Ap, Ai, Ax, sub_in, sub_out, link_x)
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
def interpolant(ready, fixed, t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, stages2, interp, ytmp, act, n_act, istate,
                p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """Make the step's interpolant usable, once per step; returns True.

    Adaptive methods: the dense-output coefficients (and their extra stages).
    The fixed-step method re-steps instead, which needs f(t0, y0) in ``stages2[0]``.
    """
    if ready:
        return True
    if fixed:
        for i in range(y.shape[0]):
            stages2[0, i] = stages[0, i]
    else:
        dense_prepare(t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, interp, ytmp, act, n_act,
                      p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
        istate[I_RHS] += n_ext - ns - 1
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


# how a state inside the current step is evaluated
HOW_DENSE = 0     # the adaptive method's dense output
HOW_RESTEP = 1    # a fresh step of the fixed-step method (the paper's RK4 with bisection)
HOW_STICK = 2     # the closed-form stick solution (constants in ``interp``, see stick_prepare)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_closed_form_ok(p):
    """The stuck hammer is an underdamped forced linear oscillator off resonance."""
    eta = p[P_ETA]
    xi = p[P_XI]
    den = (1.0 - eta * eta) ** 2 + (2.0 * xi * eta) ** 2
    return xi < 0.99 and den > 1e-12


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_prepare(t0, y0, p, interp):
    """Constants of the exact stick solution from (t0, y0) into ``interp[0:3, 0:4]``.

    While the bit sticks and the gap is open, the hammer obeys
    x1'' + 2 xi x1' + x1 = x3 + b + f_ext + a sin(eta t + phi): a forced damped
    oscillator whose solution is a particular harmonic plus a decaying
    homogeneous part.
    """
    th = p[P_ETA] * t0 + p[P_PHI]
    stick_prepare_phase(t0, y0, p, interp, math.sin(th), math.cos(th))


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_prepare_phase(t0, y0, p, interp, sn, cs):
    """``stick_prepare`` given sn, cs = sin, cos(eta t0 + phi)."""
    xi = p[P_XI]
    eta = p[P_ETA]
    a = p[P_A]
    den = (1.0 - eta * eta) ** 2 + (2.0 * xi * eta) ** 2
    P = a * (1.0 - eta * eta) / den
    Q = -a * 2.0 * xi * eta / den
    c = y0[X_BIT] + p[P_B] + p[P_FEXT]
    u0 = y0[X_HAMMER] - c - (P * sn + Q * cs)
    v0 = y0[V_HAMMER] - eta * (P * cs - Q * sn)
    wd = math.sqrt(1.0 - xi * xi)
    interp[2, 0] = sn
    interp[2, 1] = cs
    interp[0, 0] = t0
    interp[0, 1] = c
    interp[0, 2] = P
    interp[0, 3] = Q
    interp[1, 0] = u0
    interp[1, 1] = (v0 + xi * u0) / wd
    interp[1, 2] = v0
    interp[1, 3] = wd


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_state(tq, y0, interp, p, out):
    """Exact stick state at time tq from the constants of ``stick_prepare``.

    Returns sin(eta tq + phi), from which ``stick_rate`` gives the derivative.
    """
    s = tq - interp[0, 0]
    th = p[P_ETA] * tq + p[P_PHI]
    sn = math.sin(th)
    wd = interp[1, 3]
    stick_combine(y0, interp, p, sn, math.cos(th), math.exp(-p[P_XI] * s), math.cos(wd * s), math.sin(wd * s), out)
    return sn


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_combine(y0, interp, p, sn, cs, e, cw, sw, out):
    """Stick state from the constants in ``interp``, the forcing phase (sn, cs) at the target
    time and the homogeneous factors e = exp(-xi s), cw, sw = cos, sin(w_d s)."""
    xi = p[P_XI]
    P = interp[0, 2]
    Q = interp[0, 3]
    u0 = interp[1, 0]
    Bc = interp[1, 1]
    wd = interp[1, 3]
    for i in range(y0.shape[0]):
        out[i] = y0[i]
    out[X_HAMMER] = interp[0, 1] + P * sn + Q * cs + e * (u0 * cw + Bc * sw)
    out[V_HAMMER] = p[P_ETA] * (P * cs - Q * sn) + e * (interp[1, 2] * cw - (xi * Bc + wd * u0) * sw)
    out[V_BIT] = 0.0


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_chunk_consts(h_chunk, p, out):
    """Constants of a stick chunk of length h_chunk: exp(-xi h_chunk), cos and sin(w_d h_chunk), sin and cos(eta h_chunk)."""
    xi = p[P_XI]
    wd = math.sqrt(1.0 - xi * xi)
    out[0] = math.exp(-xi * h_chunk)
    out[1] = math.cos(wd * h_chunk)
    out[2] = math.sin(wd * h_chunk)
    out[3] = math.sin(p[P_ETA] * h_chunk)
    out[4] = math.cos(p[P_ETA] * h_chunk)
    out[5] = h_chunk


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_state_chunk(t1, y0, interp, p, chunk_c, out):
    """``stick_state`` at t1 = t0 + h_chunk for the chunk length h_chunk of ``stick_chunk_consts``.

    The transcendentals of a full chunk are the same every time; only the
    rounding of t1 - t0 against h_chunk (a few ulp of t) is corrected, to first
    order, so the state belongs to the clock's t1 exactly.  Returns
    sin and cos of eta t1 + phi (the next chunk starts from them).
    """
    xi = p[P_XI]
    eta = p[P_ETA]
    dlt = (t1 - interp[0, 0]) - chunk_c[5]
    wd = interp[1, 3]
    e = chunk_c[0] * (1.0 - xi * dlt)
    cw = chunk_c[1] - chunk_c[2] * (wd * dlt)
    sw = chunk_c[2] + chunk_c[1] * (wd * dlt)
    snH = chunk_c[3] + chunk_c[4] * (eta * dlt)
    csH = chunk_c[4] - chunk_c[3] * (eta * dlt)
    s0 = interp[2, 0]
    c0 = interp[2, 1]
    sn = s0 * csH + c0 * snH
    cs = c0 * csH - s0 * snH
    stick_combine(y0, interp, p, sn, cs, e, cw, sw, out)
    return sn, cs


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def stick_rate(y, sn, p, out):
    """Derivative of a stick state ``y`` (free gap) whose forcing phase has sine ``sn``."""
    for i in range(y.shape[0]):
        out[i] = 0.0
    out[X_HAMMER] = y[V_HAMMER]
    out[V_HAMMER] = p[P_B] + p[P_FEXT] + p[P_A] * sn - spring_damper_force(y, p)  # x4 = 0 in stick


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def state_at(tq, t0, y0, h, how, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, out,
             p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """State at time ``tq`` inside the current step (``how``: HOW_*).

    Adaptive methods evaluate their dense output.  The fixed-step method (the
    paper's RK4 with bisection) re-integrates one step of length tq - t0
    (``stages2[0]`` must hold f(t0, y0)).  A stick chunk evaluates the exact solution.
    """
    if how == HOW_RESTEP:
        rk_step(t0, y0, tq - t0, rk_a, rk_b, rk_c, ns, stages2, out, ytmp, act, n_act,
                p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
    elif how == HOW_STICK:
        stick_state(tq, y0, interp, p, out)
    else:
        x = (tq - t0) / h
        dense_eval(x, y0, interp, act, n_act, out)


# ---------------------------------------------------------------------------
# Reset map
# ---------------------------------------------------------------------------
@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def apply_event(kind, y, istate, fstate, p):
    """Apply the reset map of ``kind`` at the event state ``y`` (modified in place).

    Returns the kind actually taken (slip -> stick becomes EV_SLIP_ON when the
    drive still exceeds the static threshold).
    """
    mc = istate[I_CONTACT]
    if kind == EV_SLIP_START:
        istate[I_STICK] = SLIP
        y[V_BIT] = 0.0
        fstate[F_V4_PEAK] = 0.0
        fstate[F_X3_SLIP] = y[X_BIT]
    elif kind == EV_STICK:
        y[V_BIT] = 0.0
        # the drift only moves forward: no round-off step backwards
        if y[X_BIT] < fstate[F_X3_SLIP]:
            y[X_BIT] = fstate[F_X3_SLIP]
        if force_on_bit(y, p, mc) <= 1.0:
            istate[I_STICK] = STICK
            if force_on_bit(y, p, mc) < -1.0:
                istate[I_BOUNCE] = 1
                istate[I_COUNT0 + EV_BOUNCE] += 1
        else:
            kind = EV_SLIP_ON
    elif kind == EV_IMPACT:
        istate[I_CONTACT] = contact_mode_at_impact(y, p)
        fstate[F_IMPACT_V] = y[V_HAMMER] - y[V_BIT]
        fstate[F_PEAK] = 0.0
    elif kind == EV_SEPARATION:
        istate[I_CONTACT] = FREE
        if fstate[F_PEAK] > fstate[F_PEAK_RUN]:
            fstate[F_PEAK_RUN] = fstate[F_PEAK]
    elif kind == EV_CLAMP:
        istate[I_CONTACT] = CLAMPED
    elif kind == EV_UNCLAMP:
        istate[I_CONTACT] = CONTACT
    elif kind == EV_BOUNCE:
        istate[I_BOUNCE] = 1
    elif kind == EV_BOUNCE_END:
        istate[I_BOUNCE] = 0
    istate[I_COUNT0 + kind] += 1
    return kind


@njit(cache=True, inline="always", _nrt=False, no_cpython_wrapper=True)
def plain(k, n):
    """The integer constant ``k`` as a plain int64 (``n``: any integer variable).

    numba compiles a callee once per literal value of an argument; a constant
    passed through ``plain`` lets every caller share one compiled callee
    (fewer specialisations to compile, the same results).
    """
    return k + 0 * n


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


# ---------------------------------------------------------------------------
# Event detection and localisation
# ---------------------------------------------------------------------------
@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def localise_bisect(kind, ta, tb, t0, y0, tol, wtol, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys, act, n_act,
                    p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """The paper's localisation for the fixed-step method: bisection down to ``tol``.

    Each trial state is a fresh step of the method from (t0, y0) (``stages2[0]`` must
    hold f(t0, y0)).  Returns the end of the final bracket, where w > 0: after
    the reset the event cannot re-trigger.  (Adaptive methods use
    ``localise_newton``.)
    """
    for it in range(200):
        if tb - ta <= tol:
            break
        tm = 0.5 * (ta + tb)
        rk_step(t0, y0, tm - t0, rk_a, rk_b, rk_c, ns, stages2, ys, ytmp, act, n_act,
                p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
        if watch_value(kind, ys, p, mc) - wtol > 0.0:
            tb = tm
        else:
            ta = tm
    return tb


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def state_rate_at(tq, t0, y0, h, how, interp, act, n_act, ys, fs, p):
    """State and its rate at ``tq``: exact stick solution or the dense output."""
    if how == HOW_STICK:
        sn = stick_state(tq, y0, interp, p, ys)
        stick_rate(ys, sn, p, fs)
    else:
        dense_eval_rate((tq - t0) / h, y0, interp, act, n_act, h, ys, fs)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def localise_newton(kind, ta, tb, t0, y0, h, how, wtol, interp, act, n_act, ys, fs, p, mc):
    """Event time in (ta, tb] where w(ta) <= wtol < w(tb), by safeguarded Newton.

    Works on the exact stick solution or on the dense output; both give the
    indicator's slope along the curve at no extra cost, so
    Newton (kept inside the bracket, bisecting when it leaves it or every
    eighth step) needs a handful of evaluations where false position needs
    about twenty.  Returns the end of the final bracket, where w > 0, once
    the bracket is a few ulp wide.
    """
    state_rate_at(tb, t0, y0, h, how, interp, act, n_act, ys, fs, p)
    wb = watch_value(kind, ys, p, mc) - wtol
    sb = watch_slope(kind, ys, fs, p, mc)
    state_rate_at(ta, t0, y0, h, how, interp, act, n_act, ys, fs, p)
    wa = watch_value(kind, ys, p, mc) - wtol
    # start from the end whose Newton step stays inside the bracket, else the secant
    t = ta - wa * (tb - ta) / (wb - wa) if wb > wa else 0.5 * (ta + tb)
    if sb > 0.0:
        tn = tb - wb / sb
        if ta < tn < tb:
            t = tn
    if not (ta < t < tb):
        t = 0.5 * (ta + tb)
    for it in range(100):
        if tb - ta <= 4.0 * EPS * max(abs(tb), 1.0):
            break
        state_rate_at(t, t0, y0, h, how, interp, act, n_act, ys, fs, p)
        w = watch_value(kind, ys, p, mc) - wtol
        if w > 0.0:
            tb = t
        else:
            ta = t
        if tb - ta <= 4.0 * EPS * max(abs(tb), 1.0):
            break
        sl = watch_slope(kind, ys, fs, p, mc)
        ulp2 = 2.0 * EPS * max(abs(t), 1.0)
        tn = t - w / sl if sl > 0.0 else 0.5 * (ta + tb)
        if w > 0.0 and tn > t - ulp2:
            tn = t - ulp2     # converged from above: probe just below
        elif w <= 0.0 and tn < t + ulp2:
            tn = t + ulp2     # converged from below: probe just above
        if not (ta < tn < tb) or it % 8 == 7:
            tn = 0.5 * (ta + tb)
        t = tn
    return tb


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def find_extremum(kind, t0, t1, y0, h, how, interp, act, n_act, ys, fs,
                  p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """Time in (t0, t1) where the slope of w changes from + to - (a local max of w)."""
    ta = t0
    tb = t1
    for it in range(60):
        tm = 0.5 * (ta + tb)
        if how == HOW_STICK:
            stick_state(tm, y0, interp, p, ys)
        else:
            dense_eval((tm - t0) / h, y0, interp, act, n_act, ys)
        rhs(tm, ys, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, fs)
        if watch_slope(kind, ys, fs, p, mc) > 0.0:
            ta = tm
        else:
            tb = tm
        if tb - ta <= 1e-9 * (t1 - t0):
            break
    return 0.5 * (ta + tb)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def sign_change(kind, y, ynew, f0, f1, p, mc, w0, wtol, h, graze_ok):
    """Sign-change detection of one indicator over a step.

    Returns 1 when the indicator ends above its round-off level (a crossing
    inside the step), 2 when its slope turns from + to - with a cheap
    Hermite estimate of the maximum near zero (a possible grazing extremum,
    only if ``graze_ok``), else 0.
    """
    w1 = watch_value(kind, ynew, p, mc)
    if w1 > wtol:
        return 1
    if not graze_ok:
        return 0
    s0 = watch_slope(kind, y, f0, p, mc)
    s1 = watch_slope(kind, ynew, f1, p, mc)
    if s0 > 0.0 and s1 < 0.0 and hermite_peak(w0, w1, s0 * h, s1 * h) > -0.1 * (
            abs(w0) + abs(w1) + abs(s0 * h) + abs(s1 * h)):
        return 2
    return 0


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def locate_event(kind, code, t0, t1, y0, h, how, bisect_tol, graze, wtol, interp, act, n_act, rk_a, rk_b, rk_c, ns,
                 stages2, ytmp, ys, fscr, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x):
    """Event time of one indicator in (t0, t1] for a ``sign_change`` code, or -1.

    A grazing candidate (code 2) counts only if the indicator's maximum inside
    the step exceeds max(graze, wtol); the event is then localised between the
    step start and that maximum.
    """
    tb = t1
    if code == 2:
        tm = find_extremum(kind, t0, t1, y0, h, how, interp, act, n_act, ys, fscr,
                           p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
        state_at(tm, t0, y0, h, how, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                 p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
        if watch_value(kind, ys, p, mc) <= max(graze, wtol):
            return -1.0
        tb = tm
    if how == HOW_STICK or how == HOW_DENSE:
        return localise_newton(kind, t0, tb, t0, y0, h, how, wtol, interp, act, n_act, ys, fscr, p, mc)
    return localise_bisect(kind, t0, tb, t0, y0, bisect_tol, wtol, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys, act, n_act,
                           p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def peak_in_step(t0, t1, y0, h, interp, act, n_act, ys, fs, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, fstate):
    """Contact force at the deepest penetration inside a step (d' changes sign)."""
    tm = find_extremum(plain(EV_IMPACT, n_act), t0, t1, y0, h, plain(HOW_DENSE, n_act), interp, act, n_act, ys, fs,
                       p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
    dense_eval((tm - t0) / h, y0, interp, act, n_act, ys)
    f_contact = contact_force_at(ys, p, mc)
    if f_contact > fstate[F_PEAK]:
        fstate[F_PEAK] = f_contact


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def drive_end(y0, y1, f0, f1, h, p, mc, fstate):
    """The drive on the bit at the end of an accepted step into ``fstate[F_DRIVE_MIN]``.

    Returns True when the step holds an interior minimum worth locating: the
    drive's rate turns from - to + and the cubic Hermite estimate of that
    minimum comes near the lowest drive so far (``drive_inside`` locates it).
    """
    d0 = force_on_bit(y0, p, mc)
    d1 = force_on_bit(y1, p, mc)
    if d1 < fstate[F_DRIVE_MIN]:
        fstate[F_DRIVE_MIN] = d1
    s0 = watch_slope(EV_SLIP_START, y0, f0, p, mc) * h
    s1 = watch_slope(EV_SLIP_START, y1, f1, p, mc) * h
    if not (s0 < 0.0 and s1 > 0.0):
        return False
    low = -hermite_peak(-d0, -d1, -s0, -s1)
    return low <= fstate[F_DRIVE_MIN] + DRIVE_GATE * (abs(s0) + abs(s1))


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def drive_inside(t0, t1, y0, h, how, interp, act, n_act, ys, fs,
                 p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, fstate):
    """The drive's minimum inside a step (its rate turns from - to +) into ``fstate[F_DRIVE_MIN]``,
    on the dense output or the exact stick solution."""
    tm = find_extremum(plain(EV_BOUNCE, n_act), t0, t1, y0, h, how, interp, act, n_act, ys, fs,
                       p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
    if how == HOW_STICK:
        stick_state(tm, y0, interp, p, ys)
    else:
        dense_eval((tm - t0) / h, y0, interp, act, n_act, ys)
    d = force_on_bit(ys, p, mc)
    if d < fstate[F_DRIVE_MIN]:
        fstate[F_DRIVE_MIN] = d


@njit(cache=True, _nrt=False, no_cpython_wrapper=True)
def hermite_peak(w0, w1, m0, m1):
    """Maximum over [0, 1] of the cubic Hermite interpolant of (w0, m0), (w1, m1).

    A cheap gate: the exact (dense-output) search for a grazing extremum runs
    only when this estimate comes near zero.
    """
    a = 6.0 * w0 + 3.0 * m0 - 6.0 * w1 + 3.0 * m1
    b = -6.0 * w0 - 4.0 * m0 + 6.0 * w1 - 2.0 * m1
    c = m0
    best = max(w0, w1)
    if a == 0.0:
        roots0 = -c / b if b != 0.0 else -1.0
        roots1 = -1.0
    else:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            return best
        sq = math.sqrt(disc)
        roots0 = (-b - sq) / (2.0 * a)
        roots1 = (-b + sq) / (2.0 * a)
    for x in (roots0, roots1):
        if 0.0 < x < 1.0:
            x2 = x * x
            x3 = x2 * x
            v = ((2 * x3 - 3 * x2 + 1) * w0 + (x3 - 2 * x2 + x) * m0
                 + (-2 * x3 + 3 * x2) * w1 + (x3 - x2) * m1)
            if v > best:
                best = v
    return best


# ---------------------------------------------------------------------------
# Recording
# ---------------------------------------------------------------------------
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
def record_until(t_stop, y_stop, t0, y0, h, how, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                 p, istate, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, opts, poin, samp_t, samp):
    """Record Poincaré samples and requested samples with times in (t0, t_stop]."""
    tol = 8.0 * EPS * max(abs(t_stop), 1.0)
    ms = istate[I_STICK]
    mc = istate[I_CONTACT]
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
            state_at(tk, t0, y0, h, how, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                     p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
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
            state_at(max(tj, t0), t0, y0, h, how, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                     p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
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


# ---------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def advance(y, istate, fstate, t_end, p, opts,
            rk_a, rk_b, rk_c, err_w, err_w3, dense_w, ns, err_kind, err_exp,
            Ap, Ai, Ax, sub_in, sub_out, link_x, ne,
            poin, samp_t, samp, log):
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
    rk_a, rk_b, rk_c, err_w, err_w3, dense_w : ndarray
        Tableau (``tableaux``: A, B, C, E, E3, W): stage coefficients (n_ext, n_ext),
        weights (ns,), nodes (n_ext,), error weights (ns + 1,) of the 5th- and
        3rd-order estimates, nested dense-output weights (nF, n_ext).
    ns, err_kind : int
        Number of stages of the step; error-estimate kind (0 = fixed step).
    err_exp : float
        Controller exponent 1 / (error order + 1).
    Ap, Ai, Ax, sub_in, sub_out, link_x : ndarray
        Linear subsystem (see ``rhs_forced``); nz = sub_in.shape[0] may be 0.
    ne : int
        4 to accumulate energies, else 0.
    poin : ndarray, shape (n_poin, 5)
        Poincaré samples [tau, x1, x2, x3, x4] at O_POIN_T0 + k O_POIN_DT.
    samp_t : ndarray, shape (n_samp,)
        Requested sample times, sorted.
    samp : ndarray, shape (n_samp, N_SAMPLE_COLS)
        Samples (written).
    log : ndarray, shape (cap, N_LOG_COLS)
        Event log (written while rows remain; cap 0 disables it).

    Returns
    -------
    status : int
        ``ST_*`` code.
    """
    n = y.shape[0]
    nz = sub_in.shape[0]
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
    cf_chunk = min(2.0 * math.pi / p[P_ETA], 2.0 * math.pi / math.sqrt(max(1.0 - p[P_XI] * p[P_XI], 1e-300))) / 8.0
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
    d_start = force_on_bit(y, p, mc)
    if d_start < fstate[F_DRIVE_MIN]:
        fstate[F_DRIVE_MIN] = d_start
    rhs(t, y, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, stages[0])
    istate[I_RHS] += 1
    steps_here = 0
    refine = 0
    sc_t = math.nan  # time whose forcing phase (sc_s, sc_c) a full stick chunk left behind
    sc_s = 0.0
    sc_c = 0.0

    while True:
        remaining = t_end - t
        # a sliver below the time resolution is no dynamics: done
        if remaining <= 10.0 * EPS * max(abs(t_end), 1.0):
            break
        if log_cap > 0 and istate[I_NLOG] >= log_cap:
            fstate[F_T] = t
            fstate[F_H] = h
            return ST_LOG_FULL
        if maxsteps > 0 and steps_here >= maxsteps:
            fstate[F_T] = t
            fstate[F_H] = h
            return ST_MAX_STEPS

        # -- an indicator already positive at the start: immediate event --------
        nw = watched(istate, p, kinds)
        immediate = -1
        for q in range(nw):
            w0s[q] = watch_value(kinds[q], y, p, mc)
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
            if h_chunk >= remaining or remaining - h_chunk < 1e4 * EPS * max(abs(t), 1.0):
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
                return ST_NONFINITE
            stick_rate(ynew, sn1, p, fs)  # = rhs(t1, ynew) in stick with the gap open
            istate[I_RHS] += 1
            istate[I_STEPS] += 1
            steps_here += 1
            if count_step(t1, period, istate, stepcap):
                fstate[F_T] = t
                fstate[F_H] = h
                return ST_STEP_STORM
            # (this loop mirrors the RK step's detection below on purpose: one loop shared
            # by both paths measured 5-7 % slower, the per-path constants no longer fold)
            for q in range(nw):
                kd = kinds[q]
                code = sign_change(kd, y, ynew, stages[0], fs, p, mc, w0s[q], wtols[q], h_chunk, graze_stick)
                if code == 0:
                    continue
                te = locate_event(kd, code, t, t1, y, h_chunk, how_stick, opts[O_BISECT], graze, wtols[q],
                                  interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys, ytmp,
                                  p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                if te > 0.0 and (hit_kind < 0 or te < t_hit):
                    hit_kind = kd
                    t_hit = te
            if hit_kind < 0:
                if drive_end(y, ynew, stages[0], fs, h_chunk, p, mc, fstate):
                    drive_inside(t, t1, y, h_chunk, how_stick, interp, act, n_act, ys, ytmp,
                                 p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, fstate)
                if needs_record(t1, istate, opts, poin, samp_t):
                    record_until(t1, ynew, t, y, h_chunk, how_stick, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                                 p, istate, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, opts, poin, samp_t, samp)
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
            d_hit = force_on_bit(ys, p, mc)
            if d_hit < fstate[F_DRIVE_MIN]:
                fstate[F_DRIVE_MIN] = d_hit
            if needs_record(t_hit, istate, opts, poin, samp_t):
                record_until(t_hit, ys, t, y, h_chunk, how_stick, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ynew,
                             p, istate, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, opts, poin, samp_t, samp)
            for i in range(n):
                y[i] = ys[i]
            t = t_hit
        elif immediate < 0:
            # -- one accepted step -------------------------------------------
            if fixed:
                h = min(opts[O_HFIXED], remaining)
                rk_step(t, y, h, rk_a, rk_b, rk_c, ns, stages, ynew, ytmp, act, n_act,
                        p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                istate[I_RHS] += ns
                for i in range(n):
                    if not math.isfinite(ynew[i]):
                        fstate[F_T] = t
                        return ST_NONFINITE
            else:
                hmin = 10.0 * EPS * max(abs(t), 1.0)
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
                        hcap = 1.5 / math.sqrt(kcl * minv + 1e-300)
                        if h > hcap:
                            h = hcap
                if ms == SLIP and stages[0, V_BIT] < 0.0 and y[V_BIT] > 0.0:
                    # the bit decelerates to a stop: do not step far past the
                    # predicted stop, where the friction law is extrapolated
                    t_stop = -y[V_BIT] / stages[0, V_BIT]
                    if h > 1.3 * t_stop:
                        h = max(1.3 * t_stop, 1e-3 * h)
                while True:
                    if h > hmax:
                        h = hmax
                    if h >= remaining or (not rejected and remaining - h < 1e3 * hmin):
                        # never leave a sliver behind; after a rejection the step only
                        # shrinks (snapping back to the whole remainder would retry the
                        # rejected step forever when hmin is coarse, e.g. at a late start)
                        h = remaining
                    if h < hmin:
                        fstate[F_T] = t
                        fstate[F_H] = h
                        return ST_STEP_TOO_SMALL
                    rk_step(t, y, h, rk_a, rk_b, rk_c, ns, stages, ynew, ytmp, act, n_act,
                            p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                    istate[I_RHS] += ns
                    err = error_norm(y, ynew, h, stages, err_w, err_w3, err_kind, ns, act, n_act, rtol, atol,
                                     fstate[F_V4_PEAK])
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
                        ef, dlog = friction_layer_err(h_next, ynew[V_BIT], stages[ns, V_BIT], p, rk_c, err_w, err_w3, e_abs, ns,
                                                      err_kind, n_act, sc4)
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
                fstate[F_H] = h
                return ST_STEP_STORM

            # -- detection over [t, t1] ------------------------------------
            dense_ok = no_act > 0  # False, as a plain bool (see ``plain``)
            for q in range(nw):
                kd = kinds[q]
                code = sign_change(kd, y, ynew, stages[0], stages[ns], p, mc, w0s[q], wtols[q], h, not fixed)
                if code == 0:
                    continue
                dense_ok = interpolant(dense_ok, fixed, t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, stages2, interp, ytmp, act, n_act,
                                       istate, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                te = locate_event(kd, code, t, t1, y, h, how_rk, opts[O_BISECT], graze, wtols[q],
                                  interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys, fs,
                                  p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                if te > 0.0 and (hit_kind < 0 or te < t_hit):
                    hit_kind = kd
                    t_hit = te
                    wtol_hit = wtols[q]

            if hit_kind < 0:
                # -- no event: record and accept ----------------------------
                if needs_record(t1, istate, opts, poin, samp_t):
                    dense_ok = interpolant(dense_ok, fixed, t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, stages2, interp, ytmp, act, n_act,
                                       istate, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                    record_until(t1, ynew, t, y, h, how_rk, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                                 p, istate, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, opts, poin, samp_t, samp)
                if mc == CONTACT:
                    if not fixed and y[V_HAMMER] - y[V_BIT] > 0.0 and ynew[V_HAMMER] - ynew[V_BIT] <= 0.0:
                        dense_ok = interpolant(dense_ok, fixed, t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, stages2, interp, ytmp, act, n_act,
                                       istate, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                        peak_in_step(t, t1, y, h, interp, act, n_act, ys, fs, p, ms, mc, nz, ne,
                                     Ap, Ai, Ax, sub_in, sub_out, link_x, fstate)
                    f_contact1 = contact_force_at(ynew, p, mc)
                    if f_contact1 > fstate[F_PEAK]:
                        fstate[F_PEAK] = f_contact1
                if drive_end(y, ynew, stages[0], stages[ns], h, p, mc, fstate) and not fixed:
                    dense_ok = interpolant(dense_ok, fixed, t, y, ynew, h, rk_a, rk_c, dense_w, ns, n_ext, stages, stages2, interp, ytmp, act, n_act,
                                           istate, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
                    drive_inside(t, t1, y, h, how_dense, interp, act, n_act, ys, fs,
                                 p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, fstate)
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
            rk_step(t, y, t_hit - t, rk_a, rk_b, rk_c, ns, stages2, ys, ytmp, act, n_act,
                    p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
            istate[I_RHS] += ns
            confirmed = fixed or watch_value(hit_kind, ys, p, mc) > wtol_hit
            if not confirmed and refine >= 2:
                # give up refining: take the dense-output state, crossed by construction
                state_at(t_hit, t, y, h, how_dense, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                         p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
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
                peak_in_step(t, t_hit, y, h, interp, act, n_act, ynew, fs, p, ms, mc, nz, ne,
                             Ap, Ai, Ax, sub_in, sub_out, link_x, fstate)
            d_hit = force_on_bit(ys, p, mc)
            if d_hit < fstate[F_DRIVE_MIN]:
                fstate[F_DRIVE_MIN] = d_hit
            if needs_record(t_hit, istate, opts, poin, samp_t):
                record_until(t_hit, ys, t, y, h, how_rk, interp, act, n_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ynew,
                             p, istate, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, opts, poin, samp_t, samp)
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
        d_reset = force_on_bit(y, p, istate[I_CONTACT])
        if d_reset < fstate[F_DRIVE_MIN]:
            fstate[F_DRIVE_MIN] = d_reset
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
            fstate[F_H] = h
            return ST_EVENT_STORM
        ms = istate[I_STICK]
        mc = istate[I_CONTACT]
        if not fixed and fstate[F_H_MODE + step_slot(ms, mc)] > 0.0:
            h = fstate[F_H_MODE + step_slot(ms, mc)]
        n_act = set_active(istate, n, act)
        rhs(t, y, p, ms, mc, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, stages[0])
        istate[I_RHS] += 1

    # final: samples that sit exactly on t_end
    t = t_end
    fstate[F_T] = t
    fstate[F_H] = h
    if needs_record(t, istate, opts, poin, samp_t):
        for i in range(n):
            ynew[i] = y[i]
        record_until(t, ynew, t, y, 1.0, how_dense, interp, act, no_act, rk_a, rk_b, rk_c, ns, stages2, ytmp, ys,
                     p, istate, nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x, opts, poin, samp_t, samp)
    return ST_DONE


# ---------------------------------------------------------------------------
# Entry points.  numba compiles each on its first call (or loads it from the
# on-disk cache), so a scene compiles only the specialisation it uses:
#
# * ``advance_hammer``: DOP853, no linear subsystem, no energy block -- the
#   tableau and the empty subsystem are constants, folded into the code (a
#   plain ``simulate``, the FMU, the sweeps);
# * ``advance``: every other combination (DP54, RK4, the energy block, the
#   linear subsystem of the monolithic reference), compiled once for all of
#   them, the first time one is used.
#
# Fewer arguments also make a call from Python cheaper (the FMU calls once
# per communication step).  ``advance_hammer`` is ``advance`` with those
# arguments bound as constants (``partial.bind``), compiled as one function:
# the same folded code as an IR-inlined call, without numba re-typing a copy
# of the driver's IR.
# ---------------------------------------------------------------------------
from . import tableaux as _T  # noqa: E402
from .partial import bind  # noqa: E402

_NO_AP = np.zeros(1, dtype=np.int64)
_NO_AI = np.zeros(0, dtype=np.int64)
_NO_AX = np.zeros(0)
_NO_H = np.zeros((0, 2))
_NO_G = np.zeros(0)
_NO_G2 = np.zeros(2)


#: ``advance`` with DOP853, no linear subsystem and no energy block, all bound as constants
advance_hammer = njit(cache=True, nogil=True)(bind(
    advance, "advance_hammer",
    **dict(zip(("rk_a", "rk_b", "rk_c", "err_w", "err_w3", "dense_w", "ns", "err_kind", "err_exp"),
               _T.METHODS["dop853"])),
    Ap=_NO_AP, Ai=_NO_AI, Ax=_NO_AX, sub_in=_NO_H, sub_out=_NO_G, link_x=_NO_G2, ne=0))
