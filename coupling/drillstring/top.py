"""Top conditions of the string in the co-simulation: a fixed hook, a constant feed, an auto-driller.

The hook point (the travelling block) moves down by ``u_top(t)`` [m]; the
string's own top boundary (``fixed``, or a ``spring`` to the block) moves
with it.  The string is written in coordinates **relative to the block**,
``r = u - u_top``: its stiffness, its structural (modal) damping and a top
spring act on ``r`` only, so the block's motion enters through

* the interface: the hammer's position relative to the block, ``x_h - u_top``;
* the inertia of the string's rigid translation, ``-(M_full 1) a_top`` on the
  DOFs (``M_full`` the mass matrix with the top node's column kept).

A prescribed top velocity is therefore an input (a polynomial in time over
any step), and a linear controller on the hook load is a linear feedback
that augments the linear system; either way the string side stays exactly
steppable for any communication step.

* ``fixed``: ``u_top = 0`` (the string as the file gives it).
* ``feed``: ``u_top = V (t - t0)`` with a constant downward velocity ``V``
  [m/s]; the string starts moving with the block (``r = 0``, ``r' = 0``).
* ``auto-driller``: a PI controller on the hook load, the way a rig's
  auto-driller holds the WOB with the drawworks.  With ``e`` the hook load
  minus its set point (the buoyed weight minus the WOB set point; a positive
  ``e`` means too little weight on the bit) the block is lowered at

      v_top = k_p e + k_i z,    z' = e.

  The set point is the WOB of the static equilibrium, so the run starts at
  rest on its set point.  In velocity form the controller acts like a
  dashpot ``1 / k_p`` in series with an inerter ``1 / k_i`` between the block
  and the derrick: it damps the string's slow modes rather than drive them
  (the closed loop is stable from a hundredth to a hundred times the default
  gains on the field string, ``tests/test_top.py``).
  Default tuning (:func:`auto_driller_gains`): on the quasi-static string
  (the bit held by the rock; the string, the interface and the hammer spring
  in series, stiffness ``k_s``), ``e' = -k_s v_top + k_s ROP``, so the loop is
  ``e'' + k_s k_p e' + k_s k_i e = k_s ROP'``: a second-order loop of natural
  frequency ``w_n = sqrt(k_s k_i)`` and damping ratio ``zeta = k_s k_p / (2 w_n)``.
  ``w_n`` is a fifth of the string's first axial mode (the quasi-static
  picture holds below it, and the bit's slip cycles at a few hertz pass
  through unanswered) and ``zeta = 1`` (no overshoot):
  ``k_p = 2 w_n / k_s``, ``k_i = w_n^2 / k_s``.  A constant ROP then leaves no
  error in the mean WOB.

:func:`top_matrices` builds the matrices of the string side with its top
condition (the co-simulation master and the string FMU step them).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .boundary import Boundary
from .drill_string import DrillString
from .validation import DrillStringError

__all__ = ["TOP_KINDS", "TopCondition", "AutoDrillerGains", "auto_driller_gains", "SideMatrices", "top_matrices",
           "BANDWIDTH_FRACTION", "DAMPING_RATIO", "M_PER_H", "SETTLE_TIME_CONSTANTS"]

TOP_KINDS = ("fixed", "feed", "auto-driller")
#: Natural frequency of the default auto-driller loop as a fraction of the string's first axial mode.
BANDWIDTH_FRACTION = 0.2
#: Damping ratio of the default auto-driller loop (critical: no overshoot of the WOB).
DAMPING_RATIO = 1.0
#: Time constants ``1 / w_n`` the auto-driller's loop takes to settle.
SETTLE_TIME_CONSTANTS = 6.0
#: Metres per hour in metres per second.
M_PER_H = 1.0 / 3600.0
#: Largest feed velocity accepted [m/s] (1000 m/h: far above any drilling rate).
MAX_FEED = 1000.0 * M_PER_H


@dataclass(frozen=True)
class TopCondition:
    """How the string's top (the hook) moves.

    Attributes
    ----------
    kind : {'fixed', 'feed', 'auto-driller'}
    feed_velocity : float
        ``feed``: downward velocity of the block [m/s].
    proportional_gain : float, optional
        ``auto-driller``: k_p [m/s per N of hook-load error]; None: the default
        tuning (:func:`auto_driller_gains`).
    integral_gain : float, optional
        ``auto-driller``: k_i [m/s per N s]; None: the default tuning.
    """

    kind: str = "fixed"
    feed_velocity: float = 0.0
    proportional_gain: Optional[float] = None
    integral_gain: Optional[float] = None

    def __post_init__(self):
        if self.kind not in TOP_KINDS:
            raise ValueError(f"top = {self.kind!r}: allowed {', '.join(TOP_KINDS)}")
        v = self.feed_velocity
        if not (isinstance(v, (int, float)) and math.isfinite(v) and abs(v) <= MAX_FEED):
            raise ValueError(f"feed_velocity = {v!r} m/s: allowed range -{MAX_FEED:.4g} to {MAX_FEED:.4g} m/s "
                             f"(1000 m/h)")
        if self.kind != "feed" and v != 0.0:
            raise ValueError(f"feed_velocity = {v!r}: only the 'feed' top takes a feed velocity")
        for name in ("proportional_gain", "integral_gain"):
            g = getattr(self, name)
            if g is None:
                continue
            if self.kind != "auto-driller":
                raise ValueError(f"{name} = {g!r}: only the 'auto-driller' top takes gains")
            if not (isinstance(g, (int, float)) and math.isfinite(g) and 0.0 <= g <= 1.0):
                raise ValueError(f"{name} = {g!r}: allowed range 0 <= {name} <= 1 (SI: m/s per N"
                                 f"{'' if name == 'proportional_gain' else ' s'})")

    # constructors ------------------------------------------------------------
    @classmethod
    def fixed(cls) -> "TopCondition":
        """The hook does not move."""
        return cls("fixed")

    @classmethod
    def feed(cls, velocity: float) -> "TopCondition":
        """The block moves down at ``velocity`` [m/s]."""
        return cls("feed", feed_velocity=float(velocity))

    @classmethod
    def auto_driller(cls, proportional_gain: Optional[float] = None,
                     integral_gain: Optional[float] = None) -> "TopCondition":
        """A PI controller on the hook load that holds the static WOB (default gains: the tuning
        of :func:`auto_driller_gains`)."""
        return cls("auto-driller", proportional_gain=proportional_gain, integral_gain=integral_gain)

    @classmethod
    def parse(cls, text: str, *, where: str = "--top") -> "TopCondition":
        """``fixed``, ``feed:RATE`` (RATE in m/h, downward) or ``auto-driller[:kp=..,ki=..]`` (SI gains).

        Raises ValueError naming ``where`` and the text as typed."""
        s = str(text).strip()
        kind, _, rest = s.partition(":")
        kind = kind.strip().lower().replace("_", "-")
        try:
            if kind == "fixed" and not rest:
                return cls.fixed()
            if kind == "feed":
                if not rest:
                    raise ValueError("give the rate, feed:RATE in m/h")
                try:
                    rate = float(rest)
                except ValueError:
                    raise ValueError(f"RATE {rest.strip()!r} is not a number (m/h)") from None
                return cls.feed(rate * M_PER_H)
            if kind in ("auto-driller", "autodriller"):
                gains = {}
                for item in filter(None, (p.strip() for p in rest.split(","))):
                    k, eq, v = item.partition("=")
                    k = k.strip().lower()
                    if not eq or k not in ("kp", "ki"):
                        raise ValueError(f"unknown setting {item!r}: allowed kp=VALUE, ki=VALUE")
                    try:
                        gains[{"kp": "proportional_gain", "ki": "integral_gain"}[k]] = float(v)
                    except ValueError:
                        raise ValueError(f"{k} = {v.strip()!r} is not a number") from None
                return cls("auto-driller", **gains)
        except ValueError as e:
            raise ValueError(f"{where} {s}: {e}") from None
        raise ValueError(f"{where} {s}: allowed fixed, feed:RATE (m/h, downward), auto-driller[:kp=..,ki=..]")

    @property
    def moves(self) -> bool:
        return self.kind != "fixed"

    def to_dict(self) -> dict:
        """JSON-ready: kind, feed [m/s and m/h], the gains as given."""
        out = {"kind": self.kind}
        if self.kind == "feed":
            out.update(feed_velocity_m_per_s=self.feed_velocity, feed_m_per_h=self.feed_velocity / M_PER_H)
        if self.kind == "auto-driller":
            out.update(proportional_gain=self.proportional_gain, integral_gain=self.integral_gain)
        return out


@dataclass(frozen=True)
class AutoDrillerGains:
    """Gains of the auto-driller and what they were derived from.

    Attributes
    ----------
    proportional_gain : float
        k_p [m/s per N].
    integral_gain : float
        k_i [m/s per N s].
    series_stiffness : float
        k_s: string, interface and hammer spring in series, bit held [N/m].
    first_mode_hz : float
        First axial mode of the string on the hammer (bit held) [Hz].
    natural_frequency_hz : float
        Natural frequency of the quasi-static loop ``sqrt(k_s k_i) / 2 pi`` [Hz].
    damping_ratio : float
        ``k_s k_p / (2 w_n)`` [-].
    """

    proportional_gain: float
    integral_gain: float
    series_stiffness: float
    first_mode_hz: float
    natural_frequency_hz: float
    damping_ratio: float
    loop_eigenvalue: complex = complex(math.nan, math.nan)
    """The closed loop's eigenvalue with the largest real part (string and controller, hammer
    held) [1/s] (:mod:`.top_stability`)."""
    retuned_from: Optional[tuple] = None
    """The default gains ``(k_p, k_i)`` when they were unstable and these replace them."""

    @property
    def retune_note(self) -> str:
        """For people: why the gains are not the default tuning (empty when they are)."""
        if self.retuned_from is None:
            return ""
        kp, ki = self.retuned_from
        return (f"the default auto-driller gains (kp = {kp:.4g} m/s/N, ki = {ki:.4g} m/s/(N s)) make the closed "
                f"loop unstable; retuned to kp = {self.proportional_gain:.4g}, ki = {self.integral_gain:.4g} "
                f"(the loop's natural frequency scaled down, damping ratio kept, until its largest real part "
                f"is {self.loop_eigenvalue.real:.4g} 1/s)")

    @property
    def settling_time_s(self) -> float:
        """Time [s] the loop needs to settle: :data:`SETTLE_TIME_CONSTANTS` of ``1 / w_n`` (critically
        damped, the WOB is then within 2 % of its set point after a step in the ROP).  A study
        measures the sustained ROP after it."""
        return SETTLE_TIME_CONSTANTS / (2.0 * math.pi * self.natural_frequency_hz)

    def to_dict(self) -> dict:
        out = {k: float(getattr(self, k)) for k in self.__dataclass_fields__
               if k not in ("loop_eigenvalue", "retuned_from")}
        out["settling_time_s"] = self.settling_time_s
        out["loop_max_real_part_per_s"] = float(self.loop_eigenvalue.real)
        out["loop_frequency_hz"] = abs(float(self.loop_eigenvalue.imag)) / (2.0 * math.pi)
        out["retuned"] = self.retuned_from is not None
        if self.retuned_from is not None:
            out["default_proportional_gain"], out["default_integral_gain"] = map(float, self.retuned_from)
            out["retune_note"] = self.retune_note
        return out


def series_stiffness(string: DrillString, interface_stiffness: float, hammer_stiffness: float) -> float:
    """Static stiffness [N/m] seen from the hook with the bit held: string (and a top spring),
    interface and hammer spring in series."""
    from .statics import static_compliance
    c_string = static_compliance(string, None, "free")
    return 1.0 / (c_string + 1.0 / interface_stiffness + 1.0 / hammer_stiffness)


def auto_driller_gains(string: DrillString, top: TopCondition, *, interface_stiffness: float,
                       hammer_stiffness: float, mass: str = "mixed") -> AutoDrillerGains:
    """The auto-driller's gains: those of ``top``, else the default tuning (module docstring).

    The first mode is that of the string with its top boundary and, at the
    bit, the interface and the hammer spring in series (the bit held).
    """
    from .modes import modes
    k_s = series_stiffness(string, interface_stiffness, hammer_stiffness)
    k_b = 1.0 / (1.0 / interface_stiffness + 1.0 / hammer_stiffness)
    f1 = float(modes(string, None, Boundary.spring(k_b, mass=string.bit_mass), count=1, mass=mass,
                     rtol=None).frequencies_hz[0])
    w_n = 2.0 * math.pi * f1 * BANDWIDTH_FRACTION
    kp = 2.0 * DAMPING_RATIO * w_n / k_s if top.proportional_gain is None else float(top.proportional_gain)
    ki = w_n * w_n / k_s if top.integral_gain is None else float(top.integral_gain)
    wn = math.sqrt(k_s * ki)
    return AutoDrillerGains(kp, ki, k_s, f1, wn / (2 * math.pi), k_s * kp / (2 * wn) if wn > 0 else math.inf)


@dataclass(frozen=True)
class SideMatrices:
    """The string side (string + interface spring) with its top condition, as one linear system.

    With the state ``xi`` (the string's state relative to the block, then the
    top's states: ``u_top`` and the controller's integral ``z`` for the
    auto-driller) and the hammer's motion ``w = (x_h - u_feed, v_h - V)``
    (deviation from equilibrium, relative to a feed's block; ``u_feed = 0``
    otherwise):

        xi' = A1 xi + E w,   F_i - W = frow . xi - k_i w_0 - c_i w_1

    and the outputs ``bit u = Cu . xi (+ u_feed)``, ``bit v = Cv . xi (+ V)``,
    ``hook load - hook load at equilibrium = Ct . xi``.

    Attributes
    ----------
    A1, E, frow, Cu, Cv, Ct : ndarray
    n_string : int
        States of the string itself (the first ``n_string`` of ``xi``).
    kinds : tuple of str
        Per state: ``x`` (a displacement-like state), ``v`` (velocity-like),
        ``z`` (the integral of a force, N s).
    top : TopCondition
    gains : AutoDrillerGains, optional
    """

    A1: np.ndarray
    E: np.ndarray
    frow: np.ndarray
    Cu: np.ndarray
    Cv: np.ndarray
    Ct: np.ndarray
    n_string: int
    kinds: tuple
    top: TopCondition = field(default_factory=TopCondition)
    gains: Optional[AutoDrillerGains] = None

    @property
    def feed_velocity(self) -> float:
        """Velocity of a prescribed feed [m/s] (0 unless ``feed``)."""
        return self.top.feed_velocity if self.top.kind == "feed" else 0.0


def rigid_inertia(string: DrillString, ss, mass: str) -> np.ndarray:
    """Generalized force per unit block acceleration on the state-space coordinates of ``ss``:
    ``M_full 1`` on the DOFs (the top node's mass column kept), projected on the modes when modal."""
    from .assembly import assemble
    asm = assemble(string, None, ss.bottom, mass=mass)
    rows = asm.md_full.copy()
    rows[:-1] += asm.me_full
    rows[1:] += asm.me_full
    g = rows[asm.start:asm.stop]
    return g if ss.basis is None else ss.basis.T @ g


def top_matrices(string: DrillString, ss, top: TopCondition, *, interface_stiffness: float,
                 interface_damping: float, hammer_stiffness: float, mass: str = "mixed",
                 check: bool = True) -> SideMatrices:
    """The string side's linear system with its top condition (see :class:`SideMatrices`).

    ``ss`` is the string's :class:`~hammerbit.drillstring.state_space.StateSpace` with the
    hammer interface at the bottom.  With the auto-driller and ``check``, the closed loop's
    eigenvalues are checked (:mod:`.top_stability`): unstable default gains are retuned
    (``gains.retuned_from``), unstable gains the user gave raise
    :class:`~.top_stability.ControllerUnstableError`.  ``check=False``: the gains as they are
    (a finite difference in the gains).
    """
    ki, ci = float(interface_stiffness), float(interface_damping)
    n = ss.A.shape[0]
    nq = n // 2
    B = ss.B[:, 0]
    Cu, Cv, Ct = ss.C[0].copy(), ss.C[1].copy(), ss.C[2].copy()
    A1 = ss.A - np.outer(B, ki * Cu + ci * Cv)
    E = np.column_stack((B * ki, B * ci))
    frow = ki * Cu + ci * Cv
    kinds = ("x",) * nq + ("v",) * (n - nq)
    if top.moves and any(s.viscous_damping > 0.0 for s in string.sections):
        raise DrillStringError(f"string '{string.name}'", "viscous_damping",
                               max(s.viscous_damping for s in string.sections),
                               f"0 with the top '{top.kind}': the drag on the feed's rigid translation is "
                               f"not modelled")
    if top.kind != "auto-driller":
        return SideMatrices(A1, E, frow, Cu, Cv, Ct, n, kinds, top)
    gains = auto_driller_gains(string, top, interface_stiffness=ki, hammer_stiffness=hammer_stiffness, mass=mass)
    dCt = Ct @ A1                          # d/dt (Ct xi): Ct reads displacements, E and the inertia act on velocities
    g_acc = np.zeros(n)
    g_acc[nq:] = -np.linalg.solve(ss.mass_matrix, rigid_inertia(string, ss, mass))
    parts = (A1, E, frow, Cu, Cv, Ct, dCt, g_acc, ki, ci)
    if check:
        gains = _checked_gains(gains, top, lambda kp, kI: _closed_loop(parts, kp, kI)[0])
    A, Ea, fr, cu, cv, ct = _closed_loop(parts, gains.proportional_gain, gains.integral_gain)
    return SideMatrices(A, Ea, fr, cu, cv, ct, n, kinds + ("x", "z"), top, gains)


def _checked_gains(gains: AutoDrillerGains, top: TopCondition, build) -> AutoDrillerGains:
    """``gains`` with their loop eigenvalue when the loop is stable; default gains that are not
    are retuned (:func:`~.top_stability.stable_gains`); gains the user gave are refused."""
    from dataclasses import replace
    from .top_stability import ControllerUnstableError, stable_gains
    kp, kI, k_s = gains.proportional_gain, gains.integral_gain, gains.series_stiffness
    first, ok = stable_gains(build, k_s, kp, kI)
    if first.stable or (kp == 0.0 and kI == 0.0):
        return replace(gains, loop_eigenvalue=first.eigenvalue)
    given = top.proportional_gain is not None or top.integral_gain is not None
    if given or ok is None:
        raise ControllerUnstableError(kp, kI, first.eigenvalue,
                                      None if ok is None else (ok.proportional_gain, ok.integral_gain))
    wn = math.sqrt(k_s * ok.integral_gain)
    return replace(gains, proportional_gain=ok.proportional_gain, integral_gain=ok.integral_gain,
                   natural_frequency_hz=wn / (2 * math.pi), damping_ratio=k_s * ok.proportional_gain / (2 * wn),
                   loop_eigenvalue=ok.eigenvalue, retuned_from=(kp, kI))


def _closed_loop(parts: tuple, kp: float, kI: float) -> tuple:
    """``(A, E, frow, Cu, Cv, Ct)`` of the string side closed by the auto-driller with gains
    ``(kp, kI)``; ``parts`` the open string side's (see :func:`top_matrices`)."""
    A1, E, frow, Cu, Cv, Ct, dCt, g_acc, ki, ci = parts
    n = A1.shape[0]
    N = n + 2
    iu, iz = n, n + 1
    g = np.zeros(N)                        # v_top = g . X
    g[:n] = kp * Ct
    g[iz] = kI
    a = np.zeros(N)                        # a_top = a . X
    a[:n] = kp * dCt + kI * Ct
    A = np.zeros((N, N))
    A[:n, :n] = A1
    A[:n] += np.outer(g_acc, a)
    A[:n, iu] -= E[:, 0]                   # the hammer relative to the block: x_h - u_top ...
    A[:n] -= np.outer(E[:, 1], g)          # ... and v_h - v_top
    A[iu] = g
    A[iz, :n] = Ct
    Ea = np.zeros((N, 2))
    Ea[:n] = E
    fr = np.zeros(N)
    fr[:n] = frow
    fr[iu] += ki
    fr += ci * g
    cu = np.zeros(N)
    cu[:n] = Cu
    cu[iu] = 1.0
    cv = np.zeros(N)
    cv[:n] = Cv
    cv += g
    ct = np.zeros(N)
    ct[:n] = Ct
    return A, Ea, fr, cu, cv, ct
