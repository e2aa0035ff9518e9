"""The mesh of the drillstring: elements sized by equal travel time, and the dispersion error of a mesh.

Elements are sized by **equal travel time** ``h/c`` across sections: every
element of the string takes about the same time ``tau`` for an axial wave
to cross it, so neighbouring elements see the same ``k h = omega tau`` and
the mixed mass keeps its fourth-order accuracy through section junctions.
``tau`` comes from the string's ``max_element_length`` (the longest element
of the fastest section, default 10 m) or, in :func:`~hammerbit.drillstring.modes`
and the check, from a target accuracy (see :meth:`DrillString.for_accuracy`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .validation import DEFAULT_MASS, check_mass

__all__ = ["Mesh", "theta_max", "dispersion_error"]


@dataclass(frozen=True)
class Mesh:
    """Element arrays of a discretised string (all SI, shapes noted)."""

    z: np.ndarray
    """Node depths (n_nodes,) [m], 0 at the top node."""
    h: np.ndarray
    """Element lengths (n_el,) [m]."""
    section_index: np.ndarray
    """Index of the section of each element (n_el,)."""
    ea: np.ndarray
    """Axial rigidity per element (n_el,) [N]."""
    m: np.ndarray
    """Linear mass per element (n_el,) [kg/m]."""
    cv: np.ndarray
    """Viscous damping per unit length per element (n_el,) [N s/m^2]."""
    q: np.ndarray
    """Buoyed weight per unit length per element (n_el,) [N/m]."""

    @property
    def n_nodes(self) -> int:
        return int(self.z.size)

    @property
    def n_elements(self) -> int:
        return int(self.h.size)


def theta_max(rel_tol: float, mass: str) -> float:
    check_mass(mass)
    if mass == "mixed":
        return (480.0 * rel_tol) ** 0.25
    return math.sqrt(24.0 * rel_tol)


def dispersion_error(kh: "float | np.ndarray", mass: str = DEFAULT_MASS) -> "float | np.ndarray":
    """Exact relative frequency error ``f_h/f - 1`` of an infinite uniform
    chain for a wave with ``kh`` radians per element.

    ``lumped``: ``2 sin(kh/2)/kh - 1``; ``consistent``:
    ``sqrt(6(1-cos kh)/(2+cos kh))/kh - 1``; ``mixed``:
    ``sqrt(12(1-cos kh)/(5+cos kh))/kh - 1``.
    """
    check_mass(mass)
    x = np.asarray(kh, dtype=float)
    if mass == "lumped":
        r = 2.0 * np.sin(x / 2.0) / x
    elif mass == "consistent":
        r = np.sqrt(6.0 * (1.0 - np.cos(x)) / (2.0 + np.cos(x))) / x
    else:
        r = np.sqrt(12.0 * (1.0 - np.cos(x)) / (5.0 + np.cos(x))) / x
    return r - 1.0
