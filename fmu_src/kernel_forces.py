"""The force laws and the vector field of the hammer–bit–rock model in one hybrid mode (numba kernels).

Friction (``kinetic_friction``), contact (``contact_force``), the spring and
damper between hammer and bit, the harmonic forcing and the right-hand side
``rhs`` with the optional linear subsystem (layouts: :mod:`.kernel_layouts`).
"""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_layouts import (CLAMPED, CONTACT, EXP_FRICTION_TAYLOR, FREE, FRICTION_TAYLOR_FROM, P_A, P_B,
                             P_ETA, P_FEXT, P_GAMMA, P_KC, P_LAM, P_MU, P_N, P_PHI, P_R, P_RHO, P_XI, SLIP,
                             V_BIT, V_HAMMER, X_BIT, X_HAMMER, Z0)



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
    return p[P_KC] * dn * contact_damping_factor(d_rate, p)


# The contact law's derivatives live here, beside the law: the step-size cap, the
# event slopes and the variational equations call them, so a new law is one file.

@njit(cache=True, _nrt=False)
def contact_damping_factor(d_rate, p):
    """The Hunt–Crossley damping factor 1 + lam d' (the force pulls where it is negative:
    the CLAMPED mode and its events watch its sign)."""
    return 1.0 + p[P_LAM] * d_rate


@njit(cache=True, _nrt=False)
def contact_damping_factor_rate(d_accel, p):
    """Time derivative of ``contact_damping_factor``, lam d''."""
    return p[P_LAM] * d_accel


@njit(cache=True, _nrt=False)
def contact_stiffness(d, d_rate, p):
    """dF_c/dd of ``contact_force`` in CONTACT: kc n |d|^(n-1) (1 + lam d'), 0 at d = 0
    (for n > 1 the force is C^1 there)."""
    ad = abs(d)
    if ad > 0.0:
        n = p[P_N]
        return p[P_KC] * n * ad ** (n - 1.0) * contact_damping_factor(d_rate, p)
    return 0.0


@njit(cache=True, _nrt=False)
def contact_damping(d, p):
    """dF_c/dd' of ``contact_force`` in CONTACT: kc d^n lam (the power extended oddly)."""
    return p[P_KC] * math.copysign(abs(d) ** p[P_N], d) * p[P_LAM]


@njit(cache=True, _nrt=False)
def contact_force_rate(d, d_rate, d_accel, p):
    """dF_c/dt of ``contact_force`` in CONTACT along a motion with overlap ``d``, its rate d'
    and acceleration d'': kc (n |d|^(n-1) d' (1 + lam d') + |d|^n lam d'')."""
    ad = abs(d)
    if ad > 0.0:
        n = p[P_N]
        dn = ad ** n
        dn1 = n * ad ** (n - 1.0)
        return p[P_KC] * (dn1 * d_rate * contact_damping_factor(d_rate, p) + dn * p[P_LAM] * d_accel)
    return 0.0


@njit(cache=True, _nrt=False)
def contact_elastic_force(d, p):
    """The elastic part kc d^n of ``contact_force`` for d > 0 (what the contact stores)."""
    return p[P_KC] * d ** p[P_N]


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
    if gv >= FRICTION_TAYLOR_FROM:
        e = math.exp(-gv)
    else:
        u = gv - FRICTION_TAYLOR_FROM  # < 0
        e = EXP_FRICTION_TAYLOR * (1.0 - u + 0.5 * u * u)
    return p[P_MU] + (1.0 - p[P_MU]) * e


@njit(cache=True, _nrt=False)
def contact_mode_at_impact(y, p):
    """Contact mode that a closed gap starts in: CLAMPED if the Hunt–Crossley
    damping term 1 + lam d' is not positive (the force would pull), else CONTACT."""
    return CONTACT if contact_damping_factor(y[V_HAMMER] - y[V_BIT], p) > 0.0 else CLAMPED


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
def rhs(t, y, field, out):
    """Vector field of one hybrid mode at time t (see ``rhs_forced``)."""
    rhs_forced(harmonic(t, field[0]), y, field, out)


@njit(cache=True, inline="always", _nrt=False, no_cpython_wrapper=True)
def rhs_forced(fh, y, field, out):
    """Vector field of one hybrid mode; writes dy/dtau into ``out``.

    Parameters
    ----------
    fh : float
        Harmonic force / F0 at the evaluation time, a sin(eta tau + phi)
        (``harmonic``); the field depends on time only through it.
    y : ndarray, shape (Z0 + nz + ne,)
        State.
    field : tuple
        ``(p, mode_s, mode_c, sub)``: the kernel parameters (``P_*`` layout), the
        stick/slip and contact modes and the linear subsystem ``sub = (nz, ne, Ap,
        Ai, Ax, sub_in, sub_out, link_x)``: its size nz and the size ne of the
        energy block (0 or 4); the matrix A in CSR form (indptr, indices, data);
        ``sub_in``, shape (nz, 2), the input of (x1, x2) into the subsystem (H in
        ``LinearSubsystem``); the link force on the hammer, sub_out . z + link_x .
        (x1, x2) (G and g in ``LinearSubsystem``).  The groups are listed in
        :mod:`.kernel_layouts`.
    out : ndarray, shape like y
        Derivative (written).
    """
    p, mode_s, mode_c, sub = field
    nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x = sub
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
            out[j + 2] = (f_contact - contact_elastic_force(d, p)) * dd
        else:
            out[j + 2] = 0.0
        out[j + 3] = f_friction * x4
