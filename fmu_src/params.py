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
    "Groups",
    "Scales",
    "PRESETS",
    "preset",
    "P_RHO", "P_XI", "P_ETA", "P_A", "P_B", "P_R", "P_MU", "P_GAMMA", "P_KC",
    "P_N", "P_LAM", "P_PHI", "P_FEXT", "P_CONTACT", "N_P",
]

G_ACCEL = 9.81  # m/s^2, for documentation of weights only


class ParameterError(ValueError):
    """A parameter is out of range or not finite.

    Attributes
    ----------
    name : str
        Parameter name as the caller spelled it.
    value : object
        The offending value.
    allowed : str
        The allowed range, human-readable.
    """

    def __init__(self, name: str, value, allowed: str):
        self.name = name
        self.value = value
        self.allowed = allowed
        super().__init__(f"parameter {name!r} = {value!r} is out of range: allowed {allowed}")


def _check(name: str, value, lo: float, hi: float, *, lo_open=False, hi_open=False,
           allow_inf=False) -> float:
    """Validate one real value against [lo, hi] (open ends as flagged)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, value, f"a real number in {_rng(lo, hi, lo_open, hi_open)}") from None
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ParameterError(name, value, f"a finite number in {_rng(lo, hi, lo_open, hi_open)}")
    if allow_inf and math.isinf(v) and v > 0:
        return v
    bad = (v < lo) or (v > hi) or (lo_open and v == lo) or (hi_open and v == hi)
    if bad:
        raise ParameterError(name, value, _rng(lo, hi, lo_open, hi_open))
    return v


def _rng(lo, hi, lo_open, hi_open) -> str:
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


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


@dataclass(frozen=True)
class Groups:
    """The paper's nondimensional groups (model.md, "Nondimensional form").

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

    _RANGES = {
        "rho": (0.0, 1e3, True, False, False),
        "xi": (0.0, 10.0, False, False, False),
        "eta": (0.0, 100.0, True, False, False),
        "a": (0.0, 1e3, False, False, False),
        "b": (-1e3, 1e3, False, False, False),
        "r": (0.0, 1e12, False, False, True),
        "mu": (0.0, 1.0, True, False, False),
        "gamma_hat": (0.0, 1e6, False, False, False),
        "kc": (0.0, 1e12, False, False, False),
        "n": (0.0, 5.0, True, False, False),
        "lam_hat": (0.0, 1e4, False, False, False),
        "phi": (-1e6, 1e6, False, False, False),
    }

    def __post_init__(self):
        for f in fields(self):
            lo, hi, lo_open, hi_open, allow_inf = self._RANGES[f.name]
            object.__setattr__(self, f.name, _check(f.name, getattr(self, f.name), lo, hi,
                                                    lo_open=lo_open, hi_open=hi_open,
                                                    allow_inf=allow_inf))

    # -- derived ----------------------------------------------------------
    @property
    def period(self) -> float:
        """Forcing period in nondimensional time, 2 pi / eta."""
        return 2.0 * math.pi / self.eta

    @property
    def has_gap(self) -> bool:
        """True when the impact device exists and can act (finite gap, kc > 0)."""
        return math.isfinite(self.r) and self.kc > 0.0

    def replace(self, **changes) -> "Groups":
        """Copy with some groups changed (validated)."""
        return replace(self, **changes)

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

    def to_rig(self, scales: Scales, *, mu_static: float = 0.62) -> "RigParameters":
        """SI parameters with these groups, for the given scales.

        ``mu_static`` splits F0 = mu_e F_N into a friction coefficient and a
        normal force; it does not change the dynamics.
        """
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
        c = self._set
        c("hammer_mass", 1e-9, 1e9, lo_open=False)
        c("bit_mass", 1e-9, 1e9)
        c("stiffness", 1e-9, 1e15)
        c("damping", 0.0, 1e12)
        c("mu_static", 1e-9, 10.0)
        c("mu_kinetic", 1e-9, self.mu_static)
        c("friction_decay", 0.0, 1e9)
        c("normal_force", 1e-12, 1e12)
        c("contact_stiffness", 0.0, 1e20)
        c("contact_exponent", 0.0, 5.0, lo_open=True)
        c("contact_damping", 0.0, 1e9)
        c("gap", 0.0, 1e9, allow_inf=True)
        c("preload", -1e12, 1e12)
        c("amplitude", 0.0, 1e12)
        c("frequency", 0.0, 1e9, lo_open=True)
        c("phase", -1e6, 1e6)

    def _set(self, name, lo, hi, *, lo_open=False, allow_inf=False):
        object.__setattr__(self, name, _check(name, getattr(self, name), lo, hi,
                                              lo_open=lo_open, allow_inf=allow_inf))

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
        )

    def replace(self, **changes) -> "RigParameters":
        """Copy with some fields changed (validated)."""
        return replace(self, **changes)


# ---------------------------------------------------------------------------
# Presets
# ---------------------------------------------------------------------------
RIG = RigParameters()
RIG_SCALES = RIG.scales

#: Short SI names accepted by ``--set`` (the spec's symbols) -> RigParameters field.
SI_ALIASES = {
    "m1": "hammer_mass", "m2": "bit_mass", "K": "stiffness", "C": "damping",
    "mu_e": "mu_static", "mu_d": "mu_kinetic", "gamma": "friction_decay",
    "F_N": "normal_force", "Kc": "contact_stiffness", "lam": "contact_damping",
    "R": "gap", "B": "preload", "A": "amplitude", "f": "frequency",
}
GROUP_NAMES = tuple(f.name for f in fields(Groups))


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


def apply_settings(groups: Groups, settings: dict, *, scales: Scales = RIG_SCALES) -> Groups:
    """Apply ``{name: value}`` overrides given by group name or SI name.

    Group names (``a``, ``b``, ``eta`` ...) change the group directly.  SI names
    (``m1``, ``K``, ``preload``, ``frequency`` [Hz] ...) are applied to the
    SI parameters at ``scales`` and converted back, so e.g. ``K`` changes
    every group that depends on it.
    """
    g_changes = {}
    si_changes = {}
    valid_si = {f.name for f in fields(RigParameters)}
    for key, value in settings.items():
        if key in GROUP_NAMES:
            g_changes[key] = float(value)
        elif key in SI_ALIASES or key in valid_si:
            si_changes[SI_ALIASES.get(key, key)] = float(value)
        else:
            raise ParameterError(key, value, "a group name (" + ", ".join(GROUP_NAMES)
                                 + ") or an SI name (" + ", ".join(sorted(SI_ALIASES)) + ")")
    if si_changes:
        mu_e = si_changes.get("mu_static", 0.62)
        rig = groups.to_rig(scales, mu_static=mu_e).replace(**si_changes)
        groups = rig.to_groups()
    if g_changes:
        groups = groups.replace(**g_changes)
    return groups
