"""The two parameter sets of the hammer–bit–rock model (Franca & Weber 2004): SI rig and nondimensional groups.

Two frozen dataclasses describe the same model:

* :class:`RigParameters` — SI quantities of a physical hammer (masses, spring,
  friction, contact, gap and the driving forces);
* :class:`Groups` — the paper's nondimensional groups, which the kernels use.

``RigParameters.to_groups()`` and ``Groups.to_rig(scales)`` convert both ways;
:class:`~.scales.Scales` carries the three numbers the nondimensional form loses
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

from .fmu_description import GROUP_FORMULAS, KERNEL_SLOTS, SI_NAMES, si_to_groups
from .kernel_layouts import N_P, P_CONTACT, P_FEXT
from .scales import DEFAULT_SCALES, Scales
from .validation import ParameterError, check

__all__ = ["ParameterError", "RigParameters", "Groups", "GROUP_NAMES"]


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
        for name, slot in KERNEL_SLOTS:
            p[slot] = getattr(self, name)
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


GROUP_NAMES = tuple(name for name, _ in GROUP_FORMULAS)


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
        """The paper's nondimensional groups of these parameters (the formulas of
        :mod:`.fmu_description`, which the native FMU evaluates in C to the same bits)."""
        _, groups = si_to_groups({name: getattr(self, name) for name in SI_NAMES})
        return Groups(**groups, scales=self.scales, mu_static=self.mu_static)

    def replace(self, **changes) -> "RigParameters":
        """Copy with some fields changed (validated)."""
        return replace(self, **changes)
