"""Regime flags of a scene from its own dynamics: runaway, bounce, tension, stall and a settled period.

The paper's static rules (``a < b``, ``a + b <= 1``, ``b <= mu``,
:func:`hammerbit.model.regime.regime`) say where the paper worked: they are
reported as *the paper's domain*.  Whether a scene's answer is usable comes
from what the scene did (``docs/model.md``, "Validity domain and the regime verdict"):

``runaway``
    the bit cannot stick again: after its last stick, a Poincaré state passes
    the certificate :func:`hammerbit.model.regime.runaway_certified` (a proof,
    kept once reached); failing a proof (the gap may close), the fallback of
    :func:`runaway_rows`: no stick for ``RUNAWAY_WINDOWS`` windows of at least
    ``MIN_WINDOW`` periods each, their mean velocity growing without levelling
    off and the slowest sampled velocity of the last one above ``v*``;
``bounce``
    the drive on the bit fell below the model's threshold ``-F_s`` while the
    bit was stuck (the rock would have to pull it back), with the count;
``tension``
    the drive on the bit fell below zero (reported with its minimum; the
    spring pulls the bit, which the model allows);
``stall``
    the bit has not slipped for ``STALL_PERIODS`` forcing periods up to the end
    (a scene holds its preload, its weight-on-bit set point, at all times);
``transient``
    the period-n seen over the last half is not yet the orbit's settled one
    (:func:`settling_rows`): the last quarter shows another period, or a
    repeat is still contracting.  ``settled_after`` is the forcing period
    from which the period the last quarter shows repeats up to the end: a
    period that was seen, never an extrapolation.

``runaway`` and ``bounce`` make a scene unusable as a drilling point
(:attr:`SceneFlags.unusable`); :attr:`SceneFlags.code` is the one verdict
(:mod:`hammerbit.model.regime_codes`).  The minimum drive and the last stuck
time are tracked by the solver itself (``kernel_layouts.F_DRIVE_MIN``,
``kernel_layouts.F_T_STICK``); the rest comes from the Poincaré rows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from numba import njit

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups
from hammerbit.model.regime import (STALL_PERIODS, certificate_constants, friction_floor, regime,
                                    runaway_certified, slip_speed_limit)
from hammerbit.model.regime_codes import (REGIME_BOUNCE, REGIME_RUNAWAY, REGIME_STALL, REGIME_TENSION,
                                          REGIME_TRANSIENT, regime_json, regime_names)

from .analysis import PERIOD_MAX, PERIOD_TOL, period_n, relative_rows

__all__ = ["SceneFlags", "scene_flags", "stepper_flags", "runaway_rows", "certified_row", "settling_rows",
           "slip_speed_limit", "friction_floor", "regime_json", "RUNAWAY_WINDOWS", "MIN_WINDOW", "CONTRACT",
           "DOMAIN_RULES", "paper_domain"]

#: Windows after the last stick compared by the runaway fallback, and the settling test's quarters.
RUNAWAY_WINDOWS = 4
#: Shortest window of the runaway fallback [forcing periods].
MIN_WINDOW = 2
#: A repeat deviation that shrinks by at least this factor from one window to the next is still settling.
CONTRACT = 0.8
#: A deviation above this is no near-repeat (a different orbit, not a slow approach to one).
NEAR_REPEAT = 0.1
#: Slots of :func:`settling_rows`'s ``out``.
S_PERIOD, S_TRANSIENT, S_SETTLED, S_TOWARD = range(4)
N_SETTLING = 4

#: The paper's static rules, by :class:`~hammerbit.model.params.Regime` field: the rule broken.
DOMAIN_RULES = {"bounce": "a >= b", "overload": "a + b > 1", "runaway": "b > mu"}


@njit(cache=True, nogil=True)
def certified_row(poin, n_poin, t_stuck, consts):
    """First Poincaré row after ``t_stuck`` whose state passes the runaway certificate (-1: none)."""
    for k in range(n_poin):
        if poin[k, 0] > t_stuck and runaway_certified(consts, poin[k, 0], poin[k, 1], poin[k, 2],
                                                      poin[k, 3], poin[k, 4]):
            return k
    return -1


@njit(cache=True, nogil=True)
def runaway_rows(poin, n_poin, t_end, t_stuck, v_star):
    """1 when the Poincaré rows ``poin[:n_poin]`` (``[tau, x1, x2, x3, x4]``) show a runaway drift.

    The fallback of the certificate.  ``t_stuck`` is the last time the bit
    was stuck (``t_end`` if it is stuck now), ``v_star`` the slip speed above
    which friction is below the preload (inf: never).  Runaway: the rows
    after ``t_stuck`` hold ``RUNAWAY_WINDOWS`` windows of at least
    ``MIN_WINDOW`` rows, the windows' mean velocities grow strictly, the last
    growth at least half the first (no levelling off), and the slowest
    sampled velocity over the last window exceeds ``v_star``.
    """
    if not (v_star < math.inf) or t_stuck >= t_end:
        return 0
    first = 0
    while first < n_poin and not (poin[first, 0] > t_stuck):
        first += 1
    L = (n_poin - 1 - first) // RUNAWAY_WINDOWS
    if L < MIN_WINDOW:
        return 0
    k0 = n_poin - 1 - RUNAWAY_WINDOWS * L
    prev = 0.0
    first_growth = 0.0
    growth = 0.0
    for w in range(RUNAWAY_WINDOWS):
        a = k0 + w * L
        b = a + L
        mean_v = (poin[b, 3] - poin[a, 3]) / (poin[b, 0] - poin[a, 0])
        if w > 0:
            growth = mean_v - prev
            if not (growth > 0.0):
                return 0
            if w == 1:
                first_growth = growth
        prev = mean_v
    if growth < 0.5 * first_growth:
        return 0
    for k in range(k0 + (RUNAWAY_WINDOWS - 1) * L, n_poin):
        if not (poin[k, 4] > v_star):
            return 0
    return 1


@njit(cache=True, nogil=True)
def _repeat_dev(s, k, n):
    """Relative repeat deviation of row k after n rows (a NaN never repeats)."""
    worst = 0.0
    for c in range(s.shape[1]):
        a = s[k + n, c]
        d = abs(a - s[k, c]) / (1.0 + abs(a))
        if not (d <= worst):
            worst = d if d == d else math.inf
    return worst


@njit(cache=True, nogil=True)
def _settled_from(s, n, tol):
    """First row from which period n repeats up to the end."""
    k0 = 0
    for k in range(s.shape[0] - n - 1, -1, -1):
        if not (_repeat_dev(s, k, n) <= tol):
            k0 = k + 1
            break
    return k0


@njit(cache=True, nogil=True)
def _window_dev(s, a, b, n):
    worst = 0.0
    for k in range(a, min(b, s.shape[0] - n)):
        d = _repeat_dev(s, k, n)
        if not (d <= worst):
            worst = d
    return worst


@njit(cache=True, nogil=True)
def settling_rows(s, max_period, tol, out):
    """Whether the period-n of the relative coordinates ``s`` (shape (n, 3)) has settled, into ``out``.

    ``out[S_PERIOD]`` the period over the last half (the rule of
    ``analysis.period_n``, 0: none); ``out[S_TOWARD]`` the period over the
    last quarter (0: none); ``out[S_SETTLED]`` the row (forcing period) from
    which that period repeats up to the end (-1: none seen);
    ``out[S_TRANSIENT]`` 1 when the orbit has not settled: the two periods
    differ, or the repeat deviation of a period (a divisor of the one seen, or
    any when none is seen) still contracts by ``CONTRACT`` or more from the
    third quarter to the last.  Only what the rows show: a period that is
    being approached is not claimed before it repeats.
    """
    rows = s.shape[0]
    half = rows // 2
    quarter = half + (rows - half) // 2
    n_half = period_n(s, max_period, tol)
    n_last = period_n(s[half:], max_period, tol)      # its last half: the last quarter
    out[S_PERIOD] = n_half
    out[S_TRANSIENT] = 0.0
    out[S_SETTLED] = -1.0
    out[S_TOWARD] = n_last
    if n_last > 0:
        out[S_SETTLED] = _settled_from(s, n_last, tol)
    if n_last != n_half:
        out[S_TRANSIENT] = 1.0
    # a smaller repeat still contracting: the orbit approaches it
    top = n_half - 1 if n_half > 0 else max_period
    L = rows - quarter
    for m in range(1, top + 1):
        if n_half > 0 and n_half % m != 0:
            continue
        if L < m + 2:
            break
        e3 = _window_dev(s, half, quarter, m)
        e4 = _window_dev(s, quarter, rows, m)
        if tol < e4 <= CONTRACT * e3 and e3 < NEAR_REPEAT:
            out[S_TRANSIENT] = 1.0
            break


def paper_domain(groups: Groups) -> dict:
    """The paper's static rules: ``{"inside": bool, "outside": [rule broken, ...]}``."""
    r = regime(groups)
    out = [DOMAIN_RULES[k] for k in r.flags]
    return {"inside": not out, "outside": out}


@dataclass(frozen=True)
class SceneFlags:
    """What a scene's dynamics say about its answer (see the module docstring).

    Attributes
    ----------
    runaway, bounce, tension, stall, transient : bool
    bounces : int
        Bounce violations (drive below ``-F_s`` while stuck).
    min_drive : float
        Lowest drive on the bit over the run [F0] (nan when unknown).
    period : int or None
        Period-n over the last half of the horizon.
    settled_after : int or None
        The forcing period from which ``settling_period`` repeats up to the end (seen, never
        extrapolated).
    settling_period : int or None
        The period the last quarter of the horizon shows, None when none.
    domain : dict
        :func:`paper_domain` of the scene.
    runaway_proof : str or None
        ``"certificate"`` (proved at ``certified_at``), ``"fallback"`` (growing drift) or None.
    certified_at : int or None
        The forcing period at whose Poincaré sample the certificate holds.
    """

    runaway: bool
    bounce: bool
    bounces: int
    tension: bool
    min_drive: float
    transient: bool
    period: Optional[int]
    settled_after: Optional[int]
    settling_period: Optional[int]
    domain: dict
    stall: bool = False
    runaway_proof: Optional[str] = None
    certified_at: Optional[int] = None

    @property
    def unusable(self) -> bool:
        """True when the scene is no drilling point: it runs away or bounces."""
        return self.runaway or self.bounce

    @property
    def flags(self) -> list:
        """Names of the flags that are set, in bit order (:data:`hammerbit.model.regime_codes.REGIME_BITS`)."""
        return regime_names(self.code)

    @property
    def code(self) -> int:
        """The verdict as the integer of :mod:`hammerbit.model.regime_codes`."""
        return ((REGIME_RUNAWAY if self.runaway else 0) | (REGIME_BOUNCE if self.bounce else 0)
                | (REGIME_TENSION if self.tension else 0) | (REGIME_STALL if self.stall else 0)
                | (REGIME_TRANSIENT if self.transient else 0))

    def to_dict(self, friction_force: float) -> dict:
        """JSON form; the minimum drive nondimensional (``min_drive_f0``) and in N."""
        return {**regime_json(self.code), "runaway": self.runaway, "bounce": self.bounce,
                "bounces": self.bounces, "tension": self.tension, "stall": self.stall,
                "min_drive_f0": self.min_drive, "min_drive_n": self.min_drive * friction_force,
                "transient": self.transient, "period": self.period, "settled_after_periods": self.settled_after,
                "settling_period": self.settling_period, "runaway_proof": self.runaway_proof,
                "runaway_certified_at_period": self.certified_at, "unusable": self.unusable,
                "flags": self.flags}


def _runaway(groups: Groups, rows: np.ndarray, t_end: float, last_stuck: float, final):
    """(runaway, proof, certified_at) of the Poincaré rows after the last stuck time and the final state."""
    n = rows.shape[0]
    if groups.b <= friction_floor(groups):     # friction above the preload at every speed
        return False, None, None
    consts = certificate_constants(groups)
    k = int(certified_row(rows, n, last_stuck, consts))
    if k >= 0:
        return True, "certificate", int(round(rows[k, 0] / groups.period))
    if final is not None and t_end > last_stuck and runaway_certified(consts, t_end, *final):
        return True, "certificate", int(math.floor(t_end / groups.period))
    if runaway_rows(rows, n, t_end, last_stuck, slip_speed_limit(groups)):
        return True, "fallback", None
    return False, None, None


def scene_flags(groups: Groups, poincare_rows: np.ndarray, *, t_end: float, min_drive: float,
                bounces: int, t_stuck: float, stuck_now: bool, final=None) -> SceneFlags:
    """The :class:`SceneFlags` of a run from its Poincaré rows and the solver's trackers.

    Parameters
    ----------
    groups : Groups
    poincare_rows : ndarray, shape (n, 5)
        ``[tau, x1, x2, x3, x4]`` once per forcing period from the start.
    t_end : float
        End of the run [tau].
    min_drive : float
        Lowest drive on the bit [F0] (``kernel_layouts.F_DRIVE_MIN``).
    bounces : int
        Bounce violations (``counts["bounce"]``).
    t_stuck : float
        Last time the bit stuck [tau] (``kernel_layouts.F_T_STICK``; -1 never).
    stuck_now : bool
        The bit is stuck at ``t_end``.
    final : sequence of 4 floats, optional
        ``(x1, x2, x3, x4)`` at ``t_end``: the certificate is tried there too, so a runaway is
        proved as soon as the state allows, not only at the next Poincaré sample.
    """
    rows = np.ascontiguousarray(poincare_rows, dtype=np.float64)
    n = rows.shape[0]
    last_stuck = t_end if stuck_now else t_stuck
    run, proof, cert_at = _runaway(groups, rows, t_end, last_stuck, final)
    rel = np.empty((n, 3))
    relative_rows(rows, n, rel)
    out = np.zeros(N_SETTLING)
    settling_rows(rel, PERIOD_MAX, PERIOD_TOL, out)
    per = int(out[S_PERIOD])
    settled = int(out[S_SETTLED]) if out[S_SETTLED] >= 0 else None
    toward = int(out[S_TOWARD])
    if run:         # a drift without bound settles into nothing
        settled, toward = None, 0
    # stuck since its last stick event (or from the start, never having slipped) for STALL_PERIODS periods
    stall = bool(stuck_now) and max(t_stuck, 0.0) <= t_end - STALL_PERIODS * groups.period
    return SceneFlags(runaway=run, bounce=bounces > 0, bounces=int(bounces),
                      tension=bool(min_drive < 0.0), min_drive=float(min_drive),
                      transient=bool(out[S_TRANSIENT]) and not run, period=per if per > 0 else None,
                      settled_after=settled, settling_period=toward if toward > 0 else None,
                      domain=paper_domain(groups), stall=stall, runaway_proof=proof, certified_at=cert_at)


def stepper_flags(groups: Groups, stepper, poincare_rows: np.ndarray) -> SceneFlags:
    """:func:`scene_flags` of a :class:`~hammerbit.model.stepping.Stepper` after its run."""
    return scene_flags(groups, poincare_rows, t_end=stepper.time,
                       min_drive=float(stepper.fstate[KL.F_DRIVE_MIN]),
                       bounces=int(stepper.istate[KL.I_COUNT0 + KL.EV_BOUNCE]),
                       t_stuck=float(stepper.fstate[KL.F_T_STICK]),
                       stuck_now=bool(stepper.istate[KL.I_STICK] == KL.STICK),
                       final=tuple(float(v) for v in stepper.y[:4]))
