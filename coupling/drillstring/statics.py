"""Statics: the string hanging from the hook with a weight on bit, and the static bit compliance.

Gravity ``g = 9.81 m/s^2`` acts on the buoyed weight per length
``q = m' g (1 - rho_mud / rho)`` (buoyancy-factor method: effective tension,
pressure-area and ballooning terms neglected).  Nodal displacements are exact
for piecewise-uniform sections (linear elements, consistent nodal loads).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .assembly import assemble
from .validation import G
from .boundary import Boundary, check_end, parse_boundary
from .drill_string import DrillString, resolve_ends

__all__ = ["StaticState", "static_equilibrium", "static_compliance"]


@dataclass(frozen=True)
class StaticState:
    """Static equilibrium of the string hanging from the hook."""

    z: np.ndarray
    """Node depths (n_nodes,) [m]."""
    displacement: np.ndarray
    """Downward node displacement from the unstrained string (n_nodes,) [m]."""
    tension_nodes: np.ndarray
    """Effective tension at the nodes (n_nodes,) [N] (exact; < 0 = compression)."""
    tension_elements: np.ndarray
    """Effective tension ``EA du/dz`` per element (n_el,) [N] (= exact value at
    the element mid-point)."""
    hook_load: float
    """Force at the hook = buoyed weight - weight on bit [N]."""
    wob: float
    """Weight on bit [N] (force of the rock on the bit, upward)."""
    buoyed_weight: float
    """Buoyed weight of the string incl. bit-end mass [N]."""
    neutral_point_depth: float | None
    """Depth of zero effective tension [m] (None when the whole string is in tension)."""

    @property
    def bit_displacement(self) -> float:
        """Static displacement of the bit node [m]."""
        return float(self.displacement[-1])


def static_equilibrium(string: DrillString, wob: float | None = None, hook_load: float | None = None,
                       *, top: "Boundary | str | None" = None, mud_density: float | None = None,
                       bottom_mass: float | None = None) -> StaticState:
    """Static stretch of the string hung from the hook with a weight on bit.

    The top is the hook (default ``string.top``, normally fixed; a spring top
    stretches by ``hook_load/k``).  The bit carries the upward force ``wob``.
    Give ``wob`` *or* ``hook_load`` (``hook_load = W_buoyed - wob``); neither
    means off bottom (``wob = 0``).  Nodal displacements are exact for
    piecewise-uniform sections (linear elements, consistent nodal loads).

    Parameters
    ----------
    string : DrillString
    wob : float, optional
        Weight on bit [N], 0 <= wob <= buoyed weight.
    hook_load : float, optional
        Hook load [N].
    top : Boundary or str, optional
        Hook boundary (``fixed`` or ``spring``).
    mud_density : float, optional
        Override ``string.mud_density`` [kg/m^3].
    bottom_mass : float, optional
        Lumped mass at the bit [kg] (weight included, buoyed); default the
        string's bit mass (:attr:`DrillString.bit_mass`).

    Returns
    -------
    StaticState
    """
    import scipy.linalg as sla  # noqa: PLC0415 -- imported where needed (a slow import)
    if mud_density is not None:
        string = string.replace(mud_density=mud_density)
    topb = check_end(parse_boundary(string.top if top is None else top), "top")
    if topb.kind == "free" or (topb.kind == "spring" and topb.stiffness == 0.0):
        raise ValueError("static equilibrium needs a hook: top must be 'fixed' or 'spring'")
    bottom_mass = string.bit_mass if bottom_mass is None else float(bottom_mass)
    asm = assemble(string.replace(bottom=Boundary.free(bottom_mass)), topb, None, mass="lumped")
    f = asm.gravity_load()
    weight = float(f.sum() - (topb.mass * G if not topb.is_fixed else 0.0))
    if wob is not None and hook_load is not None:
        raise ValueError("give wob or hook_load, not both")
    if hook_load is not None:
        wob = weight - float(hook_load)
    wob = 0.0 if wob is None else float(wob)
    if not -1e-9 * weight <= wob <= weight * (1 + 1e-12):
        raise ValueError(f"wob = {wob:.6g} N: allowed range 0 <= wob <= buoyed weight {weight:.6g} N")
    f = f.copy()
    f[-1] -= wob
    kd, ke = asm.tridiagonal("K")
    ab = np.zeros((2, kd.size))
    ab[0, 1:], ab[1] = ke, kd
    u = np.zeros(asm.n_nodes)
    u[asm.start:asm.stop] = sla.solveh_banded(ab, f[asm.start:asm.stop])
    ms = asm.mesh
    t_el = ms.ea * np.diff(u) / ms.h
    below = np.concatenate((np.cumsum((ms.q * ms.h)[::-1])[::-1], [0.0]))
    bf_bit = string.sections[-1].buoyancy_factor(string.mud_density)
    t_nodes = below + bottom_mass * G * bf_bit - wob
    neutral = None
    if t_nodes[-1] < 0.0:
        i = int(np.argmax(t_nodes <= 0.0))
        if i == 0:
            neutral = 0.0
        else:
            t0, t1 = t_nodes[i - 1], t_nodes[i]
            neutral = float(ms.z[i - 1] + (ms.z[i] - ms.z[i - 1]) * t0 / (t0 - t1))
    return StaticState(ms.z, u, t_nodes, t_el, weight - wob, wob, weight, neutral)


def static_compliance(string: DrillString, top: "Boundary | str | None" = None,
                      bottom: "Boundary | str | None" = None) -> float:
    """Static driving-point compliance at the bit [m/N].

    The hook spring (if any) and the elements act in series, the bottom
    spring in parallel: ``1 / (1/(1/k_t + sum h/EA) + k_b)``.  Returns inf
    with a rigid-body mode and 0 with a fixed bit.
    """
    topb, botb = resolve_ends(string, top, bottom)
    if botb.is_fixed:
        return 0.0
    ms = string.mesh()
    if topb.is_fixed:
        flex = float(np.sum(ms.h / ms.ea))
    elif topb.ground_stiffness > 0.0:
        flex = float(np.sum(ms.h / ms.ea)) + 1.0 / topb.ground_stiffness
    else:
        flex = math.inf
    stiff = (0.0 if math.isinf(flex) else 1.0 / flex) + botb.ground_stiffness
    return math.inf if stiff == 0.0 else 1.0 / stiff


