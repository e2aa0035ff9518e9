"""The regime flags of a scene: where the model's answer is not drilling (bounce, overload, runaway)."""
from __future__ import annotations

from dataclasses import dataclass

from .params import Groups

__all__ = ["Regime", "regime"]


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
