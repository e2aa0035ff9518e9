"""Physical parameters of the hammer–bit–rock model (Franca & Weber 2004).

Two frozen dataclasses describe the same model:

* :class:`RigParameters` — SI quantities of a physical hammer (masses, spring,
  friction, contact, gap and the driving forces);
* :class:`Groups` — the paper's nondimensional groups, which the kernels use.

``RigParameters.to_groups()`` and ``Groups.to_rig(scales)`` convert both ways;
:class:`Scales` carries the three numbers the nondimensional form loses
(hammer mass, spring stiffness and the static friction force ``F0``).

Every constructor validates: an out-of-range or non-finite value raises
:class:`ParameterError`, which names the parameter, its value and the allowed
range.  Conversion to the float array the kernels take happens only at the
kernel boundary (:meth:`Groups.to_kernel`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

__all__ = [
    "ParameterError",
    "RigParameters",
    "DEFAULT_SCALES",
    "Regime",
    "regime",
    "Groups",
    "Scales",
    "PRESETS",
    "preset",
    "P_RHO", "P_XI", "P_ETA", "P_A", "P_B", "P_R", "P_MU", "P_GAMMA", "P_KC",
    "P_N", "P_LAM", "P_PHI", "P_FEXT", "P_CONTACT", "N_P",
]

from .validation import RANGES, ParameterError, check


# ---------------------------------------------------------------------------
# Kernel parameter vector layout (nondimensional)
# ---------------------------------------------------------------------------
P_RHO = 0      # mass ratio m2/m1
P_XI = 1       # damping ratio
P_ETA = 2      # forcing frequency ratio
P_A = 3        # harmonic amplitude / F0
P_B = 4        # preload / F0
P_R = 5        # gap / x0 (inf: no impact device)
P_MU = 6       # kinetic / static friction
P_GAMMA = 7    # friction decay gamma * x0 * Omega
P_KC = 8       # contact stiffness Kc x0^n / F0
P_N = 9        # contact exponent
P_LAM = 10     # contact damping lam x0 Omega
P_PHI = 11     # forcing phase [rad]
P_FEXT = 12    # extra constant force on the hammer / F0 (FMU input, held over a step)
P_CONTACT = 13  # 1.0 if the contact code runs, 0.0 if the gap is disabled
N_P = 14


@dataclass(frozen=True)
class Scales:
    """Scales of the nondimensional form.

    Attributes
    ----------
    hammer_mass : float
        m1 [kg].
    stiffness : float
        K [N/m].
    friction_force : float
        F0 = mu_e F_N, the static friction threshold [N].
    """

    hammer_mass: float
    stiffness: float
    friction_force: float

    @property
    def omega(self) -> float:
        """Omega = sqrt(K/m1), the time scale [rad/s]."""
        return math.sqrt(self.stiffness / self.hammer_mass)

    @property
    def length(self) -> float:
        """x0 = F0/K, the length scale [m]."""
        return self.friction_force / self.stiffness

    @property
    def velocity(self) -> float:
        """x0 Omega, the velocity scale [m/s]."""
        return self.length * self.omega

    @property
    def time(self) -> float:
        """1/Omega, the time scale [s]: t = tau / Omega."""
        return 1.0 / self.omega

    def to_dict(self) -> dict:
        """The scales in SI, for JSON output (keys name their unit)."""
        return {"hammer_mass_kg": self.hammer_mass, "stiffness_n_per_m": self.stiffness,
                "friction_force_n": self.friction_force, "length_m": self.length,
                "omega_rad_per_s": self.omega, "velocity_m_per_s": self.velocity}


#: Scales of the paper's rig (section 4): m1 = 25.3 kg, K = 2170 N/m, F0 = 54 N.
DEFAULT_SCALES = Scales(25.3, 2170.0, 54.0)


@dataclass(frozen=True)
class Groups:
    """The paper's nondimensional groups, with the scales that make them SI.

    The twelve groups fix the dynamics; :attr:`scales` (m1, K, F0) turn its
    answers back into SI.  Every SI figure of a scene (penetration in m, rate
    of penetration in m/h, forces in N, time in s) uses the scene's own
    scales, so an override of ``K``, a mass or ``F_N`` changes them too.

    Attributes
    ----------
    rho : float
        Mass ratio m2/m1 [-], in (0, 1e3].
    xi : float
        Damping ratio C / (2 sqrt(K m1)) [-], in [0, 10].
    eta : float
        Frequency ratio omega/Omega [-], in (0, 100].
    a : float
        Harmonic amplitude A/F0 [-], in [0, 1e3].
    b : float
        Preload B/F0 [-], in [-1e3, 1e3].
    r : float
        Gap R/x0 [-], in [0, inf]; ``inf`` disables the impact device.
    mu : float
        Kinetic/static friction mu_d/mu_e [-], in (0, 1].
    gamma_hat : float
        Friction decay gamma x0 Omega [-], in [0, 1e6].
    kc : float
        Contact stiffness Kc x0^n / F0 [-], in [0, 1e12].
    n : float
        Hunt–Crossley exponent [-], in (0, 5].
    lam_hat : float
        Contact damping lam x0 Omega [-], in [0, 1e4].
    phi : float
        Forcing phase [rad], finite.
    scales : Scales
        m1 [kg], K [N/m] and F0 [N] of the scene (default: the paper's rig).
    mu_static : float
        mu_e [-]: splits F0 = mu_e F_N into a coefficient and a normal force
        when converting to SI; it does not change the dynamics.
    """

    rho: float
    xi: float
    eta: float
    a: float
    b: float
    r: float
    mu: float
    gamma_hat: float
    kc: float
    n: float
    lam_hat: float
    phi: float
    scales: Scales = DEFAULT_SCALES
    mu_static: float = 0.62

    def __post_init__(self):
        for name in GROUP_NAMES:
            object.__setattr__(self, name, check("group." + name, getattr(self, name), label=name))
        if not isinstance(self.scales, Scales):
            raise ParameterError("scales", self.scales, "a Scales(hammer_mass, stiffness, friction_force)")
        object.__setattr__(self, "mu_static", check("mu_static", self.mu_static))

    # -- derived ----------------------------------------------------------
    @property
    def period(self) -> float:
        """Forcing period in nondimensional time, 2 pi / eta."""
        return 2.0 * math.pi / self.eta

    @property
    def period_s(self) -> float:
        """Forcing period [s]: 2 pi / (eta Omega)."""
        return self.period / self.scales.omega

    @property
    def has_gap(self) -> bool:
        """True when the impact device exists and can act (finite gap, kc > 0)."""
        return math.isfinite(self.r) and self.kc > 0.0

    def values(self) -> dict:
        """The twelve groups as a dict (``inf`` kept as a float)."""
        return {name: getattr(self, name) for name in GROUP_NAMES}

    def replace(self, **changes) -> "Groups":
        """Copy with some groups changed (validated); the scales stay."""
        return replace(self, **changes)

    # -- SI ----------------------------------------------------------------
    def length_m(self, x: float) -> float:
        """A length in x0 -> m, with this scene's x0 = F0/K."""
        return x * self.scales.length

    def rop(self, per_period: float) -> dict:
        """A rate of penetration ``per_period`` [x0 per forcing period] in SI.

        Returns ``{"x0_per_period", "mm_per_period", "m_per_h"}``.
        """
        m = per_period * self.scales.length
        return {"x0_per_period": per_period, "mm_per_period": m * 1e3,
                "m_per_h": m / self.period_s * 3600.0}

    def to_kernel(self, *, extra_force: float = 0.0) -> np.ndarray:
        """Float array of length ``N_P`` in the kernel layout (``P_*`` indices)."""
        p = np.empty(N_P)
        p[P_RHO] = self.rho
        p[P_XI] = self.xi
        p[P_ETA] = self.eta
        p[P_A] = self.a
        p[P_B] = self.b
        p[P_R] = self.r
        p[P_MU] = self.mu
        p[P_GAMMA] = self.gamma_hat
        p[P_KC] = self.kc
        p[P_N] = self.n
        p[P_LAM] = self.lam_hat
        p[P_PHI] = self.phi
        p[P_FEXT] = extra_force
        p[P_CONTACT] = 1.0 if self.has_gap else 0.0
        return p

    def to_rig(self, scales: "Scales | None" = None, *, mu_static: "float | None" = None) -> "RigParameters":
        """SI parameters with these groups, at ``scales`` (default: the scene's own)."""
        scales = self.scales if scales is None else scales
        mu_static = self.mu_static if mu_static is None else mu_static
        m1, K, F0 = scales.hammer_mass, scales.stiffness, scales.friction_force
        Om, x0 = scales.omega, scales.length
        return RigParameters(
            hammer_mass=m1,
            bit_mass=self.rho * m1,
            stiffness=K,
            damping=2.0 * self.xi * math.sqrt(K * m1),
            mu_static=mu_static,
            mu_kinetic=self.mu * mu_static,
            friction_decay=self.gamma_hat / (x0 * Om),
            normal_force=F0 / mu_static,
            contact_stiffness=self.kc * F0 / x0 ** self.n,
            contact_exponent=self.n,
            contact_damping=self.lam_hat / (x0 * Om),
            gap=self.r * x0,
            preload=self.b * F0,
            amplitude=self.a * F0,
            frequency=self.eta * Om / (2.0 * math.pi),
            phase=self.phi,
        )


GROUP_NAMES = ("rho", "xi", "eta", "a", "b", "r", "mu", "gamma_hat", "kc", "n", "lam_hat", "phi")


@dataclass(frozen=True)
class RigParameters:
    """SI parameters of a resonance hammer on rock.

    Defaults are the rig of Franca & Weber (2004), section 4, at the Fig. 9
    operating point (b = 0.55, eta = 1) with an amplitude that drills
    (a = 0.15) and no impact device.

    Attributes
    ----------
    hammer_mass : float
        m1, the hammer (drillstring side) [kg], > 0.
    bit_mass : float
        m2, the bit/slider (rock side) [kg], > 0.
    stiffness : float
        K, spring joining hammer and bit [N/m], > 0.
    damping : float
        C, damper joining hammer and bit [N s/m], >= 0.
    mu_static : float
        mu_e, static friction coefficient [-], > 0.
    mu_kinetic : float
        mu_d, kinetic friction coefficient at high speed [-], in (0, mu_e].
    friction_decay : float
        gamma, velocity-weakening decay [s/m], >= 0.
    normal_force : float
        F_N, normal force on the rock [N], > 0.
    contact_stiffness : float
        Kc, Hunt–Crossley stiffness [N/m^n], >= 0.
    contact_exponent : float
        n, Hunt–Crossley exponent [-], in (0, 5].
    contact_damping : float
        lam, Hunt–Crossley damping [s/m], >= 0.
    gap : float
        R, hammer–bit gap [m], >= 0; ``inf`` disables impact.
    preload : float
        B, weight on bit pushing the hammer [N].
    amplitude : float
        A, harmonic force amplitude [N], >= 0.
    frequency : float
        omega / 2 pi, harmonic force frequency [Hz], > 0.
    phase : float
        phi, harmonic force phase [rad].
    """

    hammer_mass: float = 25.3
    bit_mass: float = 6.7
    stiffness: float = 2170.0
    damping: float = 2.0 * 0.074 * math.sqrt(2170.0 * 25.3)
    mu_static: float = 0.62
    mu_kinetic: float = 0.56
    friction_decay: float = 400.0
    normal_force: float = 54.0 / 0.62
    contact_stiffness: float = 2.1e8
    contact_exponent: float = 1.3
    contact_damping: float = 0.95
    gap: float = math.inf
    preload: float = 0.55 * 54.0
    amplitude: float = 0.15 * 54.0
    frequency: float = math.sqrt(2170.0 / 25.3) / (2.0 * math.pi)
    phase: float = math.pi / 2

    def __post_init__(self):
        for f in fields(self):
            object.__setattr__(self, f.name, check(f.name, getattr(self, f.name)))
        if self.mu_kinetic > self.mu_static:
            raise ParameterError("mu_kinetic", self.mu_kinetic,
                                 f"(0, mu_static = {self.mu_static:g}]: kinetic friction above static")

    @property
    def scales(self) -> Scales:
        """Scales of the nondimensional form (m1, K, F0 = mu_e F_N)."""
        return Scales(self.hammer_mass, self.stiffness, self.mu_static * self.normal_force)

    def to_groups(self) -> Groups:
        """The paper's nondimensional groups of these parameters."""
        s = self.scales
        F0, x0, Om = s.friction_force, s.length, s.omega
        return Groups(
            rho=self.bit_mass / self.hammer_mass,
            xi=self.damping / (2.0 * math.sqrt(self.stiffness * self.hammer_mass)),
            eta=2.0 * math.pi * self.frequency / Om,
            a=self.amplitude / F0,
            b=self.preload / F0,
            r=self.gap / x0,
            mu=self.mu_kinetic / self.mu_static,
            gamma_hat=self.friction_decay * x0 * Om,
            kc=self.contact_stiffness * x0 ** self.contact_exponent / F0,
            n=self.contact_exponent,
            lam_hat=self.contact_damping * x0 * Om,
            phi=self.phase,
            scales=s,
            mu_static=self.mu_static,
        )

    def replace(self, **changes) -> "RigParameters":
        """Copy with some fields changed (validated)."""
        return replace(self, **changes)


# ---------------------------------------------------------------------------
# Presets
# ---------------------------------------------------------------------------
RIG = RigParameters()
RIG_SCALES = RIG.scales   # == DEFAULT_SCALES

#: Short SI names accepted by ``--set`` (the spec's symbols) -> RigParameters field.
SI_ALIASES = {
    "m1": "hammer_mass", "m2": "bit_mass", "K": "stiffness", "C": "damping",
    "mu_e": "mu_static", "mu_d": "mu_kinetic", "gamma": "friction_decay",
    "F_N": "normal_force", "Kc": "contact_stiffness", "lam": "contact_damping",
    "R": "gap", "B": "preload", "A": "amplitude", "f": "frequency",
}


def _lab() -> Groups:
    return RIG.to_groups()


def _paper_fig9() -> Groups:
    return RIG.to_groups().replace(eta=1.0, b=0.55, phi=math.pi / 2, mu=0.85, r=math.inf, a=0.11)


def _paper_fig12() -> Groups:
    return _paper_fig9().replace(r=0.84, a=0.06)


def _chaos() -> Groups:
    # found by a scan (README, "Chaos"): impact device, low preload, lower kinetic friction
    return _paper_fig12().replace(eta=0.8, b=0.3, mu=0.6, a=0.1967)


PRESETS = {
    "lab": _lab,
    "paper-fig9": _paper_fig9,
    "paper-fig12": _paper_fig12,
    "chaos": _chaos,
}


def preset(name: str) -> Groups:
    """Nondimensional groups of a named preset.

    Parameters
    ----------
    name : {'lab', 'paper-fig9', 'paper-fig12', 'chaos'}
        ``lab``: the rig with its identified friction (mu = 0.56/0.62) at the
        Fig. 9 operating point, a = 0.15, no gap.  ``paper-fig9``: eta = 1,
        b = 0.55, phi = pi/2, mu = 0.85 (the calibration of model.md), no gap,
        a = 0.11.  ``paper-fig12``: ``paper-fig9`` with r = 0.84 and a = 0.06.
        ``chaos``: ``paper-fig12`` with eta = 0.8, b = 0.3, mu = 0.6, a = 0.1967,
        a strange attractor (positive largest Lyapunov exponent; Fig. 15).
    """
    try:
        return PRESETS[name]()
    except KeyError:
        raise ParameterError("preset", name, "one of " + ", ".join(PRESETS)) from None


#: FMU variable names that are not RigParameters fields, accepted by ``--set`` too.
FMU_ALIASES = {"impact_gap": "gap"}


def setting_target(key: str, value=None) -> tuple[str, str]:
    """Where a ``--set`` name points: ``("group", name)`` or ``("rig", field)``.

    Accepted names: the groups (``a``, ``b``, ``eta`` ...), the spec's SI
    symbols (``m1``, ``K``, ``mu_d``, ``B``, ``A``, ``f`` ...), the
    :class:`RigParameters` fields, which are also the FMU's variable names
    (``hammer_mass``, ``preload``, ``amplitude``, ``frequency`` ...).
    """
    if key in GROUP_NAMES:
        return "group", key
    if key in SI_ALIASES:
        return "rig", SI_ALIASES[key]
    if key in _RIG_FIELDS:
        return "rig", key
    if key in FMU_ALIASES:
        return "rig", FMU_ALIASES[key]
    raise ParameterError(key, "?" if value is None else value, "a known name: a group (" + ", ".join(GROUP_NAMES)
                         + "), an SI symbol (" + ", ".join(SI_ALIASES)
                         + ") or an SI/FMU name (" + ", ".join(_RIG_FIELDS) + ")")


def apply_settings(groups: Groups, settings: dict) -> Groups:
    """Apply ``{name: value}`` overrides given by group, SI symbol or SI/FMU name.

    Group names change the group directly.  SI names are applied to the scene's
    SI parameters (at its own scales) and converted back, so e.g. ``K`` changes
    every group that depends on it *and* the scales that turn results into SI.
    Errors name the parameter as it was typed.
    """
    g_changes, si_changes, typed = {}, {}, {}
    for key, value in settings.items():
        kind, name = setting_target(key, value)
        typed[name] = key
        (g_changes if kind == "group" else si_changes)[name] = value
    try:
        if si_changes:
            groups = groups.to_rig(mu_static=float(si_changes.get("mu_static", groups.mu_static))
                                   if _is_real(si_changes.get("mu_static", groups.mu_static))
                                   else groups.mu_static).replace(**si_changes).to_groups()
        if g_changes:
            groups = groups.replace(**g_changes)
    except ParameterError as e:
        raise e.renamed(typed.get(e.name, e.name)) from None
    return groups


def _is_real(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


_RIG_FIELDS = tuple(f.name for f in fields(RigParameters))


# ---------------------------------------------------------------------------
# Regimes: where the model's answer is not drilling
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Regime:
    """Where a scene lies relative to the model's validity domain.

    Attributes
    ----------
    bounce : bool
        ``a >= b``: the harmonic force can exceed the preload, the drive on
        the bit can fall below ``-F_s`` and the rock would have to pull the
        bit back (bit bounce).  The model holds the bit and counts it.
    overload : bool
        ``a + b > 1``: preload plus amplitude exceed the static threshold
        ``F0 = mu_e F_N``, outside the paper's domain ``a + b <= 1``.
    runaway : bool
        ``b > f_floor`` where ``f_floor`` is the kinetic friction the bit
        feels at high speed: ``mu`` when ``gamma_hat > 0``, else 1.  Adding
        the two equations of motion gives ``m1 x_b'' + m2 x_s'' = B + F_h(t)
        - F_f(v_s)`` while the bit slips; ``F_h`` averages to zero over a
        period and ``F_f`` decreases to ``mu_d F_N`` as ``v_s`` grows.  So if
        ``B > mu_d F_N`` a fast-sliding bit gains momentum every period and
        the drift grows without bound; if ``B <= mu_d F_N`` the friction
        exceeds the preload at every speed and the momentum stays bounded.
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
    """The :class:`Regime` flags of a scene (pure function of its groups)."""
    floor = groups.mu if groups.gamma_hat > 0.0 else 1.0
    return Regime(bounce=groups.a >= groups.b, overload=groups.a + groups.b > 1.0,
                  runaway=groups.b > floor)
