"""Stability of the auto-driller's closed loop: its eigenvalues before a run, and gains that work.

The auto-driller (:mod:`.top`) closes a PI loop on the hook load around the
string.  With the hammer held (the interface's far end fixed) the string side
and the controller are one linear time-invariant system ``X' = A X``; the loop
is stable when every eigenvalue of ``A`` lies left of ``-margin``, with
``margin`` = :data:`MARGIN_FRACTION` times the loop's own rate (its natural
frequency ``sqrt(k_s k_i)``, or ``k_s k_p`` without the integral).  The PI
controller acts on the tension rate through the block's acceleration, so a
large gain can feed a string mode energy faster than its damping removes it: a
stiff lab rig at 539 Hz, a long string on a derrick spring under a heavy block
at a few hertz.

Gains that work are found by scaling the loop down, ``k_p -> s k_p``,
``k_i -> s^2 k_i`` (the natural frequency times ``s``, the damping ratio kept),
halving ``s`` until the loop is stable.  Unstable default gains are retuned so;
unstable gains the user gave are refused (:class:`ControllerUnstableError`)
with the retuned ones as the suggestion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .validation import DrillStringError

__all__ = ["MARGIN_FRACTION", "MAX_HALVINGS", "ControllerUnstableError", "LoopCheck", "loop_eigenvalues",
           "loop_margin", "check_loop", "stable_gains", "sliding_loop", "sliding_check"]

#: The loop is stable when its largest real part is below -MARGIN_FRACTION times the loop's rate.
MARGIN_FRACTION = 1e-3
#: Halvings of the loop's scale tried before giving up (2^-40 ~ 1e-12).
MAX_HALVINGS = 40


class ControllerUnstableError(DrillStringError):
    """Auto-driller gains that make the closed loop (string and controller, hammer held) unstable.

    Attributes
    ----------
    eigenvalue : complex
        The eigenvalue with the largest real part [1/s].
    working : tuple
        ``(k_p, k_i)`` that make the loop stable (the given ones scaled down), or None.
    """

    def __init__(self, kp: float, ki: float, eigenvalue: complex, working):
        self.eigenvalue = eigenvalue
        self.working = working
        lam = eigenvalue
        hint = (f"; gains that work: --top auto-driller:kp={working[0]:.4g},ki={working[1]:.4g}"
                if working is not None else "; no scaled-down gains are stable")
        super().__init__("--top auto-driller", "kp, ki", (kp, ki),
                         f"the closed loop (string and controller, hammer held) is unstable: eigenvalue "
                         f"{lam.real:+.4g} {'+' if lam.imag >= 0 else '-'} {abs(lam.imag):.4g}i 1/s "
                         f"(Re > 0, at {abs(lam.imag) / (2 * math.pi):.4g} Hz){hint}")


@dataclass(frozen=True)
class LoopCheck:
    """The eigenvalue check of one pair of gains.

    Attributes
    ----------
    proportional_gain, integral_gain : float
        k_p [m/s per N], k_i [m/s per N s].
    eigenvalue : complex
        The eigenvalue with the largest real part [1/s].
    margin : float
        The real part it must stay below, negated [1/s].
    """

    proportional_gain: float
    integral_gain: float
    eigenvalue: complex
    margin: float

    @property
    def stable(self) -> bool:
        return bool(self.eigenvalue.real < -self.margin)


def loop_eigenvalues(A: np.ndarray) -> np.ndarray:
    """Eigenvalues of the closed-loop matrix ``A`` [1/s], read-only (remembered: every run and
    study of a string under the auto-driller checks the same loop, a dense eigenproblem of the
    whole string)."""
    from hammerbit.memo import digest, memo
    A = np.ascontiguousarray(A, dtype=float)
    return memo(digest("loop eigenvalues", A), lambda: _eigenvalues(A))


def _eigenvalues(A: np.ndarray) -> np.ndarray:
    """``np.linalg.eigvals`` on one BLAS thread: a small eigenproblem runs many times slower on
    threads that share two busy cores."""
    from hammerbit.model.string_step import one_blas_thread
    with one_blas_thread():
        return np.linalg.eigvals(A)


def loop_margin(series_stiffness: float, kp: float, ki: float) -> float:
    """:data:`MARGIN_FRACTION` of the loop's rate [1/s]: ``sqrt(k_s k_i)``, else ``k_s k_p``."""
    rate = math.sqrt(series_stiffness * ki) if ki > 0.0 else series_stiffness * kp
    return MARGIN_FRACTION * rate


def check_loop(build: Callable[[float, float], np.ndarray], series_stiffness: float, kp: float,
               ki: float) -> LoopCheck:
    """The check of gains ``(kp, ki)``; ``build(kp, ki)`` gives the closed-loop matrix.  Without an
    integral gain the controller's integral state is not fed back (an eigenvalue 0 that nothing
    excites) and is left out."""
    A = build(kp, ki)
    if ki == 0.0:
        A = A[:-1, :-1]
    lam = loop_eigenvalues(A)
    i = int(np.argmax(lam.real))
    return LoopCheck(float(kp), float(ki), complex(lam[i]), loop_margin(series_stiffness, kp, ki))


def stable_gains(build: Callable[[float, float], np.ndarray], series_stiffness: float, kp: float,
                 ki: float) -> tuple:
    """``(first, stable)``: the check of ``(kp, ki)`` and that of the first stable gains of the
    scaled loop ``(s kp, s^2 ki)``, ``s = 1, 1/2, 1/4, ...`` (None if none within
    :data:`MAX_HALVINGS`).  Gains both zero do not move the block: nothing to check."""
    first = check_loop(build, series_stiffness, kp, ki)
    if first.stable or (kp == 0.0 and ki == 0.0):
        return first, first
    s = 1.0
    for _ in range(MAX_HALVINGS):
        s *= 0.5
        chk = check_loop(build, series_stiffness, s * kp, s * s * ki)
        if chk.stable:
            return first, chk
    return first, None


def sliding_loop(matrices, *, interface_stiffness: float, interface_damping: float, hammer_mass: float,
                 bit_mass: float, stiffness: float, damping: float) -> np.ndarray:
    """The closed-loop matrix of the string side with the hammer and the bit free, as while the
    bit slides (kinetic friction constant): states ``X``, then the hammer's and the bit's
    position and velocity (deviations).  ``matrices`` is a
    :class:`~hammerbit.drillstring.top.SideMatrices`; the interface (``k_i``, ``c_i``) joins
    the string's bottom to the hammer, the hammer spring (``stiffness``, ``damping``) the
    hammer to the bit."""
    A, E, fr = matrices.A1, matrices.E, matrices.frow
    ki, ci, K, C = interface_stiffness, interface_damping, stiffness, damping
    N = A.shape[0]
    Z = np.zeros((N + 4, N + 4))
    ih, jh, ib, jb = N, N + 1, N + 2, N + 3
    Z[:N, :N] = A
    Z[:N, ih] = E[:, 0]
    Z[:N, jh] = E[:, 1]
    Z[ih, jh] = 1.0
    Z[jh, :N] = fr / hammer_mass
    Z[jh, ih] = (-ki - K) / hammer_mass
    Z[jh, jh] = (-ci - C) / hammer_mass
    Z[jh, ib] = K / hammer_mass
    Z[jh, jb] = C / hammer_mass
    Z[ib, jb] = 1.0
    Z[jb, ih] = K / bit_mass
    Z[jb, jh] = C / bit_mass
    Z[jb, ib] = -K / bit_mass
    Z[jb, jb] = -C / bit_mass
    return Z


def sliding_check(matrices, **masses_and_springs) -> LoopCheck:
    """The check of the loop while the bit slides (:func:`sliding_loop`; its keywords).  The
    rigid translation of string, hammer and bit under the block (a double eigenvalue 0, split
    by rounding) is left out: eigenvalues below the margin in modulus."""
    g = matrices.gains
    kp, ki = g.proportional_gain, g.integral_gain
    margin = loop_margin(g.series_stiffness, kp, ki)
    lam = loop_eigenvalues(sliding_loop(matrices, **masses_and_springs))
    lam = lam[np.abs(lam) >= margin]
    i = int(np.argmax(lam.real))
    return LoopCheck(float(kp), float(ki), complex(lam[i]), margin)
