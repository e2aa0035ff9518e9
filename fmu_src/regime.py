"""The paper's static domain of a scene: the rules a < b, a + b <= 1 and b <= mu it breaks.

These rules are where the paper worked, not whether a scene's answer is a
drilling point: a scene outside them may drill, and the scene's own run says
whether it runs away or bounces (the studies' scene flags, computed from the
solver's trackers ``F_DRIVE_MIN`` and ``F_T_STICK`` and the Poincaré samples).
"""
from __future__ import annotations

from dataclasses import dataclass

from .params import Groups

__all__ = ["Regime", "regime"]


@dataclass(frozen=True)
class Regime:
    """Which of the paper's static rules a scene breaks.

    Attributes
    ----------
    bounce : bool
        ``a >= b``: the harmonic amplitude reaches the preload.  The drive on
        the bit may then fall below zero, and below ``-F_s`` only in some scenes.
    overload : bool
        ``a + b > 1``: preload plus amplitude exceed the static threshold
        ``F0 = mu_e F_N``, outside the paper's domain ``a + b <= 1``.
    runaway : bool
        ``b > f_floor`` where ``f_floor`` is the kinetic friction the bit
        feels at high speed: ``mu`` when ``gamma_hat > 0``, else 1.  Necessary
        for a runaway drift (friction below the preload at high speed), not
        sufficient: the slip must also reach the speed where the friction falls
        below the preload and keep sliding.
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
    """The paper's static rules a scene breaks (pure function of its groups)."""
    floor = groups.mu if groups.gamma_hat > 0.0 else 1.0
    return Regime(bounce=groups.a >= groups.b, overload=groups.a + groups.b > 1.0,
                  runaway=groups.b > floor)
