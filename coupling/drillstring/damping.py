"""Damping of the frequency response and the bit receptance.

Damping model
    The file's ``modal_damping_ratio`` zeta is read as a **hysteretic loss
    factor** ``eta = 2 zeta`` of the steel: the modulus is ``E (1 + i eta)``
    in every element (and in the continuous string).  Each mode then has the
    damping ratio ``eta/2 = zeta`` at resonance, as in the file, but the
    damping is a property of the material per unit length, not of the mesh's
    modes: the receptance converges under mesh refinement.  A damping ratio
    attached to every discrete mode does not, because the number of modes
    grows with the mesh (at a fixed bit the receptance then grows like log N).
    Viscous damping per unit length ``c'`` (``viscous_damping`` of a section)
    and the boundary dashpots add to it.  A damping ``scale`` multiplies
    ``eta`` and ``c'`` (the check's damping range), never the boundary
    dashpots, which are separate inputs.

Bit receptance
    ``D(omega)`` is the dynamic stiffness of the string at the bit with the
    bit held and the top boundary in place; a bottom boundary of dynamic
    stiffness ``Z_bc = k + i omega c - omega^2 m`` gives the receptance
    ``H = 1/(D + Z_bc)``.  Two evaluations:

    * :func:`exact_dynamic_stiffness` -- the continuous string, section
      transfer matrices on ``[u, EA u']`` with the complex wave number
      ``k = omega sqrt(m*/EA*)``, ``EA* = EA (1 + i eta)``, ``m* = m' - i c'/omega``;
    * :func:`bit_dynamic_stiffness` -- the finite elements, ``LDL^T`` pivots
      of the tridiagonal dynamic stiffness, each element divided by its
      impedance factor ``rho`` (:mod:`.modes`), so the discrete string carries
      the exact impedance and converges at fourth order (mixed mass).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .assembly import element_pattern
from .validation import DEFAULT_MASS, check_number
from .boundary import Boundary
from .drill_string import DrillString, resolve_ends

__all__ = ["DampingModel", "boundary_impedance", "exact_dynamic_stiffness", "bit_dynamic_stiffness",
           "bit_receptance", "exact_receptance", "reference_impedance"]


@dataclass(frozen=True)
class DampingModel:
    """Damping of the string in the frequency domain."""

    loss_factor: float = 0.0
    """Hysteretic loss factor eta [-] of the modulus, ``E (1 + i eta)``."""
    viscous_scale: float = 1.0
    """Factor on each section's viscous damping per unit length c' [-]."""

    def __post_init__(self) -> None:
        check_number("damping", "loss_factor", self.loss_factor, 0.0, 2.0)
        check_number("damping", "viscous_scale", self.viscous_scale, 0.0, 1e6)

    @classmethod
    def of(cls, string: DrillString, scale: float = 1.0) -> "DampingModel":
        """The string's own damping times ``scale``: ``eta = 2 zeta scale``, c' x scale."""
        return cls(min(2.0, 2.0 * string.modal_damping_ratio * float(scale)), float(scale))

    def to_dict(self) -> dict:
        return {"loss_factor": self.loss_factor, "viscous_scale": self.viscous_scale}


def _omega(freqs_hz: Any) -> np.ndarray:
    return 2.0 * math.pi * np.atleast_1d(np.asarray(freqs_hz, dtype=float))


def boundary_impedance(b: Boundary, w: np.ndarray, mass: float | None = None) -> np.ndarray:
    """Dynamic stiffness of a boundary ``k + i w c - w^2 m`` [N/m] (F,) complex."""
    m = b.mass if mass is None else mass
    return b.ground_stiffness + 1j * w * b.ground_damping - w * w * m


def _section_waves(string: DrillString, w: np.ndarray, damping: DampingModel):
    """Per section: ``(EA*, k*)`` arrays (F,) complex of the damped continuous string."""
    out = []
    for s in string.sections:
        ea = s.axial_stiffness * (1.0 + 1j * damping.loss_factor)
        # omega^2 m* = omega^2 m' - i omega c'
        w2m = w * w * s.mass_per_length - 1j * w * s.viscous_damping * damping.viscous_scale
        out.append((ea, np.sqrt(w2m / ea)))
    return out


def reference_impedance(string: DrillString, freqs_hz: Any, damping: DampingModel | None = None) -> np.ndarray:
    """``i omega Z*`` [N/m] (F,): dynamic stiffness of the bottom section
    continued to infinity (no reflections), ``Z* = EA* k*/omega``."""
    w = _omega(freqs_hz)
    damping = DampingModel.of(string) if damping is None else damping
    ea, k = _section_waves(string.replace(sections=string.sections[-1:]), w, damping)[0]
    return 1j * ea * k


def exact_dynamic_stiffness(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                            damping: DampingModel | None = None) -> np.ndarray:
    """Dynamic stiffness at the bit of the continuous string, bit held [N/m] (F,) complex.

    Transfer matrices ``[[cos kl, sin kl/(EA k)], [-EA k sin kl, cos kl]]`` on
    ``[u, N = EA u']`` from the top (fixed: ``[0, 1]``; otherwise ``[1, Z_top]``)
    to the bit, ``D = N/u``.  ``damping`` defaults to the string's own.
    """
    w = _omega(freqs_hz)
    t, _ = resolve_ends(string, top, "free")
    damping = DampingModel.of(string) if damping is None else damping
    if t.is_fixed:
        u, n = np.zeros(w.size, complex), np.ones(w.size, complex)
    else:
        u, n = np.ones(w.size, complex), boundary_impedance(t, w).astype(complex)
    for s, (ea, k) in zip(string.sections, _section_waves(string, w, damping)):
        kl = k * s.length
        c, sn = np.cos(kl), np.sin(kl)
        eak = ea * k
        with np.errstate(divide="ignore", invalid="ignore"):
            s_over = np.where(np.abs(kl) > 1e-12, sn / np.where(eak == 0, 1.0, eak), s.length / ea)
        u, n = c * u + s_over * n, -eak * sn * u + c * n
    with np.errstate(divide="ignore", invalid="ignore"):
        return n / u


def exact_receptance(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                     bottom: "Boundary | str | None" = None, damping: DampingModel | None = None) -> np.ndarray:
    """``H = 1/(D + Z_bc)`` [m/N] of the continuous string (bit mass applied; fixed bit: 0)."""
    _, b = resolve_ends(string, top, bottom)
    w = _omega(freqs_hz)
    if b.is_fixed:
        return np.zeros(w.size, complex)
    m = string.bit_mass if b.kind == "hammer" else b.mass
    with np.errstate(divide="ignore", invalid="ignore"):
        return 1.0 / (exact_dynamic_stiffness(string, freqs_hz, top, damping) + boundary_impedance(b, w, m))


def bit_dynamic_stiffness(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None, *,
                          mass: str = DEFAULT_MASS, damping: DampingModel | None = None,
                          correct: bool = True) -> np.ndarray:
    """Dynamic stiffness at the bit of the finite-element string, bit held [N/m] (F,) complex.

    ``LDL^T`` pivots of the tridiagonal dynamic stiffness from the top node to
    the bit (O(n) per frequency, vectorised over frequencies); the last pivot
    is ``D``.  ``correct`` divides each element by its impedance factor.
    """
    w = _omega(freqs_hz)
    t, _ = resolve_ends(string, top, "free")
    damping = DampingModel.of(string) if damping is None else damping
    a, b = element_pattern(mass)
    ms = string.mesh()
    kel = ms.ea / ms.h * (1.0 + 1j * damping.loss_factor)                       # (n_el,)
    w2m = (w[:, None] ** 2) * (ms.m * ms.h) - 1j * w[:, None] * (ms.cv * ms.h * damping.viscous_scale)
    if correct:
        theta2 = w2m / kel
        s = 1.0 / np.sqrt(1.0 + 0.5 * (b - a) * theta2)                          # (F, n_el)
    else:
        s = np.ones_like(w2m)
    dd = s * (kel - a * w2m)        # element end diagonal
    off = s * (-kel - b * w2m)      # element off-diagonal
    n_el = ms.n_elements
    tiny = 1e-300
    if t.is_fixed:
        piv = dd[:, 0] + (dd[:, 1] if n_el > 1 else 0.0)
        first = 1
        if n_el == 1:
            return dd[:, 0].copy()
    else:
        piv = dd[:, 0] + boundary_impedance(t, w)
        first = 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for i in range(first + 1, n_el + 1):       # node i couples to node i-1 through element i-1
            diag = dd[:, i - 1] + (dd[:, i] if i < n_el else 0.0)
            p = np.where(piv == 0, tiny, piv)
            piv = diag - off[:, i - 1] ** 2 / p
    return piv


def bit_receptance(string: DrillString, freqs_hz: Any, top: "Boundary | str | None" = None,
                   bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS,
                   damping: DampingModel | None = None, correct: bool = True) -> np.ndarray:
    """Damped driving-point receptance at the bit ``x_bit/F_bit`` [m/N] (F,) complex.

    Finite elements with the damping model of this module (default: the
    string's own); the bottom spring/dashpot/mass act at the bit (the bit
    mass applies, ``hammer`` counts as free).  A fixed bit gives zeros.
    """
    _, bot = resolve_ends(string, top, bottom)
    w = _omega(freqs_hz)
    if bot.is_fixed:
        return np.zeros(w.size, dtype=complex)
    m = string.bit_mass if bot.kind == "hammer" else bot.mass
    d = bit_dynamic_stiffness(string, freqs_hz, top, mass=mass, damping=damping, correct=correct)
    with np.errstate(divide="ignore", invalid="ignore"):
        return 1.0 / (d + boundary_impedance(bot, w, m))
