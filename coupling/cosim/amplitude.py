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

__all__ = ["fundamental", "steady_periods", "peak"]


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
