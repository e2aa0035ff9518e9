"""The regime verdict's rules that a run applies once per forcing period: friction floor, runaway certificate, stall.

One place for each rule, for every face (``simulate``, the studies, the
co-simulation, the FMUs' ``regime`` output): each rule reads only the state at a
Poincaré sample and a few numbers fixed per scene (:func:`certificate_constants`),
so it runs causally, period by period (``docs/model.md``, "Validity domain and the regime verdict").

Also the paper's static domain of a scene (:func:`regime`): the rules
a < b, a + b <= 1 and b <= mu it breaks.  These rules are where the paper
worked, not whether a scene's answer is a drilling point.

The runaway certificate (derived in ``docs/model.md``): while the bit slips,
the momentum of hammer and bit ``P = x2 + rho x4`` obeys
``P' = b + a sin(eta tau + phi) - f_f(x4)`` (spring, damper and contact are
internal), and ``(1 + rho) x4 = P - w`` with ``w = x2 - x4``.  If
``x4 >= v_c`` from now on and ``b >= f_f(v_c)``, the friction term cannot
pull ``P`` down, the harmonic term can lower it by at most
``(a/eta)(1 - cos theta0)``, and ``w`` stays below a bound ``W+`` given by the
relative oscillator (linear while the gap stays open; its energy bounds the
free part, the L1 norm of its impulse response the friction's part).  So
``(1 + rho)(x4_0 - v_c) > (a/eta)(1 - cos theta0) + W+ - w0`` proves that
``x4`` never falls to ``v_c``: the bit never sticks again.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from .kernel_layouts import P_A, P_ETA, P_GAMMA, P_MU, P_PHI, P_R, P_RHO, P_XI
from .params import Groups

__all__ = ["Regime", "regime", "friction_floor", "friction_floor_of", "slip_speed_limit", "slip_speed_limit_of",
           "sliding_capacity", "oscillator_l1", "certificate_constants", "fill_certificate", "runaway_certified", "N_CERT", "STALL_PERIODS", "STALL_WOB_FRACTION"]

#: A stall: no slip for this many forcing periods ...
STALL_PERIODS = 20
#: ... while the weight on bit is at least this fraction of its set point.
STALL_WOB_FRACTION = 0.5

#: Slots of :func:`certificate_constants`.
(C_K, C_L1Z, C_L1W, C_HZ_RE, C_HZ_IM, C_A, C_B, C_ETA, C_PHI, C_MU, C_GAMMA, C_RHO, C_R,
 C_VSTAR) = range(14)
N_CERT = 14
#: Trial velocities v_c between v* and the bit's velocity tried by the certificate.
CERT_TRIALS = 16
#: Impulse responses are integrated over this many slowest decay times (e^-30: nothing left).
DECAY_TIMES = 30.0
#: Integration steps per oscillation period (or per fastest time constant, overdamped).
STEPS_PER_CYCLE = 64
#: The trapezoidal quadrature's relative error (below 1e-3 at 64 steps) is far below this safety factor.
L1_SAFETY = 1.01
#: the most steps the L1 norms are integrated over (a slower decay gives no certificate)
L1_MAX_STEPS = 5_000_000


def friction_floor(groups: Groups) -> float:
    """Kinetic friction at high speed [F0]: ``mu`` with velocity weakening, else 1 (the one rule)."""
    return friction_floor_of(groups.mu, groups.gamma_hat)


@njit(cache=True, nogil=True)
def friction_floor_of(mu, gamma_hat):
    """:func:`friction_floor` of the groups ``mu`` and ``gamma_hat`` (a kernel)."""
    return mu if gamma_hat > 0.0 else 1.0


def slip_speed_limit(groups: Groups) -> float:
    """``v*`` [x0 Omega]: the slip speed above which the friction is below the preload.

    ``f_f(v*) = b`` with ``f_f(v) = mu + (1 - mu) exp(-gamma_hat v)``: ``v* =
    ln((1 - mu)/(b - mu))/gamma_hat``.  ``inf`` when ``b`` is at or below the
    friction floor (no speed is fast enough), 0 when ``b >= 1`` or without
    velocity weakening above the floor.
    """
    return slip_speed_limit_of(groups.b, groups.mu, groups.gamma_hat)


@njit(cache=True, nogil=True)
def slip_speed_limit_of(b, mu, gamma_hat):
    """:func:`slip_speed_limit` of the groups ``b``, ``mu`` and ``gamma_hat`` (a kernel)."""
    if b <= friction_floor_of(mu, gamma_hat):
        return math.inf
    if b >= 1.0 or gamma_hat == 0.0:
        return 0.0
    return math.log((1.0 - mu) / (b - mu)) / gamma_hat


def sliding_capacity(mu_kinetic: float, normal_force: float) -> float:
    """The largest weight on bit [N] the rock holds against a fast-sliding bit: ``mu_d F_N``.

    A weight on bit held above it drives the bit faster and faster (runaway).
    """
    return float(mu_kinetic * normal_force)


@njit(cache=True, nogil=True)
def _impulse_l1(a10, a11, ds, n):
    """L1 norms of the impulse responses of z and w (``z'' = a10 z + a11 z' + delta``)."""
    # one exact-to-O(ds^5) RK4 step per ds: the system is linear, 2x2
    z, w = 0.0, 1.0
    l1z = l1w = 0.0
    for _ in range(n):
        l1z += abs(z) * ds
        l1w += abs(w) * ds
        k1z, k1w = w, a10 * z + a11 * w
        z2, w2 = z + 0.5 * ds * k1z, w + 0.5 * ds * k1w
        k2z, k2w = w2, a10 * z2 + a11 * w2
        z3, w3 = z + 0.5 * ds * k2z, w + 0.5 * ds * k2w
        k3z, k3w = w3, a10 * z3 + a11 * w3
        z4, w4 = z + ds * k3z, w + ds * k3w
        k4z, k4w = w4, a10 * z4 + a11 * w4
        z += ds / 6.0 * (k1z + 2 * k2z + 2 * k3z + k4z)
        w += ds / 6.0 * (k1w + 2 * k2w + 2 * k3w + k4w)
    # trapezoid: the left sum counts the first sample whole (z(0) = 0, w(0) = 1)
    return l1z, l1w - 0.5 * ds


@njit(cache=True, nogil=True)
def oscillator_l1(rho, xi):
    """L1 norms of the relative oscillator's impulse responses in z and z' (they depend on rho, xi only;
    inf, inf: too weakly damped to bound, no certificate)."""
    k = 1.0 + 1.0 / rho
    c = 2.0 * xi * k
    sigma = 0.5 * c
    disc = sigma * sigma - k
    slow = sigma - math.sqrt(disc) if disc > 0 else sigma      # slowest decay rate
    fast = sigma + math.sqrt(disc) if disc > 0 else sigma      # fastest
    if not slow > 0.0:
        # undamped (xi = 0): the responses never decay, their L1 norms are unbounded, no certificate
        return math.inf, math.inf
    cycle = 2.0 * math.pi / math.sqrt(-disc) if disc < 0 else 1.0 / fast
    ds = min(cycle, 1.0 / math.sqrt(k)) / STEPS_PER_CYCLE
    n_steps = DECAY_TIMES / slow / ds
    if not n_steps <= L1_MAX_STEPS:
        # a barely damped oscillator: its L1 norms are too large to bound here, no certificate
        return math.inf, math.inf
    l1z, l1w = _impulse_l1(-k, -c, ds, int(math.ceil(n_steps)))
    return L1_SAFETY * l1z, L1_SAFETY * l1w


@lru_cache(maxsize=64)
def _oscillator_l1(rho: float, xi: float) -> tuple:
    """:func:`oscillator_l1`, remembered (a study asks for the same rho, xi many times)."""
    return oscillator_l1(float(rho), float(xi))


def certificate_constants(groups: Groups) -> np.ndarray:
    """The numbers of a scene that :func:`runaway_certified` reads (fixed per scene), shape ``(N_CERT,)``
    (:func:`fill_certificate` of the scene's kernel parameters)."""
    out = np.empty(N_CERT)
    l1z, l1w = _oscillator_l1(float(groups.rho), float(groups.xi))
    fill_certificate(groups.to_kernel(), float(groups.b), l1z, l1w, out)
    return out


@njit(cache=True, nogil=True)
def fill_certificate(p, b, l1z, l1w, out):
    """The certificate's constants (shape ``(N_CERT,)``, into ``out``) of the kernel parameters ``p``
    (``kernel_layouts.P_*``) with the constant drive ``b`` on the hammer [F0].

    The relative oscillator of a slipping bit, ``z = x1 - x3``:
    ``z'' + 2 xi k z' + k z = b + a sin(eta tau + phi) + f_f(x4)/rho`` with
    ``k = 1 + 1/rho``; its frequency response ``H_z(i eta)`` and the L1 norms
    ``l1z, l1w`` of its impulse responses in ``z`` and ``z'`` (:func:`oscillator_l1`).
    """
    rho, eta = p[P_RHO], p[P_ETA]
    k = 1.0 + 1.0 / rho
    c = 2.0 * p[P_XI] * k
    s = 1j * eta
    hz = 1.0 / (s * s + c * s + k)
    out[C_K], out[C_L1Z], out[C_L1W] = k, l1z, l1w
    out[C_HZ_RE], out[C_HZ_IM] = hz.real, hz.imag
    out[C_A], out[C_B], out[C_ETA], out[C_PHI] = p[P_A], b, eta, p[P_PHI]
    out[C_MU], out[C_GAMMA], out[C_RHO], out[C_R] = p[P_MU], p[P_GAMMA], rho, p[P_R]
    out[C_VSTAR] = slip_speed_limit_of(b, p[P_MU], p[P_GAMMA])


@njit(cache=True, nogil=True)
def _margin(c, tau, x1, x2, x3, x4, vc):
    """Margin of the certificate with the floor velocity ``vc`` (> 0: proved), -inf when the gap may close."""
    k, rho, a, eta = c[C_K], c[C_RHO], c[C_A], c[C_ETA]
    f_c = c[C_MU] + (1.0 - c[C_MU]) * math.exp(-c[C_GAMMA] * vc)
    if not c[C_B] >= f_c:
        return -math.inf
    c_mid = 0.5 * (c[C_MU] + f_c) / rho          # f_f/rho lies in [mu/rho, f_f(vc)/rho]
    dc = 0.5 * (f_c - c[C_MU]) / rho
    th = eta * tau + c[C_PHI]
    sn, cs = math.sin(th), math.cos(th)
    hr, hi = c[C_HZ_RE], c[C_HZ_IM]
    # the periodic response to b + c_mid + a sin(theta): Im(H e^{i theta}) and its derivative
    z_p = (c[C_B] + c_mid) / k + a * (hr * sn + hi * cs)
    w_p = a * eta * (hr * cs - hi * sn)
    dz, dw = (x1 - x3) - z_p, (x2 - x4) - w_p
    free = math.sqrt(dw * dw + k * dz * dz)       # sqrt(2 E) of the free part: never grows
    h = math.sqrt(hr * hr + hi * hi)
    z_top = (c[C_B] + c_mid) / k + a * h + free / math.sqrt(k) + c[C_L1Z] * dc
    if not z_top < c[C_R]:
        return -math.inf                          # the gap may close: the oscillator is no longer linear
    w_top = a * eta * h + free + c[C_L1W] * dc
    return (1.0 + rho) * (x4 - vc) - (a / eta) * (1.0 - cs) - (w_top - (x2 - x4))


@njit(cache=True, nogil=True)
def runaway_certified(c, tau, x1, x2, x3, x4):
    """1 when the state ``(x1..x4)`` at ``tau`` of a slipping bit proves that it never sticks again.

    ``c`` is :func:`certificate_constants`.  Tries ``CERT_TRIALS`` floor
    velocities ``v_c`` between ``v*`` and ``x4`` (see the module docstring).
    A sound sufficient condition: 0 says "not proved", not "it will stick".
    """
    v_star = c[C_VSTAR]
    if not (v_star < math.inf) or not (x4 > v_star):
        return 0
    tiny = 1e-12 * (1.0 + abs(x4) + abs(x2))
    for j in range(CERT_TRIALS):
        vc = v_star + (x4 - v_star) * j / CERT_TRIALS
        if _margin(c, tau, x1, x2, x3, x4, vc) > tiny:
            return 1
    return 0


@dataclass(frozen=True)
class Regime:
    """Which of the paper's static rules a scene breaks.

    Attributes
    ----------
    bounce : bool
        ``a >= b``: the harmonic amplitude reaches the preload.  The drive on
        the bit may then fall below zero, and below ``-F_s`` only in some scenes.
    overload : bool
        ``a + b > 1``: preload plus amplitude exceed the static threshold
        ``F0 = mu_e F_N``, outside the paper's domain ``a + b <= 1``.
    runaway : bool
        ``b`` above :func:`friction_floor`.  Necessary for a runaway drift
        (friction below the preload at high speed), not sufficient: the slip
        must also reach the speed where the friction falls below the preload
        and keep sliding (:func:`runaway_certified`).
    """

    bounce: bool
    overload: bool
    runaway: bool

    @property
    def flags(self) -> list:
        """Names of the flags that are set."""
        return [k for k in ("bounce", "overload", "runaway") if getattr(self, k)]

    def to_dict(self) -> dict:
        return {"bounce": self.bounce, "overload": self.overload, "runaway": self.runaway}


def regime(groups: Groups) -> Regime:
    """The paper's static rules a scene breaks (pure function of its groups)."""
    return Regime(bounce=groups.a >= groups.b, overload=groups.a + groups.b > 1.0,
                  runaway=groups.b > friction_floor(groups))
