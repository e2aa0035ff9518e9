"""An independent reference solver of the hammer–bit–rock model built on SciPy.

This module re-implements the hybrid model of ``model.md`` from scratch, with
no code shared with the kernels (``hammerbit.model.kernel_*``): a Python-level loop over the
hybrid modes drives :func:`scipy.integrate.solve_ivp` with *terminal* events,
one call per smooth segment.

Modes and events
----------------
* stick/slip of the bit (m2):

  - stick: ``x3' = x4' = 0``; the segment ends when the drive ``F_d`` rises
    through the static threshold 1 (``slip_start``), or when it falls through
    ``-1`` (the *bounce* violation of the model: the bit is kept stuck and the
    violation is only counted, ``bounce`` / ``bounce_end``);
  - slip: ``rho x4' = F_d - f_f(x4)``; the segment ends when ``x4`` falls to 0;
    then ``F_d <= 1`` gives ``stick``, else ``slip_on`` (slip goes on);

* contact of the hammer on the bit (only when the gap is finite and kc > 0):

  - free: the segment ends when ``d = x1 - x3 - r`` rises through 0 (``impact``);
  - contact: Hunt–Crossley ``f_c = kc d^n (1 + lam_hat d')``; ends when ``d``
    falls through 0 (``separation``) or when ``1 + lam_hat d'`` falls through 0
    (``clamp``: the tensile force is clamped to 0);
  - clamped: ``f_c = 0`` while ``d > 0``; ends at ``separation`` or when
    ``1 + lam_hat d'`` rises through 0 (``unclamp``).

Inside a contact segment the power ``d^n`` is extended oddly to ``d < 0`` so
that the vector field is smooth across the located event (the events
themselves are located by ``solve_ivp`` with Brent's method on the dense
output, to ``4 eps``).

Every event is "an indicator w rises through +margin", with a margin of
16 ulp of the state's scale: the indicator that an event has just set to
0 +- roundoff cannot re-trigger at the start of the next segment (without it,
a separation followed by a genuine re-impact inside the first step of the
next segment makes Brent's method return the segment start: an endless
zero-length impact/separation loop).  An indicator already past its margin
at a segment start fires at once, without integration.

The event kind names are the same as ``hammerbit.model.stepping.EVENT_NAMES``
so the two solvers can be compared event by event.

Examples
--------
>>> from hammerbit.model.presets import preset
>>> ref = simulate_reference(preset('paper-fig9'), 10)   # doctest: +SKIP
>>> ref.penetration                                       # doctest: +SKIP
"""
from __future__ import annotations

import math
import time as _time
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["RefResult", "simulate_reference", "EVENT_KINDS", "ReferenceError"]

EVENT_KINDS = ("slip_start", "stick", "slip_on", "impact", "separation",
               "clamp", "unclamp", "bounce", "bounce_end")

STICK, SLIP = 0, 1
FREE, CONTACT, CLAMPED = 0, 1, 2


class ReferenceError(RuntimeError):
    """The reference solver could not continue (event storm, solver failure)."""


@dataclass
class RefResult:
    """Result of :func:`simulate_reference`.

    Attributes
    ----------
    final : ndarray, shape (4,)
        Final (x1, x2, x3, x4).
    counts : dict
        Event counts by kind (same names as the library's).
    events : list of (float, str)
        (tau, kind) of every event, only when requested.
    nfev : int
        Right-hand-side evaluations in all segments.
    segments : int
        ``solve_ivp`` calls (smooth segments).
    wall_time_s : float
        Wall time of the integration.
    """

    final: np.ndarray
    counts: dict
    nfev: int
    segments: int
    wall_time_s: float
    events: list = field(default_factory=list)
    poincare: np.ndarray | None = None

    @property
    def penetration(self) -> float:
        """Bit position x3 at the end [x0]."""
        return float(self.final[2])


def _unpack(g):
    return (float(g.rho), float(g.xi), float(g.eta), float(g.a), float(g.b), float(g.r),
            float(g.mu), float(g.gamma_hat), float(g.kc), float(g.n), float(g.lam_hat),
            float(g.phi))


class _Scene:
    """The hybrid model of one scene: its force laws, vector fields and event indicators."""

    def __init__(self, groups):
        (self.rho, self.xi, self.eta, self.a, self.b, self.r, self.mu, self.gh, self.kc, self.n, self.lam,
         self.phi) = _unpack(groups)
        self.has_gap = math.isfinite(self.r) and self.kc > 0.0
        self.two_xi = 2.0 * self.xi
        # event margin (see the module docstring), set per segment
        self.margin = [0.0]

    def fc_of(self, d, dd, mc):
        """The contact force at overlap ``d`` and its rate ``dd`` in contact mode ``mc``."""
        if mc != CONTACT:
            return 0.0
        ad = abs(d)
        p = ad ** self.n if ad > 0.0 else 0.0
        return self.kc * (p if d >= 0.0 else -p) * (1.0 + self.lam * dd)

    def drive(self, y, mc):
        """The drive on the bit: spring, damper and contact force."""
        x1, x2, x3, x4 = y[0], y[1], y[2], y[3]
        dd = x2 - x4
        return (x1 - x3) + self.two_xi * dd + self.fc_of(x1 - x3 - self.r, dd, mc)

    def make_rhs(self, ms, mc):
        """The vector field of mode ``(ms, mc)``."""
        rho, eta, a, b, r, mu, gh, phi, two_xi = (self.rho, self.eta, self.a, self.b, self.r, self.mu, self.gh,
                                                  self.phi, self.two_xi)
        fc_of = self.fc_of
        sin = math.sin
        exp = math.exp
        if ms == SLIP:
            def f(t, y):
                x1, x2, x3, x4 = y
                dd = x2 - x4
                fk = (x1 - x3) + two_xi * dd
                fc = fc_of(x1 - x3 - r, dd, mc)
                arg = -gh * x4
                # a trial stage may overshoot to x4 < 0; inf makes solve_ivp reject the step
                ff = mu + (1.0 - mu) * exp(arg) if arg < 700.0 else math.inf
                return np.array((x2, b + a * sin(eta * t + phi) - fk - fc, x4, (fk + fc - ff) / rho))
        else:
            def f(t, y):
                x1, x2, x3, x4 = y
                dd = x2 - x4
                fk = (x1 - x3) + two_xi * dd
                fc = fc_of(x1 - x3 - r, dd, mc)
                return np.array((x2, b + a * sin(eta * t + phi) - fk - fc, 0.0, 0.0))
        return f

    def indicators(self, ms, mc, bounce):
        """(w, kind) of the events watched in a mode."""
        drive, r, lam = self.drive, self.r, self.lam
        out = []
        if ms == STICK:
            if not bounce:
                out.append((lambda t, y: drive(y, mc) - 1.0, "slip_start"))
                out.append((lambda t, y: -(drive(y, mc) + 1.0), "bounce"))
            else:
                out.append((lambda t, y: drive(y, mc) + 1.0, "bounce_end"))
        else:
            out.append((lambda t, y: -y[3], "stick"))
        if self.has_gap:
            if mc == FREE:
                out.append((lambda t, y: y[0] - y[2] - r, "impact"))
            else:
                out.append((lambda t, y: -(y[0] - y[2] - r), "separation"))
                if lam > 0.0:
                    if mc == CONTACT:
                        out.append((lambda t, y: -(1.0 + lam * (y[1] - y[3])), "clamp"))
                    else:
                        out.append((lambda t, y: 1.0 + lam * (y[1] - y[3]), "unclamp"))
        return out

    def make_events(self, ms, mc, bounce):
        """Terminal event functions of a mode, each tagged with its kind and indicator."""
        margin = self.margin
        evs = []
        for w, kind in self.indicators(ms, mc, bounce):
            def fun(t, y, w=w):
                return w(t, y) - margin[0]
            fun.terminal = True
            fun.direction = 1.0
            fun.kind = kind
            fun.w = w
            evs.append(fun)
        return evs

    def initial_modes(self, y):
        """The modes ``(ms, mc)`` of a state at rest."""
        ms = SLIP if y[3] > 0.0 else STICK
        mc = FREE
        if self.has_gap and y[0] - y[2] - self.r > 0.0:
            mc = CONTACT if 1.0 + self.lam * (y[1] - y[3]) > 0.0 else CLAMPED
        return ms, mc

    def reset(self, kind, y, modes, counts):
        """The reset map at the event ``kind`` (``y`` changed in place): ``(kind taken, (ms, mc,
        bounce))``; a stick whose drive is above the threshold is ``slip_on``."""
        ms, mc, bounce = modes
        if kind == "slip_start":
            ms = SLIP
            y[3] = 0.0
        elif kind == "stick":
            y[3] = 0.0
            if self.drive(y, mc) <= 1.0:
                ms = STICK
                if self.drive(y, mc) < -1.0:
                    bounce = True
                    counts["bounce"] += 1
            else:
                kind = "slip_on"
        elif kind == "impact":
            mc = CONTACT if 1.0 + self.lam * (y[1] - y[3]) > 0.0 else CLAMPED
        elif kind == "separation":
            mc = FREE
        elif kind == "clamp":
            mc = CLAMPED
        elif kind == "unclamp":
            mc = CONTACT
        elif kind == "bounce":
            bounce = True
        elif kind == "bounce_end":
            bounce = False
        return kind, (ms, mc, bounce)


def _segment(f, evs, span, y, solver: dict, poin_rows):
    """One ``solve_ivp`` call over ``span`` from ``y`` until its first terminal event; the
    Poincaré rows it passes are written into ``poin_rows = (poin, k_poin, T)`` (or None).
    Returns ``(sol, k_poin)``."""
    t = span[0]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        # rejected trial steps may overflow (inf friction past the stick event): harmless
        warnings.simplefilter("ignore", RuntimeWarning)
        sol = solve_ivp(f, span, y, events=evs, dense_output=poin_rows is not None, **solver)
    if sol.status < 0:
        raise ReferenceError(f"solve_ivp failed at tau = {t:.9g}: {sol.message}")
    if poin_rows is None:
        return sol, 0
    poin, k_poin, T = poin_rows
    t_new = float(sol.t[-1])
    y_new = np.array(sol.y[:, -1], dtype=float)
    while k_poin < poin.shape[0] and k_poin * T <= t_new + 1e-12 * max(1.0, t_new):
        tk = k_poin * T
        yk = y_new if tk >= t_new else sol.sol(tk)
        poin[k_poin] = (tk, *yk)
        k_poin += 1
    return sol, k_poin


def simulate_reference(groups, periods: float, *, method: str = "DOP853", rtol: float = 1e-12,
                       atol: float = 1e-14, events: bool = False, poincare: bool = False,
                       max_events_per_period: int = 2000, y0=None) -> RefResult:
    """Integrate a scene with ``solve_ivp`` and a Python hybrid-mode loop.

    Parameters
    ----------
    groups : hammerbit.model.params.Groups
        Nondimensional groups (only their attribute values are read).
    periods : float
        Horizon in forcing periods, from rest (or from ``y0``).
    method : str
        A ``solve_ivp`` explicit method: ``'RK45'``, ``'DOP853'``, ``'RK23'``.
    rtol, atol : float
        Tolerances passed to ``solve_ivp``.
    events : bool
        Keep the list of (tau, kind) of all events.
    poincare : bool
        Keep the state at every multiple of the forcing period (the segment
        containing the sample is evaluated on its dense output).
    max_events_per_period : int
        Guard against an event storm (a Zeno cascade or a bug): above this
        many events in one forcing period a :class:`ReferenceError` is raised.
    y0 : array_like, shape (4,), optional
        Initial state; zero by default (at rest: stuck, no contact).

    Returns
    -------
    RefResult
    """
    m = _Scene(groups)
    T = 2.0 * math.pi / m.eta
    t_end = periods * T
    y = np.zeros(4) if y0 is None else np.array(y0, dtype=float)
    ms, mc = m.initial_modes(y)
    bounce = False
    counts = {k: 0 for k in EVENT_KINDS}
    log = []
    t = 0.0
    nfev = 0
    nseg = 0
    n_poin = int(math.floor(periods + 1e-9)) + 1
    poin = np.full((n_poin, 5), np.nan) if poincare else None
    k_poin = 0
    if poincare:
        poin[0] = (0.0, *y)
        k_poin = 1
    win, win_events = -1, 0
    rhs_cache = {}
    ev_cache = {}
    r = m.r

    t0 = _time.perf_counter()
    while t_end - t > 4.0 * np.finfo(float).eps * max(abs(t_end), 1.0):
        key = (ms, mc)
        if key not in rhs_cache:
            rhs_cache[key] = m.make_rhs(ms, mc)
        ekey = (ms, mc, bounce)
        if ekey not in ev_cache:
            ev_cache[ekey] = m.make_events(ms, mc, bounce)
        evs = ev_cache[ekey]
        m.margin[0] = 16.0 * np.finfo(float).eps * max(1.0, abs(y[0]), abs(y[2]),
                                                       abs(r) if math.isfinite(r) else 0.0)
        # an indicator already past its margin: the event happens now (no integration)
        hit = None
        for e in evs:
            if e.w(t, y) > m.margin[0]:
                hit = e.kind
                break
        if hit is None:
            sol, k_poin = _segment(rhs_cache[key], evs, (t, t_end), y, {"method": method, "rtol": rtol, "atol": atol},
                                   (poin, k_poin, T) if poincare else None)
            nseg += 1
            nfev += sol.nfev
            t, y = float(sol.t[-1]), np.array(sol.y[:, -1], dtype=float)
            if sol.status != 1:
                break
            for i, te in enumerate(sol.t_events):
                if len(te):
                    hit = evs[i].kind
                    break
        kind, (ms, mc, bounce) = m.reset(hit, y, (ms, mc, bounce), counts)
        counts[kind] += 1
        if events:
            log.append((t, kind))
        w = int(math.floor(t / T))
        if w != win:
            win, win_events = w, 0
        win_events += 1
        if win_events > max_events_per_period:
            raise ReferenceError(f"event storm: more than {max_events_per_period} events in the forcing "
                                 f"period around tau = {t:.9g} (counts {counts})")
    wall = _time.perf_counter() - t0
    if poincare:
        poin = poin[:k_poin]
    return RefResult(final=y, counts=counts, nfev=nfev, segments=nseg, wall_time_s=wall,
                     events=log, poincare=poin)
