"""The dynamic WOB amplitude: the fundamental harmonic of the WOB over the steady window.

The WOB of a drilling hammer is periodic at the forcing frequency ``f`` with
kinks (slips) and, with a gap, short contact spikes.  Its half peak-to-peak
value depends on whether a sample hits a spike (1 ms and 50 us samples of the
same run differ by 11 %), so the amplitude is the fundamental harmonic
instead: over the last whole number of forcing periods ``[t_e - k T, t_e]``
of the steady window,

    a = 2/(kT) int w cos(2 pi f t) dt,   b = 2/(kT) int w sin(2 pi f t) dt,   amplitude = sqrt(a^2 + b^2),

by the trapezoid rule on the samples (the window's start interpolated).  For
a sinusoid it is the half peak-to-peak value; a spike of impulse ``J``
changes it by at most ``2 J / (k T)``, whatever the sampling.  The contact
peaks are reported apart (:func:`peak`).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["fundamental", "steady_periods", "peak", "StepLog", "GAUSS_NODES"]


def steady_periods(t_from: float, t_end: float, frequency: float) -> tuple:
    """``(t_start, k)``: the last whole number ``k >= 1`` of forcing periods within
    ``[t_from, t_end]`` (``k = 0``, ``t_start = t_from`` when not even one fits)."""
    T = 1.0 / frequency
    k = int(math.floor((t_end - t_from) / T * (1.0 + 1e-12)))
    return (t_end - k * T, k) if k >= 1 else (t_from, 0)


def fundamental(t: np.ndarray, w: np.ndarray, frequency: float, t_from: float) -> tuple:
    """``(amplitude, mean)`` of the samples ``w(t)`` [N] over the last whole forcing periods after
    ``t_from`` [s].  Without a whole period (or without a forcing frequency) it falls back to half
    the peak-to-peak value and the mean of the samples after ``t_from``."""
    t = np.asarray(t, dtype=float)
    w = np.asarray(w, dtype=float)
    sel = t >= t_from - 1e-12
    if not np.any(sel):
        return 0.0, math.nan
    if not frequency > 0.0:
        ws = w[sel]
        return 0.5 * float(ws.max() - ws.min()), float(ws.mean())
    t0, k = steady_periods(t_from, float(t[-1]), frequency)
    inside = t > t0
    if k == 0 or np.count_nonzero(inside) < 2:
        ws = w[sel]
        return 0.5 * float(ws.max() - ws.min()), float(ws.mean())
    w0 = float(np.interp(t0, t, w))
    tt = np.concatenate(([t0], t[inside]))
    ww = np.concatenate(([w0], w[inside]))
    span = tt[-1] - tt[0]
    ph = 2.0 * math.pi * frequency * tt
    a = 2.0 / span * float(np.trapezoid(ww * np.cos(ph), tt))
    b = 2.0 / span * float(np.trapezoid(ww * np.sin(ph), tt))
    mean = float(np.trapezoid(ww, tt)) / span
    return math.hypot(a, b), mean


def peak(t: np.ndarray, w: np.ndarray, t_from: float) -> tuple:
    """``(max, min)`` of the samples after ``t_from`` [N]: the contact peaks and the lowest WOB."""
    t = np.asarray(t, dtype=float)
    w = np.asarray(w, dtype=float)
    ws = w[t >= t_from - 1e-12]
    return (float(ws.max()), float(ws.min())) if ws.size else (math.nan, math.nan)


# ---------------------------------------------------------------------------
# the WOB within each macro step, from the hammer's own balance of forces
# ---------------------------------------------------------------------------
#: Gauss-Legendre nodes per macro step of the harmonic integrals (exact for the step's WOB, a cubic
#: in time, times cos/sin of up to half a forcing period: the residual is below 1e-12).
GAUSS_NODES = 8
#: Columns of a :class:`StepLog` row.
LOG_T, LOG_H, LOG_HELD, LOG_X, LOG_V, LOG_W = range(6)


class StepLog:
    """Per macro step of a lane: its start ``t`` [s], length ``h`` [s], the held interface force
    [N] and the hammer's position [m], velocity [m/s] and WOB [N] at its end.

    Within a step the master knows every force on the hammer: the held force, the harmonic
    force (the hammer's own source, or the master's held mean) and the WOB.  The hammer's
    acceleration at both ends is then ``(drive - WOB) / m1`` (one-sided, inside the step), and
    with its position and velocity there it fixes the quintic Hermite interpolant of the
    hammer's position over the step (error O(h^6) where the motion is smooth; the impulse of
    the step, ``v1 - v0``, exact).  The WOB inside the step is ``drive - m1 a(t)``:
    :meth:`wob_harmonic` integrates it exactly (Gauss-Legendre) against the forcing.
    """

    def __init__(self, first_out, *, hammer_mass: float, amplitude: float, frequency: float, phase: float,
                 master_harmonic=None, ramp=None):
        self.first = (float(first_out[0]), float(first_out[1]), float(first_out[4]))
        self.rows = []
        self.m1 = float(hammer_mass)
        self.A, self.f, self.phi = float(amplitude), float(frequency), float(phase)
        self.master = master_harmonic
        self.ramp = ramp

    def __len__(self) -> int:
        return len(self.rows)

    def add(self, t: float, h: float, held: float, out) -> None:
        """One step ``[t, t + h]`` and the hammer's outputs ``out`` at its end."""
        self.rows.append((t, h, held, out[0], out[1], out[4]))

    def truncate(self, n: int) -> None:
        """Drop the steps after the first ``n`` (a rollback)."""
        del self.rows[n:]

    def _drive(self, T0: np.ndarray, H: np.ndarray, held: np.ndarray) -> tuple:
        """Every force on the hammer but the WOB over steps ``[T0, T0 + H]``: ``(C, R)`` per step
        with the force ``C + R sin(2 pi f t + phase)`` [N] (the master's held harmonic in ``C``)."""
        if self.master is not None:
            return held + np.array([self.master.mean(a, b) for a, b in zip(T0, H)]), np.zeros_like(T0)
        if self.ramp is None:
            return held, np.full_like(T0, self.A)
        return held, self.A * np.array([self.ramp.ramp_factor(a + 0.5 * b) for a, b in zip(T0, H)])

    def wob_harmonic(self, t_from: float) -> tuple:
        """``(amplitude, mean)`` [N] of the WOB over the last whole forcing periods after ``t_from``
        [s] (:func:`steady_periods`), from the WOB within each step; without a whole period or a
        forcing frequency, half the peak-to-peak value and the mean of the step-end WOBs."""
        amplitude, mean, _ = self.wob_phasor(t_from)
        return amplitude, mean

    def wob_phasor(self, t_from: float) -> tuple:
        """``(amplitude, mean, phasor)``: :meth:`wob_harmonic` and the first harmonic itself, ``a + i b``
        [N] (its modulus the amplitude, its argument the phase against the forcing; NaN without a
        whole period or a forcing frequency)."""
        nan = complex(math.nan, math.nan)
        if not self.rows:
            return 0.0, math.nan, nan
        R = np.asarray(self.rows, dtype=float)
        t_end = float(R[-1, LOG_T] + R[-1, LOG_H])
        t1 = R[:, LOG_T] + R[:, LOG_H]
        t_start, k = steady_periods(t_from, t_end, self.f) if self.f > 0.0 else (t_from, 0)
        if k == 0:
            ws = R[t1 >= t_from - 1e-12, LOG_W]
            if ws.size == 0:
                return 0.0, math.nan, nan
            return 0.5 * float(ws.max() - ws.min()), float(ws.mean()), nan
        x0 = np.concatenate(([self.first[0]], R[:-1, LOG_X]))
        v0 = np.concatenate(([self.first[1]], R[:-1, LOG_V]))
        w0 = np.concatenate(([self.first[2]], R[:-1, LOG_W]))
        sel = t1 > t_start
        T0, H, held = R[sel, LOG_T], R[sel, LOG_H], R[sel, LOG_HELD]
        x0, v0, w0 = x0[sel], v0[sel], w0[sel]
        x1, v1, w1 = R[sel, LOG_X], R[sel, LOG_V], R[sel, LOG_W]
        C, Ramp = self._drive(T0, H, held)
        om = 2.0 * math.pi * self.f
        a0 = (C + Ramp * np.sin(om * T0 + self.phi) - w0) / self.m1
        a1 = (C + Ramp * np.sin(om * (T0 + H) + self.phi) - w1) / self.m1
        # the part of each step inside the window, and its Gauss-Legendre nodes in s = (t - t0) / h
        lo = np.maximum(T0, t_start)
        g, gw = np.polynomial.legendre.leggauss(GAUSS_NODES)
        s_lo = (lo - T0) / H
        s = s_lo[:, None] + (1.0 - s_lo)[:, None] * 0.5 * (g[None, :] + 1.0)
        wq = (1.0 - s_lo)[:, None] * H[:, None] * 0.5 * gw[None, :]
        # second derivatives of the quintic Hermite basis (x0, h v0, h^2 a0, x1, h v1, h^2 a1)
        s2, s3 = s * s, s * s * s
        d_x = 60.0 * s - 180.0 * s2 + 120.0 * s3
        d_v0 = -36.0 * s + 96.0 * s2 - 60.0 * s3
        d_a0 = 1.0 - 9.0 * s + 18.0 * s2 - 10.0 * s3
        d_v1 = -24.0 * s + 84.0 * s2 - 60.0 * s3
        d_a1 = 3.0 * s - 12.0 * s2 + 10.0 * s3
        Hc = H[:, None]
        acc = (((x1 - x0)[:, None] * d_x + Hc * (v0[:, None] * d_v0 + v1[:, None] * d_v1)) / (Hc * Hc)
               + a0[:, None] * d_a0 + a1[:, None] * d_a1)
        tq = T0[:, None] + s * Hc
        ph = om * tq
        wob = C[:, None] + Ramp[:, None] * np.sin(ph + self.phi) - self.m1 * acc
        span = t_end - t_start
        a = 2.0 / span * float(np.sum(wq * wob * np.cos(ph)))
        b = 2.0 / span * float(np.sum(wq * wob * np.sin(ph)))
        return math.hypot(a, b), float(np.sum(wq * wob)) / span, complex(a, b)
