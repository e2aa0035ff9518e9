"""Axial natural frequencies and mode shapes: discrete (finite elements) and exact (transfer matrix).

Discrete modes
    Eigenpairs of the tridiagonal pencil (:mod:`.eigen`: Sturm bisection and
    inverse iteration, only the modes asked for), then an **impedance
    correction**.  A two-node element with ``theta = omega h / c`` behaves
    exactly like a piece of continuous bar whose phase is off by the
    dispersion error (``-(theta)^4/480`` for the mixed mass) and whose
    impedance is ``rho(theta) Z`` with ``rho^2 = 1 + (b - a) theta^2/2`` (``a,
    b`` the diagonal and off-diagonal mass factors; ``rho = 1 - theta^2/12 +
    ...`` for the mixed mass).  Where the impedance meets something else, an
    end mass or spring or a section with a different ``theta``, that
    second-order impedance error shows up in the frequencies.  Dividing each
    element's dynamic stiffness by ``rho`` removes it; to first order each
    eigenvalue moves by ``sum_e (1/rho_e - 1) phi^T (K_e - lam M_e) phi``.  The
    corrected frequencies converge at fourth order with tip masses, springs
    and unequal sections alike; ``Modes.fe_frequencies_hz`` keeps the plain
    eigenvalues of ``K, M`` (those of the state space).

Accuracy target
    :func:`modes` meshes by equal travel time for a target relative accuracy
    ``rtol`` (default 1e-5) at the highest frequency asked for, then
    estimates the error of every mode from a second solve on a mesh with half
    the elements per section (Richardson, fourth order) and refines until the
    estimate meets ``rtol``.  ``Modes.error_estimate`` carries it.

Exact modes
    :func:`exact_frequencies` multiplies the section transfer matrices and
    brackets the roots (boundary dashpots ignored).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .assembly import Assembly, assemble, element_pattern
from .validation import DEFAULT_MASS, DEFAULT_RTOL, check_mass, check_number
from .boundary import Boundary
from .drill_string import DrillString, resolve_ends
from .eigen import assembly_eigenpairs, has_rigid_mode

__all__ = ["Modes", "modes", "exact_frequencies", "impedance_factor", "corrected_eigenvalues", "solve_modes"]


def impedance_factor(theta2: "float | complex | np.ndarray", mass: str = DEFAULT_MASS):
    """``rho = Z_h/Z`` of a two-node element with ``theta^2 = (omega h/c)^2``
    (complex with damping): ``sqrt(1 + (b - a) theta^2 / 2)``; mixed mass
    ``sqrt(1 - theta^2/6)``."""
    a, b = element_pattern(mass)
    return np.sqrt(1.0 + 0.5 * (b - a) * np.asarray(theta2))


def corrected_eigenvalues(asm: Assembly, lam: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Eigenvalues [rad^2/s^2] with the element impedance correction to first
    order: ``lam + sum_e (1/rho_e - 1) phi^T (K_e - lam M_e) phi``."""
    if lam.size == 0:
        return lam.copy()
    ms = asm.mesh
    a, b = asm.element_pattern
    full = np.zeros((asm.n_nodes, lam.size))
    full[asm.start:asm.stop] = phi
    du = np.diff(full, axis=0)                       # (n_el, m)
    kel = (ms.ea / ms.h)[:, None]
    mel = (ms.m * ms.h)[:, None]
    lag = kel * du ** 2 - lam * mel * (a * (full[:-1] ** 2 + full[1:] ** 2) + 2.0 * b * full[:-1] * full[1:])
    tau2 = (ms.h ** 2 * ms.m / ms.ea)[:, None]       # (h/c)^2
    rho = np.sqrt(np.maximum(1.0 + 0.5 * (b - a) * lam * tau2, 0.25))  # floor: coarse meshes only
    return np.maximum(lam + np.sum((1.0 / rho - 1.0) * lag, axis=0), 0.0)


@dataclass(frozen=True)
class Modes:
    """Undamped axial modes of a string with given ends."""

    frequencies_hz: np.ndarray
    """Natural frequencies (n,) [Hz], ascending, impedance-corrected (see the
    module docstring); rigid-body modes are 0."""
    shapes: np.ndarray
    """Mass-normalised shapes on all nodes (n_nodes, n) [1/sqrt(kg)];
    zero at fixed ends; sign chosen so the bit displacement is >= 0."""
    z: np.ndarray
    """Node depths (n_nodes,) [m]."""
    top: Boundary
    bottom: Boundary
    mass: str
    n_elements: int
    fe_frequencies_hz: np.ndarray | None = None
    """Plain eigenvalues of ``K, M`` as frequencies (n,) [Hz] (no correction)."""
    error_estimate: np.ndarray | None = None
    """Estimated relative error of each frequency (n,) [-] (None: not estimated)."""
    rtol: float | None = None
    """Target relative accuracy the mesh was chosen for [-] (None: mesh as given)."""
    elements_per_section: tuple[int, ...] = ()
    """Element count of each section."""

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies (n,) [rad/s]."""
        return 2.0 * math.pi * self.frequencies_hz

    def __len__(self) -> int:
        return int(self.frequencies_hz.size)

    def to_dict(self, shapes: bool = False) -> dict:
        d = {"frequencies_hz": [float(f) for f in self.frequencies_hz],
             "top": self.top.spec(), "bottom": self.bottom.spec(), "mass": self.mass,
             "elements": self.n_elements, "elements_per_section": list(self.elements_per_section),
             "rtol": self.rtol,
             "error_estimate": None if self.error_estimate is None
             else [float(e) for e in self.error_estimate]}
        if shapes:
            d["depth_m"] = self.z.tolist()
            d["shapes"] = self.shapes.T.tolist()
        return d


def solve_modes(string: DrillString, top, bottom, f_max, count, mass, correct, first=0):
    asm = assemble(string, top, bottom, mass=mass)
    lam, phi = assembly_eigenpairs(asm, f_max, count, first=first)
    lam_c = corrected_eigenvalues(asm, lam, phi) if correct else lam
    if correct and lam.size and first == 0 and has_rigid_mode(asm.top, asm.bottom):
        lam_c[0] = 0.0
    return asm, lam, lam_c, phi


def modes(string: DrillString, top: "Boundary | str | None" = None,
          bottom: "Boundary | str | None" = None, f_max: float | None = None,
          count: int | None = None, *, mass: str = DEFAULT_MASS,
          rtol: float | None = DEFAULT_RTOL, correct: bool = True) -> Modes:
    """Lowest axial natural frequencies and mode shapes.

    Parameters
    ----------
    string : DrillString
    top, bottom : Boundary or str, optional
        Ends (default ``string.top``/``string.bottom``; the bit mass applies,
        see :meth:`DrillString.resolve_bottom`); ``hammer`` = free.
    f_max : float, optional
        Keep modes with frequency <= f_max [Hz].
    count : int, optional
        Keep at most the ``count`` lowest modes (default 10 if ``f_max`` is
        not given either).
    mass : {"mixed", "lumped", "consistent"}
    rtol : float or None
        Target relative accuracy of every returned frequency [-] (default
        1e-5): the mesh is chosen by equal travel time and refined until the
        error estimate meets it (never coarser than the string's own mesh).
        ``None``: the string's mesh as it is, no estimate.
    correct : bool
        Apply the element impedance correction (module docstring).

    Returns
    -------
    Modes
    """
    check_mass(mass)
    if count is None and f_max is None:
        count = 10
    if rtol is None:
        asm, lam, lam_c, phi = solve_modes(string, top, bottom, f_max, count, mass, correct)
        est, fine = None, string
    else:
        check_number("modes", "rtol", rtol, 1e-12, 0.1, unit="(relative)")
        if f_max is not None:
            f_target = float(f_max)
        else:
            t_total = sum(x.length / x.wave_speed for x in string.sections)
            probe = string.with_travel_time(t_total / (4 * count + 8))
            _, _, first, _ = solve_modes(probe, top, bottom, None, count, mass, correct)
            f_target = math.sqrt(float(first.max(initial=0.0))) / (2.0 * math.pi) * 1.02
            if f_target <= 0.0:
                f_target = 1.0
        fine = string.for_accuracy(f_target, 0.5 * rtol, mass)
        order = 4.0 if (mass == "mixed" and correct) else 2.0
        for _ in range(6):
            asm, lam, lam_c, phi = solve_modes(fine, top, bottom, f_max, count, mass, correct)
            coarse = fine.with_elements([max(1, (n + 1) // 2) for n in fine.elements_per_section])
            _, _, lam_h, _ = solve_modes(coarse, top, bottom, None, lam.size, mass, correct)
            f_f = np.sqrt(lam_c)
            f_c = np.sqrt(lam_h[: lam.size])
            if f_c.size < f_f.size:
                f_c = np.concatenate((f_c, np.zeros(f_f.size - f_c.size)))
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(f_f > 0, np.abs(f_f - f_c) / np.where(f_f > 0, f_f, 1.0), 0.0)
            est = rel / (2.0 ** order - 1.0)
            worst = float(est.max(initial=0.0))
            if worst <= rtol:
                break
            factor = min(4.0, (2.0 * worst / rtol) ** (1.0 / order))
            fine = fine.with_travel_time(float(np.min(fine.travel_times)) / factor)
    shapes = np.zeros((asm.n_nodes, lam.size))
    shapes[asm.start:asm.stop] = phi
    two_pi = 2.0 * math.pi
    return Modes(np.sqrt(lam_c) / two_pi, shapes, asm.mesh.z, asm.top, asm.bottom, mass,
                 fine.n_elements, np.sqrt(lam) / two_pi, est, rtol, fine.elements_per_section)


# --------------------------------------------------------------------------
# exact (continuous) solution by transfer matrices
# --------------------------------------------------------------------------
def bottom_state(string: DrillString, top: Boundary, omega) -> tuple:
    """State ``(u, N)`` at the bottom of the continuous string, per ``omega`` [rad/s].

    Starts at the top (fixed: ``[0, 1]``, otherwise ``[1, k_t - m_t w^2]``) and
    carries ``s = [u, N]`` (displacement, tension ``N = EA u'``) down each uniform
    section by ``[[cos kl, sin kl/(Z w)], [-Z w sin kl, cos kl]]`` (``k = w/c``,
    ``Z w = EA k``).  Dashpots are ignored.
    """
    w = np.asarray(omega, dtype=float)
    if top.is_fixed:
        u, n = np.zeros_like(w), np.ones_like(w)
    else:
        u, n = np.ones_like(w), top.ground_stiffness - top.mass * w ** 2
    for s in string.sections:
        a = w * s.length / s.wave_speed
        zw = s.impedance * w
        ca, sa = np.cos(a), np.sin(a)
        with np.errstate(divide="ignore", invalid="ignore"):
            sz = np.where(zw > 0, sa / np.where(zw > 0, zw, 1.0), s.length / s.axial_stiffness)
        u, n = ca * u + sz * n, -zw * sa * u + ca * n
    return u, n


def _characteristic(string: DrillString, top: Boundary, bottom: Boundary,
                    omega: np.ndarray) -> np.ndarray:
    """Frequency function g(omega) whose roots are the exact natural frequencies.

    State ``s = [u, N]`` (displacement, tension ``N = EA u'``) is carried
    down each uniform section by ``[[cos kl, sin kl/(Z w)], [-Z w sin kl, cos kl]]``
    (``k = w/c``, ``Z w = EA k``).  Top: fixed ``s0=[0, 1]``, otherwise
    ``s0 = [1, k_t - m_t w^2]``.  Bottom: fixed ``r=[1, 0]``, otherwise
    ``r = [k_b - m_b w^2, 1]``; ``g = r . T(w) s0``.  Dashpots are ignored.
    """
    u, n = bottom_state(string, top, omega)
    w = np.asarray(omega, dtype=float)
    if bottom.is_fixed:
        return u
    return (bottom.ground_stiffness - bottom.mass * w ** 2) * u + n


def exact_frequencies(string: DrillString, top: "Boundary | str | None" = None,
                      bottom: "Boundary | str | None" = None, count: int = 4,
                      *, f_max: float | None = None, points_per_mode: int = 256) -> np.ndarray:
    """Natural frequencies [Hz] of the continuous piecewise-uniform bar.

    Roots of :func:`_characteristic` are bracketed on a grid of
    ``points_per_mode`` points per mean mode spacing ``1/(2 sum l/c)`` and
    polished with ``brentq``.  A rigid-body mode (both ends free, no
    springs) is returned as 0.  Boundary dashpots are ignored.

    Returns
    -------
    ndarray (count,) or all roots <= f_max.
    """
    from scipy.optimize import brentq
    top, bottom = resolve_ends(string, top, bottom)
    if bottom.kind == "hammer":
        bottom = Boundary.free(string.bit_mass)
    rigid = has_rigid_mode(top, bottom)
    roots: list[float] = [0.0] if rigid else []
    spacing = 1.0 / (2.0 * sum(s.length / s.wave_speed for s in string.sections))  # Hz
    step = 2.0 * math.pi * spacing / points_per_mode
    w0 = 1e-9 * step
    target = math.inf if f_max is None else 2.0 * math.pi * f_max
    need = math.inf if f_max is not None else count

    def g(w: float) -> float:
        return float(_characteristic(string, top, bottom, np.array([w]))[0])

    while len(roots) < need:
        grid = w0 + step * np.arange(points_per_mode * 8 + 1)
        val = _characteristic(string, top, bottom, grid)
        for i in np.nonzero(np.sign(val[:-1]) * np.sign(val[1:]) < 0)[0]:
            roots.append(brentq(g, grid[i], grid[i + 1], xtol=1e-13 * grid[i + 1], rtol=1e-15,
                                maxiter=200))
        if grid[-1] > target:
            break
        w0 = grid[-1]
    out = np.array(roots) / (2.0 * math.pi)
    if f_max is not None:
        return out[out <= f_max]
    return out[:count]


