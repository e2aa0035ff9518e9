"""The closed-form solution of the stuck hammer: a forced linear oscillator (numba kernels)."""

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_forces import spring_damper_force
from .kernel_layouts import P_A, P_B, P_ETA, P_FEXT, P_PHI, P_XI, V_BIT, V_HAMMER, X_BIT, X_HAMMER

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
