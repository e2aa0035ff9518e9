"""Finite-element assembly: tridiagonal stiffness, mass and damping of a string with its ends.

Each element of length ``h`` has stiffness ``EA/h [[1,-1],[-1,1]]`` and mass
``m' h`` times ``lumped = [[1/2, 0], [0, 1/2]]``,
``consistent = [[1/3, 1/6], [1/6, 1/3]]`` or
``mixed = (lumped + consistent)/2 = [[5/12, 1/12], [1/12, 5/12]]`` (default,
fourth order).  Viscous damping per unit length ``c'`` is distributed with the
mass pattern; boundary springs, dashpots and masses sit on the end nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .validation import DEFAULT_MASS, DrillStringError, G, check_mass
from .boundary import Boundary
from .drill_string import DrillString, resolve_ends
from .eigen import assembly_eigenpairs
from .mesh import Mesh

# --------------------------------------------------------------------------
# assembly
# --------------------------------------------------------------------------
def element_pattern(mass: str) -> tuple[float, float]:
    """(diagonal, off-diagonal) factors of the element mass ``m' h``."""
    check_mass(mass)
    return {"lumped": (0.5, 0.0), "consistent": (1.0 / 3.0, 1.0 / 6.0),
            "mixed": (5.0 / 12.0, 1.0 / 12.0)}[mass]


def _chain(diag_el: np.ndarray) -> np.ndarray:
    """Node diagonal from per-element end contributions (n_el,) -> (n_el+1,)."""
    out = np.zeros(diag_el.size + 1)
    out[:-1] += diag_el
    out[1:] += diag_el
    return out


@dataclass(frozen=True)
class Assembly:
    """Tridiagonal matrices of a string with its boundaries.

    Arrays named ``*_full`` run over all nodes; the retained degrees of
    freedom (DOFs) are nodes ``start .. stop-1`` (fixed ends removed).  The
    reduced tridiagonals ``(diagonal, off-diagonal)`` are returned by
    :meth:`tridiagonal`; dense matrices by :attr:`K`, :attr:`M`, :attr:`C`.
    Boundary springs, dashpots and masses are included at non-fixed ends.
    """

    string: DrillString
    top: Boundary
    bottom: Boundary
    mass: str
    mesh: Mesh
    kd_full: np.ndarray
    """Stiffness diagonal (n_nodes,) [N/m]."""
    ke_full: np.ndarray
    """Stiffness off-diagonal (n_nodes-1,) [N/m]."""
    md_full: np.ndarray
    """Mass diagonal (n_nodes,) [kg]."""
    me_full: np.ndarray
    """Mass off-diagonal (n_nodes-1,) [kg]."""
    cd_full: np.ndarray
    """Viscous damping diagonal (n_nodes,) [N s/m]."""
    ce_full: np.ndarray
    """Viscous damping off-diagonal (n_nodes-1,) [N s/m]."""
    start: int
    stop: int

    @property
    def n_nodes(self) -> int:
        return self.mesh.n_nodes

    @property
    def nodes(self) -> np.ndarray:
        """Node index of each DOF (n_dof,)."""
        return np.arange(self.start, self.stop)

    @property
    def n_dof(self) -> int:
        return self.stop - self.start

    @property
    def bottom_dof(self) -> int | None:
        """DOF index of the bit node (None when the bottom is fixed)."""
        return None if self.bottom.is_fixed else self.n_dof - 1

    @property
    def end_mass(self) -> float:
        """Lumped mass on the bit node [kg] (boundary mass, or the bit mass under a hammer)."""
        if self.bottom.is_fixed:
            return 0.0
        return self.string.bit_mass if self.bottom.kind == "hammer" else self.bottom.mass

    @property
    def element_pattern(self) -> tuple[float, float]:
        """(diagonal, off-diagonal) factors of the element mass ``m' h``."""
        return element_pattern(self.mass)

    @property
    def modal_damping_ratio(self) -> float:
        return self.string.modal_damping_ratio

    def tridiagonal(self, which: str) -> tuple[np.ndarray, np.ndarray]:
        """Reduced ``(diagonal (n_dof,), off-diagonal (n_dof-1,))`` of
        ``which`` in ``{"K", "M", "C"}`` (C = viscous + boundary dashpots)."""
        d, e = {"K": (self.kd_full, self.ke_full), "M": (self.md_full, self.me_full),
                "C": (self.cd_full, self.ce_full)}[which]
        return d[self.start:self.stop].copy(), e[self.start:self.stop - 1].copy()

    def dense(self, which: str) -> np.ndarray:
        """Dense reduced matrix (n_dof, n_dof)."""
        d, e = self.tridiagonal(which)
        return np.diag(d) + np.diag(e, 1) + np.diag(e, -1)

    def sparse(self, which: str):
        """``scipy.sparse`` CSC form of the reduced matrix."""
        import scipy.sparse as sp
        d, e = self.tridiagonal(which)
        return sp.diags([e, d, e], [-1, 0, 1], format="csc")

    @property
    def K(self) -> np.ndarray:
        """Stiffness (n_dof, n_dof) [N/m]."""
        return self.dense("K")

    @property
    def M(self) -> np.ndarray:
        """Mass (n_dof, n_dof) [kg]."""
        return self.dense("M")

    @property
    def C_viscous(self) -> np.ndarray:
        """Viscous + boundary-dashpot damping (n_dof, n_dof) [N s/m]."""
        return self.dense("C")

    @property
    def has_viscous(self) -> bool:
        d, e = self.tridiagonal("C")
        return bool(np.any(d != 0.0) or np.any(e != 0.0))

    def modal_damping_matrix(self) -> np.ndarray:
        """``M Phi diag(2 zeta omega) Phi^T M`` over all modes (n_dof, n_dof) [N s/m]."""
        zeta = self.modal_damping_ratio
        if zeta == 0.0:
            return np.zeros((self.n_dof, self.n_dof))
        lam, phi = assembly_eigenpairs(self, None, None, all_modes=True)
        mphi = self.M @ phi
        return (mphi * (2.0 * zeta * np.sqrt(lam))) @ mphi.T

    @property
    def C(self) -> np.ndarray:
        """Total damping: viscous + dashpots + modal (n_dof, n_dof) [N s/m]."""
        return self.C_viscous + self.modal_damping_matrix()

    def gravity_load(self) -> np.ndarray:
        """Nodal buoyed weight (n_nodes,) [N] incl. boundary masses
        (bit mass buoyed with the bottom section; top mass in air)."""
        ms = self.mesh
        f = _chain(ms.q * ms.h / 2.0)
        if not self.top.is_fixed:
            f[0] += self.top.mass * G
        if not self.bottom.is_fixed:
            bf = self.string.sections[-1].buoyancy_factor(self.string.mud_density)
            f[-1] += self.end_mass * G * bf
        return f


def assemble(string: DrillString, top: "Boundary | str | None" = None,
             bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS) -> Assembly:
    """Assemble K, M and viscous C of ``string`` with the given ends.

    Parameters
    ----------
    string : DrillString
    top, bottom : Boundary or str, optional
        End conditions (default ``string.top`` / ``string.bottom``).  A
        ``hammer`` bottom is free here.
    mass : {"mixed", "lumped", "consistent"}
        Mass-matrix scheme.

    Returns
    -------
    Assembly
    """
    top, bottom = resolve_ends(string, top, bottom)
    ms = string.mesh()
    a, b = element_pattern(mass)
    kel = ms.ea / ms.h
    mel = ms.m * ms.h
    cel = ms.cv * ms.h
    kd, ke = _chain(kel), -kel
    md, me = _chain(a * mel), b * mel
    cd, ce = _chain(a * cel), b * cel
    for bnd, i in ((top, 0), (bottom, -1)):
        if not bnd.is_fixed:
            kd[i] += bnd.ground_stiffness
            cd[i] += bnd.ground_damping
            md[i] += bnd.mass
    if bottom.kind == "hammer":
        md[-1] += string.bit_mass  # the bit mass stays on the string's bit node
    start = 1 if top.is_fixed else 0
    stop = ms.n_nodes - 1 if bottom.is_fixed else ms.n_nodes
    if stop - start < 1:
        raise DrillStringError(f"string '{string.name}'", "elements", string.n_elements,
                               "fixed-fixed needs at least 2 elements")
    return Assembly(string, top, bottom, mass, ms, kd, ke, md, me, cd, ce, start, stop)


