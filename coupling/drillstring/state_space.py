"""State-space export of the string for the co-simulation master.

The string's own damping here is the modal damping ratio of the file on every
mode (``C = M Phi diag(2 zeta omega) Phi^T M``) plus viscous damping per unit
length and the boundary dashpots; the bit mass of the file sits on the bit
node, under the hammer interface too (:meth:`DrillString.resolve_bottom`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .assembly import assemble
from .validation import DEFAULT_MASS, G
from .boundary import Boundary
from .drill_string import DrillString
from .eigen import assembly_eigenpairs
from .statics import static_compliance

__all__ = ["StateSpace", "state_space"]


@dataclass(frozen=True)
class StateSpace:
    """Linear first-order model of the string for co-simulation.

    ``dx/dt = A x + B u + d``,  ``y = C x + D u + y_offset`` with the scalar input
    ``u`` = axial force applied to the bottom (bit) node [N], **positive
    downward**; the rock or hammer pushing up on the string is negative.

    Nodal form: ``x = [u_1..u_n, v_1..v_n]`` (displacements [m] and
    velocities [m/s] of the DOFs, downward, from the unstrained string).
    Modal form (``f_max`` given): ``x = [q, dq/dt]`` are *deviations from the
    static equilibrium* of the full model, DOF displacements
    ``static_displacement[nodes] + basis @ q`` (``x0 = 0``; ``y_offset``
    holds the equilibrium outputs), so the truncation is exact at rest.
    Outputs ``y`` (see ``output_names``): bit displacement [m], bit velocity
    [m/s], effective tension in the top element [N], all absolute.

    ``x0`` is the static equilibrium with ``u = u0 = -wob`` (it satisfies
    ``A x0 + B u0 + d = 0``).  A bottom ``spring`` is unloaded at ``x0``
    (its preload is folded into ``d``), so the WOB always enters via ``u``.
    For ``bottom = hammer`` the interface force is
    ``u = k_i (x_h - y[0]) + c_i (v_h - y[1])`` with ``k_i, c_i`` from
    :attr:`interface`.
    """

    A: np.ndarray
    """State matrix (n_x, n_x)."""
    B: np.ndarray
    """Input matrix (n_x, 1) [per N]."""
    C: np.ndarray
    """Output matrix (3, n_x)."""
    D: np.ndarray
    """Feed-through (3, 1), zero."""
    d: np.ndarray
    """Constant term from gravity and bottom-spring preload (n_x,)."""
    x0: np.ndarray | None
    """Static equilibrium state (n_x,); None with a free top (no hook, no equilibrium)."""
    u0: float
    """Input at equilibrium, ``-wob`` [N]."""
    mass_matrix: np.ndarray
    """Second-order mass in the state coordinates (n_q, n_q) [kg] (identity if modal)."""
    stiffness_matrix: np.ndarray
    """Second-order stiffness (n_q, n_q) [N/m] (``diag(omega^2)`` if modal)."""
    damping_matrix: np.ndarray
    """Second-order damping (n_q, n_q) [N s/m] (``Phi^T C Phi`` if modal)."""
    load_vector: np.ndarray
    """Constant generalized force (n_q,) [N]: gravity + spring preload
    (nodal); ``basis^T b * wob`` (modal, balances ``u0``)."""
    input_vector: np.ndarray
    """Generalized force per unit input (n_q,) [-]."""
    basis: np.ndarray | None
    """Mode shapes on the DOFs (n_dof, n_modes) for the modal form, else None."""
    nodes: np.ndarray
    """Node index of each DOF (n_dof,)."""
    z: np.ndarray
    """Node depths (n_nodes,) [m]."""
    bottom_node: int
    """Node index of the bit (n_nodes - 1)."""
    bottom_dof: int
    """DOF index of the bit node."""
    top: Boundary
    bottom: Boundary
    wob: float
    """Weight on bit at equilibrium [N]."""
    hook_load: float
    """Hook load at equilibrium [N]."""
    static_displacement: np.ndarray
    """Equilibrium displacement of all nodes (n_nodes,) [m] (full model)."""
    residual_compliance: float
    """Static bit compliance missing from a modal truncation [m/N] (0 nodal)."""
    max_frequency_hz: float
    """Highest natural frequency represented [Hz] (step-size guide)."""
    y_offset: np.ndarray
    """Constant output offset (3,): zero for the nodal form; the equilibrium
    outputs for the modal form (whose states are deviations)."""
    output_names: tuple[str, ...] = ("bit_displacement", "bit_velocity", "top_element_tension")

    @property
    def interface(self) -> Boundary:
        """Bottom boundary; for ``hammer`` it carries the interface k [N/m], c [N s/m]."""
        return self.bottom

    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    def rhs(self, x: np.ndarray, u: float) -> np.ndarray:
        """``dx/dt`` (n_x,) for state ``x`` and bottom force ``u`` [N]."""
        return self.A @ x + self.B[:, 0] * u + self.d

    def output(self, x: np.ndarray, u: float = 0.0) -> np.ndarray:
        """Outputs (3,): bit displacement [m], bit velocity [m/s], top tension [N]."""
        return self.C @ x + self.D[:, 0] * u + self.y_offset


def state_space(string: DrillString, top: "Boundary | str | None" = None,
                bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS,
                wob: float | None = None, hook_load: float | None = None,
                mud_density: float | None = None, f_max: float | None = None) -> StateSpace:
    """First-order linear model with a force input at the bit.

    Parameters
    ----------
    string : DrillString
    top : Boundary or str, optional
        Hook (default ``string.top``).
    bottom : Boundary or str, optional
        Default ``string.bottom``.  ``hammer:K:C`` for the co-simulation
        (bottom node free, interface data kept in
        :attr:`StateSpace.interface`), ``free`` or ``spring``.  ``fixed`` is
        refused (there would be no bit DOF to drive).
    mass : {"mixed", "lumped", "consistent"}
        Lumped mass gives a diagonal M and the lowest top frequency.
    wob, hook_load : float, optional
        Weight on bit or hook load [N] of the equilibrium (default wob = 0).
    mud_density : float, optional
        Override ``string.mud_density`` [kg/m^3].
    f_max : float, optional
        Modal truncation: keep the modes <= f_max [Hz].

    Returns
    -------
    StateSpace
    """
    import scipy.linalg as sla  # noqa: PLC0415 -- imported where needed (a slow import)
    if mud_density is not None:
        string = string.replace(mud_density=mud_density)
    asm = assemble(string, top, bottom, mass=mass)
    if asm.bottom.is_fixed:
        raise ValueError("state_space needs a moving bit: bottom must be hammer, free or spring")
    n = asm.n_dof
    b_dof = n - 1
    K, M = asm.K, asm.M
    Cv = asm.C_viscous
    lam_all = None
    if asm.modal_damping_ratio > 0.0:
        lam_all, phi_all = assembly_eigenpairs(asm, None, None, all_modes=True)
        mphi = M @ phi_all
        Cfull = Cv + (mphi * (2.0 * asm.modal_damping_ratio * np.sqrt(lam_all))) @ mphi.T
    else:
        Cfull = Cv
    fg_full = asm.gravity_load()
    fg = fg_full[asm.start:asm.stop].copy()
    bvec = np.zeros(n)
    bvec[b_dof] = 1.0
    # equilibrium: bottom spring unloaded, WOB through the input
    rigid = asm.top.kind == "free"
    weight = float(fg_full.sum() - (asm.top.mass * G if not asm.top.is_fixed else 0.0))
    if wob is not None and hook_load is not None:
        raise ValueError("give wob or hook_load, not both")
    wob_v = weight - float(hook_load) if hook_load is not None else float(wob or 0.0)
    if not -1e-9 * weight <= wob_v <= weight * (1 + 1e-12):
        raise ValueError(f"wob = {wob_v:.6g} N: allowed range 0 <= wob <= buoyed weight {weight:.6g} N")
    x_eq_full = np.zeros(asm.n_nodes)
    load = fg.copy()
    if not rigid:
        Kstat = K.copy()
        Kstat[b_dof, b_dof] -= asm.bottom.ground_stiffness
        x_eq = np.linalg.solve(Kstat, fg - wob_v * bvec)
        x_eq_full[asm.start:asm.stop] = x_eq
        load[b_dof] += asm.bottom.ground_stiffness * x_eq[b_dof]
    # top-element tension row on the DOFs
    trow = np.zeros(n)
    k0 = asm.mesh.ea[0] / asm.mesh.h[0]
    trow[1 - asm.start] += k0
    if asm.start == 0:
        trow[0] -= k0
    if f_max is None:
        L = sla.cho_factor(M)
        Minv_K = sla.cho_solve(L, K)
        Minv_C = sla.cho_solve(L, Cfull)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv_K, -Minv_C]])
        B = np.concatenate((np.zeros(n), sla.cho_solve(L, bvec)))[:, None]
        d = np.concatenate((np.zeros(n), sla.cho_solve(L, load)))
        C = np.zeros((3, 2 * n))
        C[0, b_dof] = 1.0
        C[1, n + b_dof] = 1.0
        C[2, :n] = trow
        x0 = None if rigid else np.concatenate((x_eq, np.zeros(n)))
        lam_top = lam_all[-1] if lam_all is not None else sla.eigh(K, M, eigvals_only=True,
                                                                     subset_by_index=(n - 1, n - 1))[0]
        return StateSpace(A, B, C, np.zeros((3, 1)), d, x0, -wob_v, M, K, Cfull, load, bvec, None,
                          asm.nodes, asm.mesh.z, asm.n_nodes - 1, b_dof, asm.top, asm.bottom, wob_v,
                          weight - wob_v, x_eq_full, 0.0, math.sqrt(lam_top) / (2 * math.pi), np.zeros(3))
    lam, phi = assembly_eigenpairs(asm, f_max, None)
    m = lam.size
    if m == 0:
        raise ValueError(f"no mode below f_max = {f_max} Hz")
    # modal coordinates measure the deviation from the full-model equilibrium:
    # x = x_eq + Phi q, so the truncated model is exact at rest.
    Cm = phi.T @ Cv @ phi + np.diag(2.0 * asm.modal_damping_ratio * np.sqrt(lam))
    A = np.block([[np.zeros((m, m)), np.eye(m)], [-np.diag(lam), -Cm]])
    gen_b = phi.T @ bvec
    gen_load = gen_b * wob_v
    B = np.concatenate((np.zeros(m), gen_b))[:, None]
    d = np.concatenate((np.zeros(m), gen_load))
    C = np.zeros((3, 2 * m))
    C[0, :m] = phi[b_dof]
    C[1, m:] = phi[b_dof]
    C[2, :m] = trow @ phi
    x0 = None if rigid else np.zeros(2 * m)
    y_off = np.zeros(3)
    if not rigid:
        y_off = np.array([x_eq[b_dof], 0.0, trow @ x_eq])
    has_rigid = rigid or bool(np.any(lam == 0.0))
    comp = static_compliance(string, asm.top, asm.bottom)
    resid = comp - float(np.sum(phi[b_dof] ** 2 / lam)) if not has_rigid else math.nan
    return StateSpace(A, B, C, np.zeros((3, 1)), d, x0, -wob_v, np.eye(m), np.diag(lam), Cm, gen_load,
                      gen_b, phi, asm.nodes, asm.mesh.z, asm.n_nodes - 1, b_dof, asm.top, asm.bottom,
                      wob_v, weight - wob_v, x_eq_full, resid, math.sqrt(lam[-1]) / (2 * math.pi), y_off)

