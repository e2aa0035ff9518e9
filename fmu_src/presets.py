"""The named presets of the model: the paper's rig and its operating points (Figs. 9, 12, chaos)."""
from __future__ import annotations

import math

from .params import Groups, RigParameters
from .validation import ParameterError

__all__ = ["RIG", "RIG_SCALES", "PRESETS", "preset"]

RIG = RigParameters()
RIG_SCALES = RIG.scales   # == DEFAULT_SCALES


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
