"""The linear modes of the coupled string–hammer system with the bit stuck (frequency checks, sweeps)."""
from __future__ import annotations

import math

import numpy as np

from hammerbit.cosim.config import CosimConfig
from hammerbit.cosim.string_side import StringSide

__all__ = ["coupled_system", "coupled_modes"]


def coupled_system(string, config: CosimConfig):
    """State matrix of string + interface + hammer with the bit stuck (linear).

    Returns ``(A, n, m1, K, C)``: A of shape (n + 2, n + 2), the last two states
    the hammer's deviation and velocity; n the string-side states.
    """
    side = StringSide(string, config)
    rig = config.rig
    n = side.n
    m1, K, C = rig.hammer_mass, rig.stiffness, rig.damping
    A = np.zeros((n + 2, n + 2))
    A[:n, :n] = side.A1
    A[:n, n:n + 2] = side.E
    A[n, n + 1] = 1.0
    A[n + 1, :n] = side.frow / m1
    A[n + 1, n] = -(side.ki + K) / m1
    A[n + 1, n + 1] = -(side.ci + C) / m1
    return A, n, m1, K, C


def coupled_modes(string, config: CosimConfig = CosimConfig(), *, f_max: float = 100.0) -> np.ndarray:
    """Natural frequencies [Hz] of the coupled linear system with the bit on bottom.

    The modal check of this configuration: the string (hook at the top) with the
    hammer as its bottom boundary -- interface ``(k_i, c_i)``, hammer mass ``m1``,
    hammer spring ``(K, C)`` -- and the bit held by the rock (stuck).  Damped
    natural frequencies ``|Im lambda| / 2 pi`` of the state matrix, sorted, up
    to ``f_max``.
    """
    A, n, m1, K, C = coupled_system(string, config)
    lam = np.linalg.eigvals(A)
    f = np.abs(lam.imag[lam.imag > 0]) / (2 * math.pi)
    f = np.sort(f)
    return f[f <= f_max]
