"""Regime flags of a scene from its own dynamics: runaway, bounce, tension and a settled period.

The paper's static rules (``a < b``, ``a + b <= 1``, ``b <= mu``,
:func:`hammerbit.model.regime.regime`) say where the paper worked: they are
reported as *the paper's domain*.  Whether a scene's answer is usable comes
from what the scene did:

``runaway``
    the drift accelerates without bound (:func:`runaway_rows`, the condition
    is derived in ``docs/model.md``): ``b`` above the friction floor, the bit
    not stuck over the last half of the horizon, its slowest Poincaré velocity
    over the last window above ``v* = ln((1 - mu)/(b - mu))/gamma_hat`` (where
    the friction falls below the preload) and its mean velocity growing from
    window to window without levelling off;
``bounce``
    the drive on the bit fell below the model's threshold ``-F_s`` while the
    bit was stuck (the rock would have to pull it back), with the count;
``tension``
    the drive on the bit fell below zero (reported with its minimum; the
    spring pulls the bit, which the model allows);
``transient``
    the period-n seen over the last half is not yet the orbit's settled one
    (:func:`settling_rows`): successive windows disagree, or a repeat is still
    contracting; ``settled_after`` says how many periods it needed (or, when
    it has not settled, the extrapolated number).

``runaway`` and ``bounce`` make a scene unusable as a drilling point
(:attr:`SceneFlags.unusable`).  The minimum drive and the last stuck time are
tracked by the solver itself (``kernel_layouts.F_DRIVE_MIN``, ``kernel_layouts.F_T_STICK``);
the rest comes from the Poincaré rows in one compiled pass.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from numba import njit

from hammerbit.model import kernel_layouts as KL
from hammerbit.model.params import Groups
from hammerbit.model.regime import regime

from .analysis import PERIOD_MAX, PERIOD_TOL, period_n, relative_rows

__all__ = ["SceneFlags", "scene_flags", "stepper_flags", "runaway_rows", "settling_rows", "slip_speed_limit",
           "friction_floor", "RUNAWAY_WINDOWS", "CONTRACT", "DOMAIN_RULES", "paper_domain"]

#: Windows of the last half of the horizon compared by the runaway and settling tests.
RUNAWAY_WINDOWS = 4
#: A repeat deviation that shrinks by at least this factor from one window to the next is still settling.
CONTRACT = 0.8
#: A deviation above this is no near-repeat (a different orbit, not a slow approach to one).
NEAR_REPEAT = 0.1
#: Slots of :func:`settling_rows`'s ``out``.
S_PERIOD, S_TRANSIENT, S_SETTLED, S_TOWARD = range(4)
N_SETTLING = 4

#: The paper's static rules, by :class:`~hammerbit.model.params.Regime` field: the rule broken.
DOMAIN_RULES = {"bounce": "a >= b", "overload": "a + b > 1", "runaway": "b > mu"}


def friction_floor(groups: Groups) -> float:
    """Kinetic friction at high speed [F0]: ``mu`` with velocity weakening, else 1."""
    return groups.mu if groups.gamma_hat > 0.0 else 1.0


def slip_speed_limit(groups: Groups) -> float:
    """``v*`` [x0 Omega]: the slip speed above which the friction is below the preload.

    ``f_f(v*) = b`` with ``f_f(v) = mu + (1 - mu) exp(-gamma_hat v)``: ``v* =
    ln((1 - mu)/(b - mu))/gamma_hat``.  ``inf`` when ``b`` is at or below the
    friction floor (no speed is fast enough), 0 when ``b >= 1`` or without
    velocity weakening above the floor.
    """
    floor = friction_floor(groups)
    if groups.b <= floor:
        return math.inf
    if groups.b >= 1.0 or groups.gamma_hat == 0.0:
        return 0.0
    return math.log((1.0 - groups.mu) / (groups.b - groups.mu)) / groups.gamma_hat


@njit(cache=True, nogil=True)
def runaway_rows(poin, n_poin, t_end, t_stuck, v_star):
    """1 when the Poincaré rows ``poin[:n_poin]`` (``[tau, x1, x2, x3, x4]``) show a runaway drift.

    ``t_stuck`` is the last time the bit was stuck (``t_end`` if it is stuck
    now), ``v_star`` the slip speed above which friction is below the preload
    (inf: never).  Runaway: the bit was not stuck over the last half, its
    slowest sampled velocity over the last of ``RUNAWAY_WINDOWS`` windows of
    the last half exceeds ``v_star``, and the windows' mean velocities grow
    strictly, the last growth at least half the first (no levelling off).
    """
    if not (v_star < math.inf) or n_poin < 2 * RUNAWAY_WINDOWS + 1:
        return 0
    if t_stuck >= 0.5 * t_end:
        return 0
    start = (n_poin - 1) // 2
    L = (n_poin - 1 - start) // RUNAWAY_WINDOWS
    if L < 1:
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
    ``analysis.period_n``, 0: none); ``out[S_TRANSIENT]`` 1 when the orbit has
    not settled: the last quarter shows another period than the last half, or
    the repeat deviation of a period (a divisor of the one seen, or any when
    none is seen) still contracts by ``CONTRACT`` or more from the third
    quarter to the last; ``out[S_SETTLED]`` the row (forcing period) from
    which the period it settles into repeats up to the end, or its
    extrapolation beyond the horizon when it is still contracting (-1:
    unknown); ``out[S_TOWARD]`` that period (0: none).
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
            rate = math.log(e4 / e3) / L
            out[S_TRANSIENT] = 1.0
            out[S_TOWARD] = m
            out[S_SETTLED] = rows - 1 + math.ceil(math.log(tol / e4) / rate)
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
    runaway, bounce, tension, transient : bool
    bounces : int
        Bounce violations (drive below ``-F_s`` while stuck).
    min_drive : float
        Lowest drive on the bit over the run [F0] (nan when unknown).
    period : int or None
        Period-n over the last half of the horizon.
    settled_after : int or None
        Forcing periods the orbit needed to settle into ``settling_period``
        (extrapolated when ``transient`` and still contracting).
    settling_period : int or None
        The period the last window shows (or is approached), None when none.
    domain : dict
        :func:`paper_domain` of the scene.
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

    @property
    def unusable(self) -> bool:
        """True when the scene is no drilling point: it runs away or bounces."""
        return self.runaway or self.bounce

    @property
    def flags(self) -> list:
        """Names of the flags that are set, in a fixed order."""
        return [k for k in ("runaway", "bounce", "tension", "transient") if getattr(self, k)]

    def to_dict(self, friction_force: float) -> dict:
        """JSON form; the minimum drive nondimensional (``min_drive_f0``) and in N."""
        return {"runaway": self.runaway, "bounce": self.bounce, "bounces": self.bounces,
                "tension": self.tension, "min_drive_f0": self.min_drive,
                "min_drive_n": self.min_drive * friction_force, "transient": self.transient,
                "period": self.period, "settled_after_periods": self.settled_after,
                "settling_period": self.settling_period, "unusable": self.unusable, "flags": self.flags}


def scene_flags(groups: Groups, poincare_rows: np.ndarray, *, t_end: float, min_drive: float,
                bounces: int, t_stuck: float, stuck_now: bool) -> SceneFlags:
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
        Last time the bit was stuck [tau] (``kernel_layouts.F_T_STICK``; -1 never).
    stuck_now : bool
        The bit is stuck at ``t_end``.
    """
    rows = np.ascontiguousarray(poincare_rows, dtype=np.float64)
    n = rows.shape[0]
    last_stuck = t_end if stuck_now else t_stuck
    run = bool(runaway_rows(rows, n, t_end, last_stuck, slip_speed_limit(groups)))
    rel = np.empty((n, 3))
    relative_rows(rows, n, rel)
    out = np.zeros(N_SETTLING)
    settling_rows(rel, PERIOD_MAX, PERIOD_TOL, out)
    per = int(out[S_PERIOD])
    settled = int(out[S_SETTLED]) if out[S_SETTLED] >= 0 else None
    toward = int(out[S_TOWARD])
    if run:         # a drift without bound settles into nothing
        settled, toward = None, 0
    return SceneFlags(runaway=run, bounce=bounces > 0, bounces=int(bounces),
                      tension=bool(min_drive < 0.0), min_drive=float(min_drive),
                      transient=bool(out[S_TRANSIENT]) and not run, period=per if per > 0 else None,
                      settled_after=settled, settling_period=toward if toward > 0 else None,
                      domain=paper_domain(groups))


def stepper_flags(groups: Groups, stepper, poincare_rows: np.ndarray) -> SceneFlags:
    """:func:`scene_flags` of a :class:`~hammerbit.model.stepping.Stepper` after its run."""
    return scene_flags(groups, poincare_rows, t_end=stepper.time,
                       min_drive=float(stepper.fstate[KL.F_DRIVE_MIN]),
                       bounces=int(stepper.istate[KL.I_COUNT0 + KL.EV_BOUNCE]),
                       t_stuck=float(stepper.fstate[KL.F_T_STICK]),
                       stuck_now=bool(stepper.istate[KL.I_STICK] == KL.STICK))
