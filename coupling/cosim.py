"""Co-simulation master: a linear drillstring stepped exactly, a hammer FMU.

The coupled system (everything positive downward)::

    hook (fixed) -- drillstring (linear, n nodes) -- interface (k_i, c_i) -- hammer m1
                 -- spring/damper (K, C) and impact gap -- bit m2 -- rock (stick/slip)

Causality
---------
* **String side** (stepped by this master): the string *and* the interface
  spring-dashpot.  Input: the hammer's position and velocity ``(x_h, v_h)``;
  output: the interface force on the hammer
  ``F_i = W + k_i (u_b - u_b,eq - (x_h - x_h,eq)) + c_i (v_b - v_h)`` (pushing
  the hammer down; ``-F_i`` acts on the string's bottom node).
* **Hammer side** (the FMU ``HammerBitRock.fmu``, or the same kernels in
  process, :class:`StepperHammer`): input ``preload`` = ``F_i`` (held
  constant over a macro step, FMI 2.0 co-simulation); outputs hammer and bit
  position and velocity.

Exact string step
-----------------
Over a macro step ``[t_n, t_n + H]`` the hammer motion seen by the string is
a polynomial (degree 0, 1 or 2) given by its Taylor coefficients.  The string
state ``xi`` (deviation from static equilibrium) obeys
``xi' = A' xi + E w(s)``, ``A' = A - B (k_i C_u + c_i C_v)``, ``E = B [k_i, c_i]``.
Appending the polynomial's coefficients as a nilpotent chain and the time
integral of the interface force as one more state gives one linear
autonomous system whose matrix exponential ``expm(Z H)`` (computed once per
``H``, :func:`scipy.linalg.expm`) maps ``[xi_n, coefficients]`` exactly to
``[xi_{n+1}, int F_i dt]``: one dense mat-vec per macro step, no loops over
elements.  ``CosimConfig.f_max`` truncates to the modes below ``f_max``.

Schemes
-------
* ``jacobi``: both sides step from the data at ``t_n``.  The hammer gets the
  mean over the step of the force extrapolated (order 0, 1, 2) from
  ``F(t_n), F(t_{n-1}), F(t_{n-2})`` (weights 1; 3/2, -1/2; 23/12, -16/12, 5/12);
  the string gets the hammer motion extrapolated from ``t_n, t_{n-1}, t_{n-2}``.
* ``gauss-seidel``: the hammer steps first (as above); the string then
  *interpolates* the hammer motion through the new value: order 0 holds the
  value at ``t_{n+1}``, order 1 is linear between ``t_n`` and ``t_{n+1}``,
  order 2 the parabola through ``t_{n-1}, t_n, t_{n+1}``.

Communication times are ``t0 + n H`` (never accumulated).

Coupling instability
--------------------
As ECCO's power-bond residual (Sadjina et al. 2017): over each macro step the
energy the string side delivers through the interface,
``int F_i v_h,used dt`` (trapezoid on the step ends), is compared with the
work the held force does on the hammer, ``F_held (x_h(t_{n+1}) - x_h(t_n))``
(exact).  Their difference is the energy the coupling creates or destroys.
The absolute residual is summed over windows of ``stability_window`` steps;
when a window's residual exceeds ``energy_tol`` times the reference energy of
the interface (``W^2/(2 k_i) + W^2/(2 K) + A^2/K``) *and* has grown by
``growth`` over each of ``growth_windows`` consecutive windows, or when the
interface force leaves ``blowup`` times its physical scale, or a value is
not finite, :class:`CouplingInstabilityError` is raised.

Field hammer
------------
:func:`field_hammer` scales the rig of the paper to field size keeping all
dimensionless groups; see its docstring.
"""
from __future__ import annotations

import math
import sys
import time as _time
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Optional, Sequence

import numpy as np
import scipy.linalg as sla

from hammerbit.model.params import RigParameters, Scales, RIG

__all__ = [
    "CosimConfig", "CosimResult", "CouplingInstabilityError", "field_hammer", "StringSide",
    "StepperHammer", "FMUHammer", "cosimulate", "monolithic", "RECORDABLE", "SCHEMES",
    "extrapolation_weights", "coupled_modes",
]

SCHEMES = ("jacobi", "gauss-seidel")

#: Variables a run can record (all SI), in output order after ``time``.
RECORDABLE = {
    "wob": "weight on bit: drive of the hammer assembly on the bit K(x_h-x_b)+C(v_h-v_b)+F_c [N]",
    "interface_force": "force of the string (interface spring-dashpot) on the hammer [N]",
    "hammer_force": "force held on the hammer's preload input over the step [N]",
    "hammer_position": "hammer position [m] (downward)",
    "hammer_velocity": "hammer velocity [m/s]",
    "bit_position": "bit position = penetration [m]",
    "bit_velocity": "bit velocity [m/s]",
    "string_bit_displacement": "displacement of the string's bottom node from equilibrium [m]",
    "string_bit_velocity": "velocity of the string's bottom node [m/s]",
    "hook_load": "hook load [N]: static hook load plus the dynamic tension of the top element",
    "energy_residual": "coupling energy residual of the step (power-bond residual x H) [J]",
}


class CouplingInstabilityError(RuntimeError):
    """The co-simulation coupling became unstable (energy growth at the interface).

    Attributes
    ----------
    time : float
        Communication time [s] where it was detected.
    step : int
        Macro-step index.
    residual : float
        Absolute energy residual of the last window [J].
    reference : float
        Reference energy [J] it was compared with.
    """

    def __init__(self, message: str, *, time: float, step: int, residual: float, reference: float):
        self.time = time
        self.step = step
        self.residual = residual
        self.reference = reference
        super().__init__(message)


# ---------------------------------------------------------------------------
# field hammer
# ---------------------------------------------------------------------------
def field_hammer(*, hammer_mass: float = 400.0, natural_frequency: float = 20.0,
                 friction_force: float = 100e3, groups=None) -> RigParameters:
    """A field-size resonance hammer with the dimensionless groups of the rig.

    The rig of Franca & Weber (``RigParameters()``: m1 = 25.3 kg,
    K = 2170 N/m, F0 = 54 N, natural frequency 1.47 Hz) is scaled by choosing
    the three scales the nondimensional form loses:

    * hammer mass ``m1 = 400 kg`` -- a downhole hammer body of a few hundred
      kilograms (an 8 in percussion hammer piston and housing);
    * natural frequency ``Omega/2pi = 20 Hz`` -- the middle of the 10-30 Hz
      band of downhole resonance/percussion tools, so ``K = m1 Omega^2 =
      6.32e6 N/m``;
    * friction force ``F0 = 100 kN`` -- so the rig's preload group
      ``b = 0.55`` is a weight on bit of 55 kN (5.6 t), a usual WOB for an
      8.5 in hard-rock bit, and ``a = 0.15`` is a 15 kN harmonic force.

    Every group (rho, xi, eta, a, b, r, mu, gamma_hat, kc, n, lam_hat, phi)
    is that of ``RigParameters().to_groups()`` (or ``groups`` if given), so
    the nondimensional dynamics are the rig's; the length scale becomes
    ``x0 = F0/K = 15.8 mm``.  ``preload`` is the WOB of the static
    equilibrium, ``frequency`` = 20 Hz (eta = 1).
    """
    g = RIG.to_groups() if groups is None else groups
    K = hammer_mass * (2.0 * math.pi * natural_frequency) ** 2
    return g.to_rig(Scales(hammer_mass, K, friction_force), mu_static=RIG.mu_static)


# ---------------------------------------------------------------------------
# configuration
# ---------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class CosimConfig:
    """Options of a co-simulation run (SI units; keyword-only).

    Attributes
    ----------
    stop : float
        End time [s] (start at ``start``).
    step : float
        Macro step H [s].
    start : float
        Start time t0 [s].
    scheme : {'jacobi', 'gauss-seidel'}
    extrapolation : {0, 1, 2}
        Polynomial order of the exchanged signals over a step.
    rig : RigParameters
        Hammer; its ``preload`` is replaced by the interface force and its
        amplitude/frequency/phase drive the internal harmonic source.
    wob : float, optional
        Weight on bit of the static equilibrium [N] (default ``rig.preload``).
    interface_stiffness, interface_damping : float
        k_i [N/m], c_i [N s/m] between the string's bottom node and the hammer.
        Default 2e6 N/m and 2e3 N s/m: a shock sub.  With the 400 kg field
        hammer it puts the hammer-on-interface mode at 11 Hz, below the
        20 Hz drive, so the string is isolated and the hammer resonates and
        drills.  A stiff interface (>= 1e7 N/m) clamps the hammer to the
        collars (impedance ~ 7e5 N s/m against ``omega m1`` = 5e4 N s/m), the
        hammer cannot resonate and the bit does not progress.
    mass : str
        Mass scheme of the string (``mixed``, ``lumped``, ``consistent``).
    f_max : float, optional
        Modal truncation of the string at f_max [Hz] (None: all nodal DOFs).
    record : tuple of str
        Variables to record (keys of :data:`RECORDABLE`); ``time`` is always first.
    record_every : int
        Record every n-th communication point.
    check_stability : bool
        Watch the power-bond residual (see module docstring).
    energy_tol, growth, growth_windows, stability_window, blowup : float/int
        Thresholds of the instability detector.
    progress : bool, optional
        Progress bar on stderr (None: only for runs above 20000 steps on a tty).
    rtol : float
        Tolerance of the in-process hammer / the monolithic reference.
    """

    stop: float = 1.0
    step: float = 1e-3
    start: float = 0.0
    scheme: str = "jacobi"
    extrapolation: int = 2
    rig: RigParameters = field(default_factory=field_hammer)
    wob: Optional[float] = None
    interface_stiffness: float = 2.0e6
    interface_damping: float = 2.0e3
    mass: str = "mixed"
    f_max: Optional[float] = None
    record: tuple = ("wob", "interface_force", "hammer_position", "hammer_velocity",
                     "bit_position", "bit_velocity")
    record_every: int = 1
    check_stability: bool = True
    energy_tol: float = 0.05
    growth: float = 1.2
    growth_windows: int = 3
    stability_window: int = 10
    blowup: float = 50.0
    progress: Optional[bool] = None
    rtol: float = 1e-10
    harmonic_source: str = "fmu"
    """``fmu``: the FMU's internal harmonic source (continuous in time);
    ``master``: the master computes the harmonic force and feeds its mean over
    each macro step to the FMU's ``harmonic_force`` input (zero-order hold),
    with the FMU's internal source switched off."""

    def __post_init__(self):
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme = {self.scheme!r}: allowed {', '.join(SCHEMES)}")
        if self.extrapolation not in (0, 1, 2):
            raise ValueError(f"extrapolation = {self.extrapolation!r}: allowed 0, 1, 2")
        if self.harmonic_source not in ("fmu", "master"):
            raise ValueError(f"harmonic_source = {self.harmonic_source!r}: allowed 'fmu', 'master'")
        if not (self.step > 0 and math.isfinite(self.step)):
            raise ValueError(f"step = {self.step!r}: must be > 0 s")
        if not self.stop > self.start:
            raise ValueError(f"stop = {self.stop!r}: must be > start = {self.start!r}")
        if self.interface_stiffness <= 0 or self.interface_damping < 0:
            raise ValueError("interface_stiffness must be > 0 and interface_damping >= 0")
        bad = [r for r in self.record if r not in RECORDABLE]
        if bad:
            raise ValueError(f"record: unknown variable(s) {bad}; allowed {', '.join(RECORDABLE)}")
        if self.record_every < 1:
            raise ValueError("record_every must be >= 1")
        if self.wob is not None and self.wob < 0:
            raise ValueError("wob must be >= 0 N")

    @property
    def weight_on_bit(self) -> float:
        """WOB of the static equilibrium [N]."""
        return float(self.rig.preload if self.wob is None else self.wob)

    @property
    def macro_steps(self) -> int:
        """Number of macro steps ``round((stop - start)/step)``."""
        return int(round((self.stop - self.start) / self.step))

    def replace(self, **changes) -> "CosimConfig":
        return replace(self, **changes)


def _dtype(record: Sequence[str]) -> np.dtype:
    return np.dtype([("time", "f8")] + [(r, "f8") for r in record])


@dataclass
class CosimResult:
    """Result of :func:`cosimulate` or :func:`monolithic`.

    Attributes
    ----------
    data : structured ndarray
        ``time`` then the recorded variables (SI).
    config : CosimConfig
    macro_steps : int
    wall_time_s : float
        Time of the stepping loop (set-up excluded).
    setup_time_s : float
    penetration_m : float
        Bit position at the end [m].
    stats : dict
        Maximum window energy residual, hammer calls, ...
    method : str
        ``cosim`` or ``monolithic``.
    """

    data: np.ndarray
    config: CosimConfig
    macro_steps: int
    wall_time_s: float
    setup_time_s: float
    penetration_m: float
    stats: dict
    method: str = "cosim"

    def window(self, t_from: Optional[float] = None) -> np.ndarray:
        """Rows with time >= t_from (default: the second half of the run)."""
        if t_from is None:
            t_from = 0.5 * (self.config.start + self.config.stop)
        return self.data[self.data["time"] >= t_from - 1e-12]

    def wob_amplitude(self, t_from: Optional[float] = None) -> float:
        """Dynamic WOB amplitude (max - min)/2 over the window [N]."""
        w = self.window(t_from)["wob"]
        return float(0.5 * (w.max() - w.min()))

    def wob_mean(self, t_from: Optional[float] = None) -> float:
        """Mean WOB over the window [N]."""
        return float(np.mean(self.window(t_from)["wob"]))

    def summary(self, t_from: Optional[float] = None) -> dict:
        """JSON-ready figures."""
        out = {"method": self.method, "scheme": self.config.scheme,
               "extrapolation": self.config.extrapolation, "step_s": self.config.step,
               "stop_s": self.config.stop, "macro_steps": self.macro_steps,
               "wall_time_s": self.wall_time_s, "setup_time_s": self.setup_time_s,
               "penetration_m": self.penetration_m}
        if "wob" in self.data.dtype.names:
            out["wob_mean_n"] = self.wob_mean(t_from)
            out["wob_amplitude_n"] = self.wob_amplitude(t_from)
        out.update({k: v for k, v in self.stats.items() if isinstance(v, (int, float, str))})
        return out

    def to_csv(self, path) -> Path:
        """Write the recorded array as CSV (header = field names)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        names = self.data.dtype.names
        arr = np.column_stack([self.data[n] for n in names]) if len(self.data) else np.zeros((0, len(names)))
        np.savetxt(path, arr, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
        return path


# ---------------------------------------------------------------------------
# extrapolation
# ---------------------------------------------------------------------------
def extrapolation_weights(order: int) -> np.ndarray:
    """Weights on (F_n, F_{n-1}, F_{n-2}) of the mean over [t_n, t_n+H] of the
    extrapolation polynomial of the given order (Adams–Bashforth weights)."""
    return {0: np.array([1.0, 0.0, 0.0]), 1: np.array([1.5, -0.5, 0.0]),
            2: np.array([23.0, -16.0, 5.0]) / 12.0}[order]


# ---------------------------------------------------------------------------
# string side
# ---------------------------------------------------------------------------
class StringSide:
    """The drillstring plus interface spring, stepped exactly over a macro step.

    Parameters
    ----------
    string : DrillString
    config : CosimConfig

    Attributes
    ----------
    ss : StateSpace
        Exported model (``hammerbit.drillstring.state_space``) at the WOB.
    A1, E : ndarray
        Closed-interface state matrix and the input matrix of ``(x_h, v_h)``.
    Cu, Cv, Ct : ndarray
        Output rows: bit displacement, bit velocity, top tension.
    """

    def __init__(self, string, config: CosimConfig):
        from hammerbit.drillstring import Boundary, state_space
        self.config = config
        ki, ci = config.interface_stiffness, config.interface_damping
        self.ki, self.ci = ki, ci
        self.wob = config.weight_on_bit
        ss = state_space(string, None, Boundary.hammer(ki, ci), mass=config.mass,
                         wob=self.wob, f_max=config.f_max)
        if ss.x0 is None:
            raise ValueError("the string has a rigid-body mode: the top must hold it (fixed or spring hook)")
        self.ss = ss
        B = ss.B[:, 0]
        self.Cu, self.Cv, self.Ct = ss.C[0].copy(), ss.C[1].copy(), ss.C[2].copy()
        self.A1 = ss.A - np.outer(B, ki * self.Cu + ci * self.Cv)
        self.E = np.column_stack((B * ki, B * ci))
        self.n = ss.A.shape[0]
        self.frow = ki * self.Cu + ci * self.Cv   # F_i - W = frow.xi - ki x_dev - ci v
        self.hook_eq = float(ss.hook_load)
        self.xi = np.zeros(self.n)
        self._H = None

    def discretise(self, H: float, modal: bool = True) -> None:
        """Precompute ``expm`` of the augmented system for the macro step H.

        ``modal=False`` skips the modal form (:meth:`_modal`); ``self.modal``
        is then False and only the dense ``P`` is set.
        """
        n = self.n
        N = n + 6 + 1
        Z = np.zeros((N, N))
        Z[:n, :n] = self.A1
        Z[:n, n:n + 2] = self.E
        Z[n:n + 2, n + 2:n + 4] = np.eye(2)
        Z[n + 2:n + 4, n + 4:n + 6] = np.eye(2)
        Z[N - 1, :n] = self.frow
        Z[N - 1, n:n + 2] = (-self.ki, -self.ci)
        Phi = sla.expm(Z * H)
        rows = np.r_[np.arange(n), N - 1]
        self.P = np.ascontiguousarray(Phi[np.ix_(rows, np.arange(n + 6))])
        self._H = H
        self._buf = np.zeros(n + 6)
        if modal:
            self._modal(Phi, H)
        else:
            self.modal = False

    def _modal(self, Phi: np.ndarray, H: float) -> None:
        """Diagonal (modal) form of the exact step: O(n) per macro step instead of O(n^2).

        With ``A1 = V diag(lam) V^-1`` the step is ``eta <- exp(lam H) * eta + G c``
        in modal coordinates ``eta = V^-1 xi``, and the interface force row is
        ``frow V``.  Used only when the eigenvector basis reproduces the dense
        step to 1e-10 (otherwise the dense ``P`` is kept).
        """
        n = self.n
        self.modal = False
        if getattr(self, "_eig", None) is None:
            try:
                lam, V = np.linalg.eig(self.A1)
                self._eig = (lam, V, np.linalg.inv(V))
            except np.linalg.LinAlgError:
                self._eig = False
        if self._eig is False:
            return
        lam, V, Vinv = self._eig
        d = np.exp(lam * H)
        recon = (V * d[None, :]) @ Vinv
        scale = max(np.max(np.abs(Phi[:n, :n])), 1.0)
        if not np.all(np.isfinite(recon)) or np.max(np.abs(recon - Phi[:n, :n])) > 1e-10 * scale:
            return
        # A1 is real: its complex modes come in conjugate pairs, whose two halves
        # carry conjugate states.  Keep one of each pair with weight 2 on every
        # real output (and the real modes with weight 1): half the work.
        tol = 1e-12 * max(np.max(np.abs(lam)), 1.0)
        keep = np.flatnonzero((lam.imag > tol) | (np.abs(lam.imag) <= tol))
        if np.count_nonzero(lam.imag > tol) != np.count_nonzero(lam.imag < -tol):
            return
        wgt = np.where(lam[keep].imag > tol, 2.0, 1.0)
        Vk = V[:, keep]
        self.m_d = np.ascontiguousarray(d[keep])
        self.m_G = np.ascontiguousarray((Vinv @ Phi[:n, n:n + 6])[keep])
        self.m_frow = np.ascontiguousarray((self.frow @ Vk) * wgt)
        self.m_rows = ((self.Cu @ Vk) * wgt, (self.Cv @ Vk) * wgt, (self.Ct @ Vk) * wgt)
        self._V = Vk * wgt[None, :]          # xi = Re(_V @ eta)
        self._Vinv = Vinv[keep]               # eta = _Vinv @ xi
        self.modal = True

    def step(self, coeffs: np.ndarray) -> float:
        """Advance xi over one step with hammer-motion Taylor coefficients
        (6,) = (x, v, x', v', x'', v''); x as deviation from equilibrium.
        Returns the integral of (F_i - W) over the step [N s]."""
        b = self._buf
        b[:self.n] = self.xi
        b[self.n:] = coeffs
        out = self.P @ b
        self.xi = out[:self.n]
        return float(out[self.n])

    eta = None
    """Modal state while the master steps in modal coordinates (else None)."""

    def force(self, x_dev: float, v: float) -> float:
        """Interface force on the hammer [N] for hammer deviation x_dev and velocity v."""
        f = float((self.m_frow @ self.eta).real) if self.eta is not None else float(self.frow @ self.xi)
        return self.wob + f - self.ki * x_dev - self.ci * v

    def bit(self) -> tuple:
        """(displacement deviation [m], velocity [m/s]) of the string's bottom node."""
        if self.eta is not None:
            return float((self.m_rows[0] @ self.eta).real), float((self.m_rows[1] @ self.eta).real)
        return float(self.Cu @ self.xi), float(self.Cv @ self.xi)

    def hook_load(self) -> float:
        if self.eta is not None:
            return self.hook_eq + float((self.m_rows[2] @ self.eta).real)
        return self.hook_eq + float(self.Ct @ self.xi)


# ---------------------------------------------------------------------------
# hammer sides
# ---------------------------------------------------------------------------
class _MasterHarmonic:
    """The harmonic force A sin(2 pi f t + phi) computed by the master and held
    over each macro step at its mean (the exact impulse of the step)."""

    def __init__(self, rig: RigParameters):
        self.A = rig.amplitude
        self.w = 2.0 * math.pi * rig.frequency
        self.phi = rig.phase

    def mean(self, t: float, H: float) -> float:
        w, phi = self.w, self.phi
        return self.A * (math.cos(w * t + phi) - math.cos(w * (t + H) + phi)) / (w * H)


def _hammer_side(fmu, rig: RigParameters, W: float, c) -> object:
    """The hammer side of a run: the FMU (fmpy) or the same kernels in process."""
    master = _MasterHarmonic(rig) if c.harmonic_source == "master" else None
    if master is not None:
        rig = rig.replace(amplitude=0.0)       # the FMU's internal source off
    h = FMUHammer(fmu, rig, W, t0=c.start, rtol=c.rtol) if fmu is not None else \
        StepperHammer(rig, W, rtol=c.rtol, t0=c.start)
    h.master_harmonic = master
    return h


class StepperHammer:
    """The hammer–bit–rock model in process (the FMU's kernels, same stepper).

    Starts in static equilibrium under the WOB ``W``: hammer at ``x_h = W/K``
    (its spring compressed by ``W/K``), bit stuck at 0, both at rest.  The
    ``preload`` (interface force) is held over each step as in the FMU.
    """

    def __init__(self, rig: RigParameters, wob: float, *, rtol: float = 1e-10, t0: float = 0.0):
        from hammerbit.model import kernels as K
        from hammerbit.model.stepping import SolverOptions, Stepper
        self.rig = rig
        s = rig.scales
        self.F0, self.x0, self.Om, self.v0 = s.friction_force, s.length, s.omega, s.velocity
        g = rig.to_groups().replace(b=0.0)
        self.groups = g
        self._K = K
        self.st = Stepper(g, solver=SolverOptions(rtol=rtol, atol=rtol * 1e-2),
                          y0=[wob / self.F0, 0.0, 0.0, 0.0])
        self.st.fstate[K.F_T] = self.Om * t0
        self.x_eq = wob / rig.stiffness

    master_harmonic = None

    def step(self, t: float, H: float, force: float) -> None:
        self.st.p[self._K.P_B] = force / self.F0
        if self.master_harmonic is not None:
            self.st.p[self._K.P_FEXT] = self.master_harmonic.mean(t, H) / self.F0
        self.st.advance(self.Om * (t + H))

    def get_state(self):
        """Snapshot of the whole hammer state (for rollback)."""
        return self.st.get_state()

    def set_state(self, state) -> None:
        """Restore a snapshot of :meth:`get_state`."""
        self.st.set_state(state)

    def free_state(self, state) -> None:
        pass

    def read(self) -> np.ndarray:
        """(x_h [m], v_h [m/s], x_bit [m], v_bit [m/s], drive on bit [N])."""
        y, g = self.st.y, self.groups
        fk = (y[0] - y[2]) + 2.0 * g.xi * (y[1] - y[3])
        fc = 0.0
        if g.has_gap:
            d = y[0] - y[2] - g.r
            if d > 0:
                fc = max(0.0, g.kc * d ** g.n * (1.0 + g.lam_hat * (y[1] - y[3])))
        return np.array([y[0] * self.x0, y[1] * self.v0, y[2] * self.x0, y[3] * self.v0,
                         (fk + fc) * self.F0])

    def close(self):
        pass


#: Candidate variable names of the FMU (first match wins).
FMU_NAMES = {
    "preload": ("preload",),
    "hammer_position": ("hammer_position", "x_hammer", "hammer.position"),
    "hammer_velocity": ("hammer_velocity", "v_hammer", "hammer.velocity"),
    "bit_position": ("bit_position", "x_bit", "bit.position", "penetration"),
    "bit_velocity": ("bit_velocity", "v_bit", "bit.velocity"),
    "contact_force": ("contact_force", "impact_force"),
    "rock_force": ("rock_force", "drive_on_bit"),
    "hammer_position_start": ("hammer_position_start", "initial_hammer_position", "hammer_position0",
                              "x_hammer_start"),
}


class FMUHammer:
    """The hammer FMU driven through fmpy's ``FMU2Slave``.

    Value references come from ``read_model_description`` by name.  The
    hammer's parameters are set from the ``RigParameters`` fields the FMU
    exposes (same names); ``preload`` is the input.  If the FMU exposes a
    start value of the hammer position (``hammer_position_start`` or the
    names in :data:`FMU_NAMES`), the run starts in equilibrium
    (``W/K``); otherwise the initial preload step is the FMU's own start-up.
    """

    def __init__(self, path, rig: RigParameters, wob: float, *, t0: float = 0.0, rtol: float = 1e-8,
                 instance: str = "hammer"):
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave
        self.path = str(path)
        md = read_model_description(self.path)
        self.md = md
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.causality = {v.name: v.causality for v in md.modelVariables}
        self._unzip = extract(self.path)
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._unzip,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=t0)
        self.fmu.enterInitializationMode()
        # parameters by name
        names, vals = [], []
        for f in fields(RigParameters):
            if f.name in ("preload", "gap") or f.name not in self.vr:
                continue
            if self.causality[f.name] == "parameter":
                names.append(self.vr[f.name])
                vals.append(float(getattr(rig, f.name)))
        if "gap" in self.vr and math.isfinite(rig.gap):
            names.append(self.vr["gap"])
            vals.append(float(rig.gap))
        if "tolerance" in self.vr:
            names.append(self.vr["tolerance"])
            vals.append(float(rtol))
        if names:
            self.fmu.setReal(names, vals)
        if "impact_enabled" in self.vr:
            self.fmu.setBoolean([self.vr["impact_enabled"]], [bool(math.isfinite(rig.gap))])
        self.equilibrium_start = False
        vs = self._find("hammer_position_start", required=False)
        if vs is not None:
            self.fmu.setReal([vs], [wob / rig.stiffness])
            self.equilibrium_start = True
        self.vr_in = self._find("preload")
        self.fmu.setReal([self.vr_in], [wob])
        self.fmu.exitInitializationMode()
        out = [self._find(k) for k in ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity")]
        self.vr_rock = self._find("rock_force", required=False)
        self.vr_fc = None if self.vr_rock is not None else self._find("contact_force", required=False)
        extra = self.vr_rock if self.vr_rock is not None else self.vr_fc
        self.vr_out = out + ([extra] if extra is not None else [])
        self.rig = rig
        self.x_eq = wob / rig.stiffness if self.equilibrium_start else 0.0
        self._K, self._C = rig.stiffness, rig.damping

    def _find(self, key: str, *, required: bool = True):
        for nm in FMU_NAMES[key]:
            if nm in self.vr:
                return self.vr[nm]
        if required:
            raise KeyError(f"FMU {self.path}: no variable for {key!r} (tried {FMU_NAMES[key]}); "
                           f"it has {sorted(self.vr)}")
        return None

    master_harmonic = None

    def step(self, t: float, H: float, force: float) -> None:
        if self.master_harmonic is not None:
            self.fmu.setReal([self.vr_in, self.vr["harmonic_force"]],
                             [force, self.master_harmonic.mean(t, H)])
        else:
            self.fmu.setReal([self.vr_in], [force])
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=H)

    def get_state(self):
        """fmi2GetFMUstate (the FMU saves its whole hidden state)."""
        return self.fmu.getFMUState()

    def set_state(self, state) -> None:
        """fmi2SetFMUstate: roll the FMU back."""
        self.fmu.setFMUState(state)

    def free_state(self, state) -> None:
        self.fmu.freeFMUState(state)

    def read(self) -> np.ndarray:
        v = self.fmu.getReal(self.vr_out)
        if self.vr_rock is not None:
            wob = v[4]
        else:
            fc = v[4] if len(v) > 4 else 0.0
            wob = self._K * (v[0] - v[2]) + self._C * (v[1] - v[3]) + fc
        return np.array([v[0], v[1], v[2], v[3], wob])

    def close(self):
        import shutil
        try:
            self.fmu.terminate()
            self.fmu.freeInstance()
        finally:
            shutil.rmtree(self._unzip, ignore_errors=True)


# ---------------------------------------------------------------------------
# progress
# ---------------------------------------------------------------------------
class _Progress:
    def __init__(self, total: int, enabled: bool):
        self.total, self.enabled = total, enabled
        self.t0 = _time.perf_counter()
        self.next = 0

    def update(self, k: int):
        if not self.enabled or k < self.next:
            return
        self.next = k + max(1, self.total // 100)
        frac = k / self.total
        el = _time.perf_counter() - self.t0
        eta = el / frac - el if frac > 0 else 0.0
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\rcosim [{bar:<30}] {100 * frac:5.1f}%  {el:6.1f}s  eta {eta:6.1f}s")
        sys.stderr.flush()

    def close(self):
        if self.enabled:
            self.update(self.total)
            sys.stderr.write("\n")


# ---------------------------------------------------------------------------
# per-step exchange kernel (numba): coefficients, exact string step, residual
# ---------------------------------------------------------------------------
from numba import njit as _njit  # noqa: E402


@_njit(cache=True, fastmath=True)
def _matvec(P, b, out):
    """out[i] = sum_k P[i, k] b[k] for the first len(out) rows (SIMD reduction)."""
    m = b.shape[0]
    for i in range(out.shape[0]):
        acc = 0.0
        for k in range(m):
            acc += P[i, k] * b[k]
        out[i] = acc


@_njit(cache=True)
def _coefficients(gs, order, H, wh, x_new, v_new, c):
    """Taylor coefficients (x, v, x', v', x'', v'') of the hammer motion over the step:
    Jacobi extrapolates from the history ``wh``, Gauss–Seidel interpolates through
    the new value."""
    for k in range(2):
        w0 = wh[0, k]
        w1 = wh[1, k]
        w2 = wh[2, k]
        wn = x_new if k == 0 else v_new
        c[k] = 0.0
        c[2 + k] = 0.0
        c[4 + k] = 0.0
        if not gs:
            c[k] = w0
            if order == 1:
                c[2 + k] = (w0 - w1) / H
            elif order == 2:
                c[2 + k] = (3.0 * w0 - 4.0 * w1 + w2) / (2.0 * H)
                c[4 + k] = (w0 - 2.0 * w1 + w2) / (H * H)
        else:
            if order == 0:
                c[k] = wn
            elif order == 1:
                c[k] = w0
                c[2 + k] = (wn - w0) / H
            else:
                c[k] = w0
                c[2 + k] = (wn - w1) / (2.0 * H)
                c[4 + k] = (wn - 2.0 * w0 + w1) / (H * H)


@_njit(cache=True)
def _exchange(gs, order, H, P, xi, buf, frow, ki, ci, W, wh, Fh, x_new, v_new, F_held, out):
    """One macro step of the string side after the hammer's step (dense exact step).

    ``wh`` (3, 2): hammer (x deviation, v) at t_n, t_{n-1}, t_{n-2}; ``Fh`` (3,):
    interface forces at the same times.  Builds the Taylor coefficients of the
    hammer motion, advances ``xi`` with the precomputed ``P``, shifts the
    histories and writes ``out = [F(t_{n+1}), energy residual of the step,
    frow.xi at t_{n+1}]``; ``out[2]`` on entry is ``frow.xi`` at ``t_n`` (the
    previous call's, or the master's initial value).
    """
    n = xi.shape[0]
    c = buf[n:]
    _coefficients(gs, order, H, wh, x_new, v_new, c)
    for i in range(n):
        buf[i] = xi[i]
    F_start = W + out[2] - ki * c[0] - ci * c[1]
    # P @ buf by hand: no BLAS call (its thread pool costs more than this small mat-vec)
    _matvec(P, buf, xi)
    f_xi = 0.0
    for i in range(n):
        f_xi += frow[i] * xi[i]
    _finish(H, c, f_xi, F_start, ki, ci, W, wh, Fh, x_new, v_new, F_held, out)


@_njit(cache=True)
def _exchange_modal(gs, order, H, d, G, eta, c, frow_m, ki, ci, W, wh, Fh, x_new, v_new, F_held, out):
    """As :func:`_exchange` in modal coordinates: ``eta <- d * eta + G c`` (O(n))."""
    _coefficients(gs, order, H, wh, x_new, v_new, c)
    f1 = 0.0
    for i in range(eta.shape[0]):
        e = d[i] * eta[i]
        for k in range(6):
            e += G[i, k] * c[k]
        eta[i] = e
        f1 += (frow_m[i] * e).real
    F_start = W + out[2] - ki * c[0] - ci * c[1]
    _finish(H, c, f1, F_start, ki, ci, W, wh, Fh, x_new, v_new, F_held, out)


@_njit(cache=True)
def _finish(H, c, f_xi, F_start, ki, ci, W, wh, Fh, x_new, v_new, F_held, out):
    """Interface force at the step end, energy residual, history shift."""
    xe = c[0] + c[2] * H + 0.5 * c[4] * H * H
    ve = c[1] + c[3] * H + 0.5 * c[5] * H * H
    F_end = W + f_xi - ki * xe - ci * ve
    e_string = 0.5 * H * (F_start * c[1] + F_end * ve)
    e_hammer = F_held * (x_new - wh[0, 0])
    F = W + f_xi - ki * x_new - ci * v_new
    wh[2, 0] = wh[1, 0]
    wh[2, 1] = wh[1, 1]
    wh[1, 0] = wh[0, 0]
    wh[1, 1] = wh[0, 1]
    wh[0, 0] = x_new
    wh[0, 1] = v_new
    Fh[2] = Fh[1]
    Fh[1] = Fh[0]
    Fh[0] = F
    out[0] = F
    out[1] = e_string - e_hammer
    out[2] = f_xi          # the next step's start value of the interface sum


# ---------------------------------------------------------------------------
# the master
# ---------------------------------------------------------------------------
def cosimulate(string, config: CosimConfig = CosimConfig(), *, fmu=None, hammer=None,
               side: Optional[StringSide] = None) -> CosimResult:
    """Co-simulate the drillstring (stepped here) with the hammer.

    Parameters
    ----------
    string : DrillString
        E.g. ``hammerbit.drillstring.load_string('field-2200m')``.
    config : CosimConfig
    fmu : path, optional
        ``HammerBitRock.fmu``; the hammer is then the FMU (fmpy ``FMU2Slave``).
    hammer : object, optional
        A ready hammer side with ``step(t, H, force)``, ``read()``, ``close()``
        and ``x_eq``; default: the FMU if ``fmu`` is given, else
        :class:`StepperHammer` (the same kernels in process).
    side : StringSide, optional
        The string side of this string and config, reused across runs (a
        frequency sweep discretises the string once); its state is reset to the
        static equilibrium and it is discretised only if its step differs.

    Raises
    ------
    CouplingInstabilityError
        When the interface energy residual grows (see module docstring).
    """
    c = config
    ts = _time.perf_counter()
    H = c.step
    if side is None:
        side = StringSide(string, c)
        side.discretise(H)
    else:
        side.xi = np.zeros(side.n)
        side.eta = None
        if side._H != H:
            side.discretise(H)
    W = side.wob
    rig = c.rig
    own = hammer is None
    if hammer is None:
        hammer = _hammer_side(fmu, rig, W, c)
    setup = _time.perf_counter() - ts
    n_steps = c.macro_steps
    rec = tuple(c.record)
    nrec = n_steps // c.record_every + 1
    data = np.zeros(nrec, dtype=_dtype(rec))
    cols = {r: data[r] for r in rec}
    tcol = data["time"]
    ext_w = extrapolation_weights(c.extrapolation)
    order = c.extrapolation
    gs = c.scheme == "gauss-seidel"
    x_eq = hammer.x_eq
    # histories (index 0 newest): hammer motion (x_dev, v), forces
    out = hammer.read()
    wh = np.zeros((3, 2))
    wh[:] = (out[0] - x_eq, out[1])
    F = side.force(wh[0, 0], wh[0, 1])
    Fh = np.array([F, F, F])
    E_ref = W * W / (2 * side.ki) + W * W / (2 * rig.stiffness) + rig.amplitude ** 2 / rig.stiffness
    E_ref = max(E_ref, 1e-12)
    F_scale = c.blowup * (W + rig.amplitude + rig.scales.friction_force)
    win_sum, win_prev, n_grow, max_win, k_in_win = 0.0, math.inf, 0, 0.0, 0
    res_total = 0.0
    progress = _Progress(n_steps, c.progress if c.progress is not None
                         else (n_steps > 20000 and sys.stderr.isatty()))
    F_held = F
    r_step = 0.0

    def record(j, t, out, F, F_held, r_step):
        tcol[j] = t
        for name, col in cols.items():
            if name == "wob":
                col[j] = out[4]
            elif name == "interface_force":
                col[j] = F
            elif name == "hammer_force":
                col[j] = F_held
            elif name == "hammer_position":
                col[j] = out[0]
            elif name == "hammer_velocity":
                col[j] = out[1]
            elif name == "bit_position":
                col[j] = out[2]
            elif name == "bit_velocity":
                col[j] = out[3]
            elif name == "string_bit_displacement":
                col[j] = side.bit()[0]
            elif name == "string_bit_velocity":
                col[j] = side.bit()[1]
            elif name == "hook_load":
                col[j] = side.hook_load()
            elif name == "energy_residual":
                col[j] = r_step

    def _hammer_step(hammer, t, H, F_held, n, n_grow):
        try:
            hammer.step(t, H, F_held)
        except Exception as err:
            # the hammer side gave up; if the interface was already growing, that is the cause
            if c.check_stability and (n_grow > 0 or abs(F_held - W) > 0.2 * F_scale
                                      or not math.isfinite(F_held)):
                raise CouplingInstabilityError(
                    f"coupling unstable: the hammer side failed at t = {t:.6g} s (step {n + 1}, "
                    f"H = {H:g} s, k_i = {side.ki:g} N/m) under a growing interface force "
                    f"{F_held:.4g} N: {err}", time=t, step=n + 1, residual=math.nan,
                    reference=E_ref) from err
            raise

    record(0, c.start, out, F, F, 0.0)
    j = 1
    P, xi, frow = side.P, side.xi, side.frow
    buf = np.zeros(P.shape[1])
    modal = side.modal
    if modal:
        eta = (side._Vinv @ xi).astype(np.complex128)
        side.eta = eta
        m_d, m_G, m_frow = side.m_d, side.m_G, side.m_frow
        cbuf = np.zeros(6)
    scratch = np.zeros(4)
    # interface sum at the first step's start; later steps take it from _finish
    scratch[2] = float((m_frow @ eta).real) if modal else float(frow @ xi)
    ki, ci = side.ki, side.ci
    check = c.check_stability
    t_loop = _time.perf_counter()
    progress.t0 = t_loop
    try:
        for n in range(n_steps):
            t = c.start + n * H
            F_held = ext_w[0] * Fh[0] + ext_w[1] * Fh[1] + ext_w[2] * Fh[2]
            _hammer_step(hammer, t, H, F_held, n, n_grow)
            out = hammer.read()
            if modal:
                _exchange_modal(gs, order, H, m_d, m_G, eta, cbuf, m_frow, ki, ci, W, wh, Fh,
                                out[0] - x_eq, out[1], F_held, scratch)
            else:
                _exchange(gs, order, H, P, xi, buf, frow, ki, ci, W, wh, Fh, out[0] - x_eq, out[1],
                          F_held, scratch)
            F, r_step = scratch[0], scratch[1]
            res_total += r_step
            if check:
                if not (math.isfinite(F) and math.isfinite(out[0]) and math.isfinite(out[1])):
                    raise CouplingInstabilityError(
                        f"coupling unstable: non-finite interface values at t = {t + H:.6g} s "
                        f"(step {n + 1}, H = {H:g} s, k_i = {side.ki:g} N/m)",
                        time=t + H, step=n + 1, residual=math.inf, reference=E_ref)
                if abs(F - W) > F_scale:
                    raise CouplingInstabilityError(
                        f"coupling unstable: interface force {F:.4g} N left {c.blowup:g} x its scale "
                        f"at t = {t + H:.6g} s (step {n + 1}, H = {H:g} s, k_i = {side.ki:g} N/m); "
                        f"reduce H or the interface stiffness",
                        time=t + H, step=n + 1, residual=win_sum, reference=E_ref)
                win_sum += abs(r_step)
                k_in_win += 1
                if k_in_win == c.stability_window:
                    max_win = max(max_win, win_sum)
                    if win_sum > c.growth * win_prev:
                        n_grow += 1
                    else:
                        n_grow = 0
                    if win_sum > c.energy_tol * E_ref and n_grow >= c.growth_windows:
                        raise CouplingInstabilityError(
                            f"coupling unstable: interface energy residual {win_sum:.4g} J over "
                            f"{c.stability_window} steps (reference {E_ref:.4g} J) grew {n_grow} "
                            f"windows in a row, at t = {t + H:.6g} s (step {n + 1}, H = {H:g} s, "
                            f"k_i = {side.ki:g} N/m, scheme {c.scheme}, order {order}); "
                            f"reduce H or the interface stiffness",
                            time=t + H, step=n + 1, residual=win_sum, reference=E_ref)
                    win_prev = win_sum
                    win_sum, k_in_win = 0.0, 0
            if (n + 1) % c.record_every == 0:
                record(j, c.start + (n + 1) * H, out, F, F_held, r_step)
                j += 1
            if progress.enabled:
                progress.update(n + 1)
    finally:
        progress.close()
        if own:
            hammer.close()
        if modal:
            side.xi[:] = (side._V @ eta).real
            side.eta = None
    wall = _time.perf_counter() - t_loop
    stats = {"max_window_energy_residual_j": max_win, "energy_residual_total_j": res_total,
             "reference_energy_j": E_ref, "string_states": side.n}
    return CosimResult(data[:j], c, n_steps, wall, setup, float(out[2]), stats, "cosim")


# ---------------------------------------------------------------------------
# monolithic reference
# ---------------------------------------------------------------------------
def monolithic(string, config: CosimConfig = CosimConfig()) -> CosimResult:
    """The same coupled system as one hybrid system (reference solution).

    The string with the interface spring is the linear subsystem of
    :class:`hammerbit.model.stepping.Stepper` (nondimensional: lengths in
    ``x0``, velocities in ``x0 Omega``, time ``tau = Omega t``, forces in
    ``F0``), integrated by the same adaptive event-located solver as the
    hammer at ``config.rtol``.  A constant state (``z_c = 1``) carries the
    equilibrium offsets.  Samples at the communication times ``t0 + n H``;
    string-side variables that the sampler does not return
    (``string_bit_*``, ``hook_load``, ``energy_residual``, ``hammer_force``)
    are NaN, except ``hammer_force`` = ``interface_force``.
    """
    from hammerbit.model.stepping import LinearSubsystem, SolverOptions, Stepper
    c = config
    ts = _time.perf_counter()
    side = StringSide(string, c)
    rig = c.rig
    s = rig.scales
    F0, x0, Om, v0 = s.friction_force, s.length, s.omega, s.velocity
    W = side.wob
    n = side.n
    nq = n // 2
    D = np.r_[np.full(nq, x0), np.full(n - nq, v0)]
    x1eq = W / F0  # hammer position [x0] with the bit at 0: spring compressed by W/K
    # z = [xi / D, 1]
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = (side.A1 * D[None, :]) / D[:, None] / Om
    Hm = (side.E * np.array([x0, v0])[None, :]) / D[:, None] / Om
    A[:n, n] = -Hm[:, 0] * x1eq
    Hz = np.zeros((n + 1, 2))
    Hz[:n] = Hm
    G = np.zeros(n + 1)
    G[:n] = side.frow * D / F0
    G[n] = (W + side.ki * x0 * x1eq) / F0
    g = np.array([-side.ki * x0 / F0, -side.ci * v0 / F0])
    z0 = np.zeros(n + 1)
    z0[n] = 1.0
    lin = LinearSubsystem(A=A, H=Hz, G=G, g=g, z0=z0)
    grp = rig.to_groups().replace(b=0.0)
    st = Stepper(grp, solver=SolverOptions(rtol=c.rtol, atol=c.rtol * 1e-2), linear=lin,
                 y0=[x1eq, 0.0, 0.0, 0.0])
    from hammerbit.model import kernels as K
    st.fstate[K.F_T] = Om * c.start
    n_steps = c.macro_steps
    idx = np.arange(0, n_steps + 1, c.record_every)
    t_s = c.start + idx * c.step
    samples = np.zeros((len(t_s), K.N_SAMPLE_COLS))
    setup = _time.perf_counter() - ts
    t_loop = _time.perf_counter()
    st.advance(Om * (c.start + n_steps * c.step), sample_times=Om * t_s, samples=samples)
    wall = _time.perf_counter() - t_loop
    data = np.full(len(t_s), np.nan, dtype=_dtype(c.record))
    data["time"] = t_s
    x1, x2, x3, x4, fc, fl = (samples[:, i] for i in range(6))
    wob = ((x1 - x3) + 2 * grp.xi * (x2 - x4) + fc) * F0
    m = {"wob": wob, "interface_force": fl * F0, "hammer_force": fl * F0,
         "hammer_position": x1 * x0, "hammer_velocity": x2 * v0, "bit_position": x3 * x0,
         "bit_velocity": x4 * v0}
    for r in c.record:
        if r in m:
            data[r] = m[r]
    stats = {"string_states": n, "events": st.counts}
    return CosimResult(data, c, n_steps, wall, setup, float(st.y[2] * x0), stats, "monolithic")


# ---------------------------------------------------------------------------
# linear modes of the coupled system (frequency sweeps: hammerbit.studies.sweep)
# ---------------------------------------------------------------------------
ADAPTIVE_DTYPE = np.dtype([("time", "f8"), ("step_size", "f8"), ("wob", "f8"), ("interface_force", "f8"),
                           ("hammer_force", "f8"), ("hammer_position", "f8"), ("bit_position", "f8"),
                           ("force_defect", "f8")])


def _held_force(ts, Fs, t, H, order):
    """Mean over [t, t + H] of the polynomial of degree ``order`` through the
    last forces (non-uniform times): the force the hammer holds over the step."""
    k = min(order, len(ts) - 1)
    if k == 0:
        return Fs[-1]
    tt = np.asarray(ts[-(k + 1):]) - t
    c = np.polynomial.polynomial.polyfit(tt, np.asarray(Fs[-(k + 1):]), k)
    ci = np.polynomial.polynomial.polyint(c)
    return float((np.polynomial.polynomial.polyval(H, ci) - np.polynomial.polynomial.polyval(0.0, ci)) / H)


def cosimulate_adaptive(string, config: CosimConfig = CosimConfig(), *, fmu=None, tol: float = 1e-3,
                        h_min: Optional[float] = None, h_max: Optional[float] = None) -> CosimResult:
    """Co-simulation with an adaptive macro step and rollback through the FMU state.

    Scheme: Gauss–Seidel with the hammer first.  The hammer holds the mean of
    the interface force extrapolated (order ``config.extrapolation``, from the
    last accepted communication points, non-uniform in time) over the step;
    the string then follows the hammer motion interpolated linearly through
    the new value, stepped exactly.  The step's error estimate is the
    *interface force defect* ``|F_held - mean F_i|`` over the step -- the
    force the hammer saw against the force the string actually transmitted
    (its product with the hammer displacement is the power-bond energy
    residual of ECCO).  When the defect exceeds ``tol`` times the force scale
    (the WOB), both sides roll back (FMU: ``fmi2SetFMUstate``) and the step is
    halved; below ``tol / 4`` the next step doubles, within ``[h_min, h_max]``
    (powers of two of ``config.step``, so the exact string discretisations are
    reused).

    Parameters
    ----------
    string : DrillString
    config : CosimConfig
        ``step`` is the initial macro step [s].
    fmu : path, optional
        The hammer FMU (``canGetAndSetFMUstate`` is used); default the same
        kernels in process.
    tol : float
        Allowed force defect relative to the WOB [-].
    h_min, h_max : float, optional
        Step limits [s]; default ``step / 64`` and ``step * 8``.

    Returns
    -------
    CosimResult
        ``data`` has ``ADAPTIVE_DTYPE`` (time first, with the step size used and
        the force defect); ``stats`` counts accepted and rejected steps.
    """
    c = config
    H0 = c.step
    h_min = H0 / 64 if h_min is None else h_min
    h_max = H0 * 8 if h_max is None else h_max
    if not (0 < h_min <= H0 <= h_max) or not (0 < tol < 1):
        raise ValueError(f"need 0 < h_min <= step <= h_max and 0 < tol < 1; got h_min={h_min!r}, "
                         f"step={H0!r}, h_max={h_max!r}, tol={tol!r}")
    ts0 = _time.perf_counter()
    side = StringSide(string, c)
    W = side.wob
    rig = c.rig
    hammer = _hammer_side(fmu, rig, W, c)
    x_eq = hammer.x_eq
    disc = {}

    def discretisation(H):
        key = round(H / H0 * 2 ** 20)
        if key not in disc:
            side.discretise(H, modal=False)
            disc[key] = side.P
        side.P = disc[key]   # side._buf (n + 6, any H) is fully overwritten by side.step

    setup = _time.perf_counter() - ts0
    out = hammer.read()
    F = side.force(out[0] - x_eq, out[1])
    hist_t, hist_F = [c.start], [F]
    rows = [(c.start, 0.0, out[4], F, F, out[0], out[2], 0.0)]
    t = c.start
    H = H0
    accepted = rejected = 0
    at_min = 0
    t_loop = _time.perf_counter()
    try:
        while t < c.stop - 1e-12 * max(1.0, abs(c.stop)):
            H = min(H, c.stop - t)
            F_held = _held_force(hist_t, hist_F, t, H, c.extrapolation)
            snap = hammer.get_state()
            xi0 = side.xi.copy()
            x_old, v_old = out[0] - x_eq, out[1]
            hammer.step(t, H, F_held)
            new = hammer.read()
            x_new, v_new = new[0] - x_eq, new[1]
            discretisation(H)
            coeffs = np.array([x_old, v_old, (x_new - x_old) / H, (v_new - v_old) / H, 0.0, 0.0])
            impulse = side.step(coeffs)            # integral of (F_i - W) over the step
            F_mean = W + impulse / H
            defect = abs(F_held - F_mean) / max(W, 1.0)
            if not math.isfinite(defect):
                hammer.free_state(snap)
                raise CouplingInstabilityError(
                    f"coupling unstable: non-finite interface values at t = {t + H:.6g} s (H = {H:g} s)",
                    time=t + H, step=accepted + 1, residual=math.inf, reference=W)
            if defect > tol and H > h_min * (1 + 1e-12):
                hammer.set_state(snap)            # roll back both sides and halve the step
                hammer.free_state(snap)
                side.xi[:] = xi0
                rejected += 1
                H = max(H / 2, h_min)
                continue
            hammer.free_state(snap)
            if defect > tol:
                at_min += 1
            t = t + H
            accepted += 1
            out = new
            F = side.force(x_new, v_new)
            hist_t.append(t)
            hist_F.append(F)
            del hist_t[:-3], hist_F[:-3]
            rows.append((t, H, out[4], F, F_held, out[0], out[2], defect))
            if defect < 0.25 * tol:
                H = min(2 * H, h_max)
    finally:
        hammer.close()
    wall = _time.perf_counter() - t_loop
    data = np.array(rows, dtype=ADAPTIVE_DTYPE)
    steps = data["step_size"][1:]
    return CosimResult(data=data, config=c, macro_steps=accepted, wall_time_s=wall, setup_time_s=setup,
                       penetration_m=float(out[2]),
                       stats={"accepted": accepted, "rejected": rejected, "at_min_step": at_min,
                              "h_min_used": float(steps.min()) if steps.size else H0,
                              "h_max_used": float(steps.max()) if steps.size else H0, "tol": tol},
                       method="cosim-adaptive")


def _coupled_system(string, config: CosimConfig):
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
    A, n, m1, K, C = _coupled_system(string, config)
    lam = np.linalg.eigvals(A)
    f = np.abs(lam.imag[lam.imag > 0]) / (2 * math.pi)
    f = np.sort(f)
    return f[f <= f_max]


#: Frequency sweeps moved to :mod:`hammerbit.studies.sweep`; these names stay importable from here.
_MOVED_TO_STUDIES = ("SWEEP_DTYPE", "sweep", "plot_sweep", "write_sweep_csv", "wob_frf")


def __getattr__(name):
    if name in _MOVED_TO_STUDIES:
        from hammerbit.studies import sweep as _sweep_module
        return getattr(_sweep_module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
