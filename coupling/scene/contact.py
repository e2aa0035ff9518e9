"""The hammer-bit contact force of a run: one definition for simulate, map and optimize.

``peak contact force`` is the largest hammer-bit contact force over the
whole run, start-up included (:func:`peak_of_run`, tracked by the solver:
``kernel_layouts.F_PEAK_RUN`` for the contacts that ended, ``kernel_layouts.F_PEAK`` for
one still going).  The *steady* peak, the largest over the second half of
the horizon only, has its own name (:func:`steady_peak`, from the event log).
"""
from __future__ import annotations

from numba import njit

from hammerbit.model import kernel_layouts as KL

__all__ = ["peak_of_run", "steady_peak"]


def peak_of_run(stepper) -> float:
    """Largest contact force of a :class:`~hammerbit.model.stepping.Stepper`'s run so far [F0]."""
    peak = float(stepper.fstate[KL.F_PEAK_RUN])
    if stepper.istate[KL.I_CONTACT] != KL.FREE:
        peak = max(peak, float(stepper.fstate[KL.F_PEAK]))
    return peak


@njit(cache=True, nogil=True)
def steady_peak(log, n_log, t_from, current):
    """Largest contact force [F0] of the separations at or after ``t_from`` in ``log[:n_log]``,
    and ``current`` (the peak of a contact still going at the end, 0 if none); a NaN wins."""
    peak = current
    for i in range(n_log):
        if log[i, KL.L_T] >= t_from and log[i, KL.L_KIND] == KL.EV_SEPARATION:
            v = log[i, KL.L_PEAK]
            if v != v or v > peak:
                peak = v
            if peak != peak:
                return peak
    return peak
