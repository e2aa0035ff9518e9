"""The harmonic force computed by the co-simulation master and held over each macro step."""
from __future__ import annotations

import math
from typing import Optional

from hammerbit.model.params import RigParameters

from hammerbit.cosim.config import CosimConfig

__all__ = ["MasterHarmonic"]


class MasterHarmonic:
    """The harmonic force r(t) A sin(2 pi f t + phi) computed by the master and held
    over each macro step at its mean (the exact impulse of the step; the ramp
    factor r at the step's midpoint)."""

    def __init__(self, rig: RigParameters, config: Optional[CosimConfig] = None):
        self.A = rig.amplitude
        self.w = 2.0 * math.pi * rig.frequency
        self.phi = rig.phase
        self.config = config

    def mean(self, t: float, H: float) -> float:
        w, phi = self.w, self.phi
        r = 1.0 if self.config is None else self.config.ramp_factor(t + 0.5 * H)
        return r * self.A * (math.cos(w * t + phi) - math.cos(w * (t + H) + phi)) / (w * H)
