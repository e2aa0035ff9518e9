"""The scales of the nondimensional form: hammer mass, spring stiffness and static friction force."""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Scales", "DEFAULT_SCALES"]


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
