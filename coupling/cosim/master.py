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
Over a macro step the hammer motion seen by the string is a polynomial
(degree 0, 1 or 2); the string and the interface are stepped exactly through
the matrix exponential of the string augmented by the polynomial and the
integral of the interface force (:mod:`hammerbit.cosim.string_side`), in modal
coordinates when the eigenbasis reproduces the step, else dense; one numba
kernel per step (:func:`_exchange`).  ``CosimConfig.f_max`` truncates to the
modes below ``f_max``.

Schemes
-------
* ``jacobi``: both sides step from the data at ``t_n``.  The hammer gets the
  mean over the step of the force extrapolated (order 0, 1, 2) through
  ``F(t_n), F(t_{n-1}), F(t_{n-2})`` (uniform steps: weights 1; 3/2, -1/2;
  23/12, -16/12, 5/12; any spacing: :func:`extrapolation_weights`); the
  string gets the hammer motion extrapolated from ``t_n, t_{n-1}, t_{n-2}``.
* ``gauss-seidel``: the hammer steps first (as above); the string then
  *interpolates* the hammer motion through the new value: order 0 holds the
  value at ``t_{n+1}``, order 1 is linear between ``t_n`` and ``t_{n+1}``,
  order 2 the parabola through ``t_{n-1}, t_n, t_{n+1}``.

Communication times are ``t0 + n H`` (never accumulated); a stop time that is
not a whole number of steps ends with one shorter step.  With
``adaptive=True`` the step is chosen per step (powers of two of ``step``)
from the interface force defect, with rollback of both sides (the FMU through
``fmi2SetFMUstate``).

Coupling error estimate
-----------------------
Every run (``estimate=True``) carries a companion co-simulation that takes two
half steps per macro step; the difference, scaled by the measured order, is
the a posteriori estimate of the run's error in WOB amplitude and penetration
(:mod:`hammerbit.cosim.error`).  ``CosimResult.estimate.meets_tolerance``
says whether it is within ``tol``.  ``stats`` counts the hammer's doSteps
(``hammer_steps``, rolled-back ones included), the companion's
(``companion_steps``), the state saves and the rollbacks (summed over the
passes of an adaptive run).

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
from dataclasses import fields
from pathlib import Path
from typing import Optional

import numpy as np

from hammerbit.model.params import RigParameters

from hammerbit.cosim.config import (RECORDABLE, SCHEMES, CosimConfig, CosimResult, CouplingInstabilityError, _dtype,
                           event_counts, field_hammer, steady_start)
from hammerbit.cosim.error import CouplingErrorEstimate, StepResolutionError, check_step, measured_order, richardson
from hammerbit.cosim.exchange import _exchange, _held_force, extrapolation_weights
from hammerbit.model.dispatch import entry_point
from hammerbit.cosim.string_side import StringSide, _StringState

__all__ = [
    "CosimConfig", "CosimResult", "CouplingInstabilityError", "StepResolutionError", "CouplingErrorEstimate",
    "field_hammer", "StringSide", "StepperHammer", "FMUHammer", "cosimulate", "cosimulate_adaptive",
    "monolithic", "RECORDABLE", "SCHEMES", "extrapolation_weights", "coupled_modes",
]

# ---------------------------------------------------------------------------
# hammer sides
# ---------------------------------------------------------------------------
class _MasterHarmonic:
    """The harmonic force r(t) A sin(2 pi f t + phi) computed by the master and held
    over each macro step at its mean (the exact impulse of the step; the ramp
    factor r at the step's midpoint)."""

    def __init__(self, rig: RigParameters, config: Optional[CosimConfig] = None):
        self.A = rig.amplitude
        self.w = 2.0 * math.pi * rig.frequency
        self.phi = rig.phase
        self.config = config

    def mean(self, t: float, H: float) -> float:
        w, phi = self.w, self.phi
        r = 1.0 if self.config is None else self.config.ramp_factor(t + 0.5 * H)
        return r * self.A * (math.cos(w * t + phi) - math.cos(w * (t + H) + phi)) / (w * H)


def _hammer_side(fmu, rig: RigParameters, W: float, c, instance: str = "hammer") -> object:
    """The hammer side of a run: the FMU (fmpy) or the same kernels in process.

    With a ramp the FMU's fixed amplitude cannot follow it: the master feeds the
    (ramped) harmonic force; in process the amplitude is set per step."""
    use_master = c.harmonic_source == "master" or (c.ramp > 0.0 and fmu is not None)
    master = _MasterHarmonic(rig, c) if use_master else None
    if master is not None:
        rig = rig.replace(amplitude=0.0)       # the FMU's internal source off
    if fmu is not None:
        _check_fmu_file(fmu)
        h = FMUHammer(fmu, rig, W, t0=c.start, rtol=c.rtol, instance=instance)
    else:
        h = StepperHammer(rig, W, rtol=c.rtol, t0=c.start, ramp=c if (c.ramp > 0.0 and master is None) else None)
    h.master_harmonic = master
    return h


def _check_fmu_file(path) -> None:
    """A clear error for a path that is not an FMU (before fmpy's own)."""
    import zipfile
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"fmu {str(path)!r}: no such file (build it with `hammerbit fmu build` "
                                f"or python build_fmu.py)")
    if not zipfile.is_zipfile(p):
        raise ValueError(f"fmu {str(path)!r}: not an FMU (an FMU is a zip archive with a "
                         f"modelDescription.xml)")
    with zipfile.ZipFile(p) as z:
        if "modelDescription.xml" not in z.namelist():
            raise ValueError(f"fmu {str(path)!r}: the archive has no modelDescription.xml: not an FMU")


def _hammer_flags(h) -> tuple:
    """(stick, contact) flags of a hammer side (1.0/0.0)."""
    if isinstance(h, StepperHammer):
        return h.flags()
    vr = getattr(h, "_flag_vrs", None)
    if vr is None:
        names = h.vr
        vr = h._flag_vrs = (names.get("stick_slip"), names.get("in_contact"))
    s = 0.0
    if vr[0] is not None:
        s = 1.0 if h.fmu.getInteger([vr[0]])[0] == 0 else 0.0
    ct = 0.0
    if vr[1] is not None:
        ct = 1.0 if h.fmu.getBoolean([vr[1]])[0] else 0.0
    return s, ct


def _hammer_counts(h) -> dict:
    """Event counts of a hammer side (:func:`event_counts` names)."""
    if isinstance(h, StepperHammer):
        return event_counts(h.st.counts)
    out = {}
    for key, name in (("slips", "slip_count"), ("impacts", "impact_count"),
                      ("bounce_violations", "bounce_count")):
        if name in h.vr:
            out[key] = int(h.fmu.getInteger([h.vr[name]])[0])
    return out


class StepperHammer:
    """The hammer–bit–rock model in process (the FMU's kernels, same stepper).

    Starts in static equilibrium under the WOB ``W``: hammer at ``x_h = W/K``
    (its spring compressed by ``W/K``), bit stuck at 0, both at rest.  The
    ``preload`` (interface force) is held over each step as in the FMU.
    With ``ramp`` (a :class:`CosimConfig` with ``ramp > 0``) the harmonic
    amplitude is set per step to its ramped value at the step's midpoint.
    """

    def __init__(self, rig: RigParameters, wob: float, *, rtol: float = 1e-10, t0: float = 0.0,
                 ramp: Optional[CosimConfig] = None):
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
        self._ramp = ramp
        self._a = float(g.a)

    master_harmonic = None

    def step(self, t: float, H: float, force: float) -> None:
        p = self.st.p
        p[self._K.P_B] = force / self.F0
        if self.master_harmonic is not None:
            p[self._K.P_FEXT] = self.master_harmonic.mean(t, H) / self.F0
        elif self._ramp is not None:
            p[self._K.P_A] = self._a * self._ramp.ramp_factor(t + 0.5 * H)
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
        K = self._K
        y = self.st.y
        fd = K.force_on_bit(y, self.st.p, self.st.istate[K.I_CONTACT])
        return np.array([y[0] * self.x0, y[1] * self.v0, y[2] * self.x0, y[3] * self.v0, fd * self.F0])

    def flags(self) -> tuple:
        """(stick, contact): 1.0 while the bit sticks / while the gap is closed."""
        K = self._K
        ist = self.st.istate
        return (1.0 if ist[K.I_STICK] == K.STICK else 0.0, 0.0 if ist[K.I_CONTACT] == K.FREE else 1.0)

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
        from hammerbit.fmu.host import FMUInstance
        self.path = str(path)
        self._host = FMUInstance(self.path, instance, start_time=t0, init=False)
        md, self.fmu = self._host.md, self._host.fmu
        self.md = md
        self.vr = dict(self._host.vr)
        self.causality = {v.name: v.causality for v in md.modelVariables}
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
        self.fmu.doStep(t, H)

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
            return np.array(v)               # the rock force is the WOB
        fc = v[4] if len(v) > 4 else 0.0
        wob = self._K * (v[0] - v[2]) + self._C * (v[1] - v[3]) + fc
        return np.array([v[0], v[1], v[2], v[3], wob])

    def close(self):
        self._host.close()




# ---------------------------------------------------------------------------
# progress
# ---------------------------------------------------------------------------
def _progress_bar(total: float, enabled: Optional[bool], n_steps: int):
    """A tqdm bar over simulated time [s] on stderr, or None.

    ``enabled=None``: only for runs above 20000 macro steps and when stderr is a terminal."""
    if enabled is None:
        enabled = n_steps > 20000 and sys.stderr.isatty()
    if not enabled:
        return None
    from tqdm import tqdm
    return tqdm(total=total, unit="s", desc="cosim", file=sys.stderr, leave=False,
                bar_format="{desc}: {percentage:5.1f}% |{bar}| {n:.3g}/{total:.3g} s [{elapsed}<{remaining}]")


# ---------------------------------------------------------------------------
# one co-simulation lane: a hammer side and a string state
# ---------------------------------------------------------------------------
_NONE_C = np.zeros(0, dtype=np.complex128)
_NONE_2 = np.zeros((0, 6), dtype=np.complex128)
_NONE_F = np.zeros(0)
_NONE_P = np.zeros((0, 0))
#: position of ``x_new`` in :func:`_exchange`'s arguments (then ``v_new``, ``F_held``)
_X_NEW = _exchange.py_func.__code__.co_varnames.index("x_new")


class _Lane:
    """A run of the coupled system: its hammer side, its string state, its histories.

    The run and its half-step companion are two lanes on one :class:`StringSide`.
    """

    def __init__(self, side: StringSide, hammer, config: CosimConfig, H_hist: float):
        c = config
        self.side, self.hammer, self.c = side, hammer, c
        self.gs = c.scheme == "gauss-seidel"
        self.order = c.extrapolation
        self.fmi = c.exchange == "fmi"
        self.string = _StringState(side)
        self.x_eq = hammer.x_eq
        self.out = hammer.read()
        # the exchange histories and scalars in one array (one copy per snapshot): th (3,)
        # communication times, wh (3, 2) hammer (x deviation, v), Fh (3,) interface forces,
        # sc (4,) the exchange's outputs
        self.hist = np.zeros(16)
        self.th, self.wh = self.hist[0:3], self.hist[3:9].reshape(3, 2)
        self.Fh, self.sc = self.hist[9:12], self.hist[12:16]
        self.th[:] = (c.start, c.start - H_hist, c.start - 2 * H_hist)
        self.wh[:] = (self.out[0] - self.x_eq, self.out[1])
        self.sc[2] = self.string.f_xi()
        F = side.wob + self.sc[2] - side.ki * self.wh[0, 0] - side.ci * self.wh[0, 1]
        self.sc[0] = F
        self.Fh[:] = F
        self.F_held = F
        self.w = np.zeros(3)
        self.cbuf = np.zeros(6)
        self.frow = side.m_frow if self.string.modal else side.frow.astype(np.float64)
        self._h = None                           # the last step length
        # per step length: [the exchange (its compiled entry point after the first call), its
        # arguments (_exchange_args)]; the held force's entry point after the first step
        self._calls, self._call = {}, None
        self._held = _held_force

    @property
    def F(self) -> float:
        return float(self.sc[0])

    def step(self, t: float, h: float) -> None:
        """One macro step [t, t + h]: hammer first, then the string (both schemes;
        Jacobi's string input does not use the new hammer value)."""
        F_held = self._held(self.order, self.th, self.Fh, h, self.w)
        self.F_held = F_held
        self.hammer.step(t, h, F_held)
        out = self.out = self.hammer.read()
        if h != self._h:
            self._h = h
            call = self._calls.get(h)
            if call is None:  # a new step length: its arrays, typed by the dispatcher once
                call = self._calls[h] = [_exchange, self._exchange_args(h, self.side.discretisation(h))]
            self._call = call
        call = self._call
        args = call[1]
        args[_X_NEW] = out[0] - self.x_eq
        args[_X_NEW + 1] = out[1]
        args[_X_NEW + 2] = F_held
        call[0](*args)
        if call[0] is _exchange:  # compiled by now: later steps of this length skip the type dispatch
            call[0] = entry_point(_exchange, args)
            if self._held is _held_force:
                self._held = entry_point(_held_force, (self.order, self.th, self.Fh, h, self.w))

    def _exchange_args(self, h: float, d) -> list:
        """The arguments of :func:`_exchange` for steps of length ``h`` (discretisation ``d``);
        the hammer's new position, velocity and held force (from ``_X_NEW``) are set per step."""
        s, side = self.string, self.side
        if s.modal:
            return [self.gs, self.order, h, True, _NONE_P, _NONE_F, _NONE_F, _NONE_F, d.m_d, d.m_G,
                    d.m_irow, d.m_icol, s.v, self.frow, side.ki, side.ci, side.wob,
                    self.th, self.wh, self.Fh, 0.0, 0.0, 0.0, self.cbuf, self.sc, self.fmi]
        return [self.gs, self.order, h, False, d.P, s.v, s.buf, s.tmp, _NONE_C, _NONE_2, _NONE_C,
                _NONE_F, _NONE_C, self.frow, side.ki, side.ci, side.wob,
                self.th, self.wh, self.Fh, 0.0, 0.0, 0.0, self.cbuf, self.sc, self.fmi]

    def snapshot(self):
        return self.hammer.get_state(), self.string.copy_state(), self.hist.copy(), self.out.copy()

    def restore(self, snap) -> None:
        hs, v, hist, out = snap
        self.hammer.set_state(hs)
        self.string.restore(v)
        self.hist[:] = hist
        self.out = out.copy()

    def free(self, snap) -> None:
        self.hammer.free_state(snap[0])


class _StabilityWatch:
    """The power-bond residual watch (see the module docstring)."""

    def __init__(self, c: CosimConfig, side: StringSide, t_steady: float):
        rig = c.rig
        W = side.wob
        self.c, self.ki = c, side.ki
        E_ref = W * W / (2 * side.ki) + W * W / (2 * rig.stiffness) + rig.amplitude ** 2 / rig.stiffness
        self.E_ref = max(E_ref, 1e-12)
        self.F_scale = c.blowup * (W + rig.amplitude + rig.scales.friction_force)
        self.W = W
        self.win_sum, self.win_prev, self.n_grow, self.k_in_win = 0.0, math.inf, 0, 0
        self.max_win = self.max_steady = 0.0
        self.total = 0.0
        self.t_steady = t_steady

    def hammer_failed(self, err, t, n, H, F_held):
        # the hammer side gave up; if the interface was already growing, that is the cause
        c = self.c
        if c.check_stability and (self.n_grow > 0 or abs(F_held - self.W) > 0.2 * self.F_scale
                                  or not math.isfinite(F_held)):
            raise CouplingInstabilityError(
                f"coupling unstable: the hammer side failed at t = {t:.6g} s (step {n + 1}, "
                f"H = {H:g} s, k_i = {self.ki:g} N/m) under a growing interface force "
                f"{F_held:.4g} N: {err}", time=t, step=n + 1, residual=math.nan,
                reference=self.E_ref) from err

    def update(self, t_end, n, H, F, out, r_step) -> None:
        c = self.c
        self.total += r_step
        if not c.check_stability:
            return
        if not (math.isfinite(F) and math.isfinite(out[0]) and math.isfinite(out[1])):
            raise CouplingInstabilityError(
                f"coupling unstable: non-finite interface values at t = {t_end:.6g} s "
                f"(step {n + 1}, H = {H:g} s, k_i = {self.ki:g} N/m)",
                time=t_end, step=n + 1, residual=math.inf, reference=self.E_ref)
        if abs(F - self.W) > self.F_scale:
            raise CouplingInstabilityError(
                f"coupling unstable: interface force {F:.4g} N left {c.blowup:g} x its scale "
                f"at t = {t_end:.6g} s (step {n + 1}, H = {H:g} s, k_i = {self.ki:g} N/m); "
                f"reduce H or the interface stiffness",
                time=t_end, step=n + 1, residual=self.win_sum, reference=self.E_ref)
        self.win_sum += abs(r_step)
        self.k_in_win += 1
        if self.k_in_win < c.stability_window:
            return
        w = self.win_sum
        self.max_win = max(self.max_win, w)
        if t_end >= self.t_steady + c.stability_window * H:
            self.max_steady = max(self.max_steady, w)
        self.n_grow = self.n_grow + 1 if w > c.growth * self.win_prev else 0
        if w > c.energy_tol * self.E_ref and self.n_grow >= c.growth_windows:
            raise CouplingInstabilityError(
                f"coupling unstable: interface energy residual {w:.4g} J over "
                f"{c.stability_window} steps (reference {self.E_ref:.4g} J) grew {self.n_grow} "
                f"windows in a row, at t = {t_end:.6g} s (step {n + 1}, H = {H:g} s, "
                f"k_i = {self.ki:g} N/m, scheme {c.scheme}, order {c.extrapolation}); "
                f"reduce H or the interface stiffness",
                time=t_end, step=n + 1, residual=w, reference=self.E_ref)
        self.win_prev = w
        self.win_sum, self.k_in_win = 0.0, 0

    def stats(self) -> dict:
        return {"max_window_energy_residual_j": self.max_win,
                "steady_window_energy_residual_j": self.max_steady,
                "energy_residual_total_j": self.total, "reference_energy_j": self.E_ref}


class _Recorder:
    """The recorded series (grows as needed; adaptive runs do not know their length).

    Rows go into a plain float array (one column per variable, ``time`` first), viewed as
    the structured array of :func:`_dtype` at the end; the string's outputs are read with
    one product per row."""

    #: Variables read from the lane's hammer outputs ``out`` (their index there).
    _OUT = {"wob": 4, "hammer_position": 0, "hammer_velocity": 1, "bit_position": 2, "bit_velocity": 3}
    #: Variables of :meth:`add`'s arguments (their position after ``t``).
    _ARG = {"step_size": 0, "energy_residual": 1, "force_defect": 2, "wob_error_estimate": 3}
    #: The string's outputs (row of ``_StringState.outputs``).
    _STR = {"string_bit_displacement": 0, "string_bit_velocity": 1, "hook_load": 2}

    def __init__(self, c: CosimConfig, capacity: int, lane: _Lane):
        self.names = tuple(c.record)
        self.dtype = _dtype(self.names)
        self.data = np.zeros((max(capacity, 2), 1 + len(self.names)))
        self.j = 0
        self.lane = lane
        self.need_flags = "stick" in self.names or "contact" in self.names
        self.need_string = any(n in self._STR for n in self.names)
        cols = {"out": [], "arg": [], "str": [], "flag": [], "lane": []}
        for i, n in enumerate(self.names, start=1):
            if n in self._OUT:
                cols["out"].append((i, self._OUT[n]))
            elif n in self._ARG:
                cols["arg"].append((i, self._ARG[n]))
            elif n in self._STR:
                cols["str"].append((i, self._STR[n]))
            elif n in ("stick", "contact"):
                cols["flag"].append((i, 0 if n == "stick" else 1))
            else:                                   # interface_force, hammer_force
                cols["lane"].append((i, n))
        self.cols = cols

    def add(self, t, h, r_step, defect, wob_diff) -> None:
        if self.j == len(self.data):
            self.data = np.concatenate([self.data, np.zeros_like(self.data)])
        lane = self.lane
        out = lane.out
        row = self.data[self.j]
        row[0] = t
        cols = self.cols
        for i, k in cols["out"]:
            row[i] = out[k]
        if cols["arg"]:
            args = (h, r_step, defect, wob_diff)     # wob_diff: the difference now, the factor at the end
            for i, k in cols["arg"]:
                row[i] = args[k]
        for i, n in cols["lane"]:
            row[i] = lane.sc[0] if n == "interface_force" else lane.F_held
        if self.need_flags:
            fl = _hammer_flags(lane.hammer)
            for i, k in cols["flag"]:
                row[i] = fl[k]
        if self.need_string:
            so = lane.string.outputs()
            for i, k in cols["str"]:
                row[i] = so[k]
        self.j += 1

    def result(self) -> np.ndarray:
        return np.ascontiguousarray(self.data[:self.j]).view(self.dtype).reshape(self.j)


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
        ``adaptive=False``: fixed macro step ``step`` (communication times
        ``t0 + n H``, a shorter last step to reach ``stop``).  ``adaptive=True``:
        Gauss–Seidel-or-Jacobi as configured with the step chosen per step: the
        step's interface force defect ``|F_held - mean F_i|`` (the force the
        hammer held against the force the string transmitted) is held below
        ``tol / 4`` times the WOB; above it both sides roll back (the FMU
        through ``fmi2SetFMUstate``) and the step halves, below ``tol / 16``
        the next step doubles, within ``[h_min, h_max]`` (powers of two of
        ``step``).  When the run's estimate still exceeds ``tol`` the run is
        repeated with the defect tolerance scaled down by the estimate (at most
        :data:`MAX_PASSES` passes); the result says whether the last one meets it.
    fmu : path, optional
        ``HammerBitRock.fmu``; the hammer is then the FMU (fmpy ``FMU2Slave``);
        the companion is a second instance.
    hammer : object, optional
        A ready hammer side with ``step(t, H, force)``, ``read()``, ``close()``,
        ``get_state``/``set_state``/``free_state`` and ``x_eq``; default: the FMU
        if ``fmu`` is given, else :class:`StepperHammer` (the same kernels in
        process).  The companion is built from ``fmu`` (or in process).
    side : StringSide, optional
        The string side of this string and config, reused across runs (a
        frequency sweep builds and discretises it once per worker).

    Returns
    -------
    CosimResult
        With ``estimate`` (:class:`~hammerbit.cosim.error.CouplingErrorEstimate`)
        when ``config.estimate``; it does not raise when the estimate exceeds
        ``tol`` (``result.estimate.meets_tolerance`` says so).

    Raises
    ------
    StepResolutionError
        ``check_step`` and a step that cannot resolve the forcing, the slip
        dynamics or the string modes in the exchange (before the run).
    CouplingInstabilityError
        When the interface energy residual grows (see module docstring).
    """
    c = config
    ts = _time.perf_counter()
    if side is None:
        side = StringSide(string, c)             # shared by the run, its companion and every pass
    t_side = _time.perf_counter() - ts
    if not c.adaptive:
        res = _run(side, c, fmu=fmu, hammer=hammer, defect_tol=None)
        res.setup_time_s += t_side
        return res
    defect_tol = DEFECT_TOL_FACTOR * c.tol
    res = _run(side, c, fmu=fmu, hammer=hammer, defect_tol=defect_tol)
    setup = res.setup_time_s + t_side
    passes, wall = 1, res.wall_time_s
    total = {k: res.stats[k] for k in _SUMMED}
    while (res.estimate is not None and not res.estimate.meets_tolerance and math.isfinite(res.estimate.worst)
           and hammer is None and passes < MAX_PASSES):
        # the global error grows at least linearly with the defect tolerance
        defect_tol *= max(min(0.5 * c.tol / res.estimate.worst, 0.5), 1e-2)
        res = _run(side, c, fmu=fmu, hammer=None, defect_tol=defect_tol)
        setup += res.setup_time_s
        passes += 1
        wall += res.wall_time_s
        for k in _SUMMED:
            total[k] += res.stats[k]
    res.stats.update(passes=passes, **total)
    res.wall_time_s = wall
    res.setup_time_s = setup
    return res


#: Per-step force-defect tolerance of the adaptive step, relative to the WOB, per unit of ``tol``
#: (the first pass; a second pass tightens it when the run's estimate exceeds ``tol``).
DEFECT_TOL_FACTOR = 1.0 / 40.0
#: Counts summed over the passes of an adaptive run.
_SUMMED = ("rejected", "rollbacks", "hammer_steps", "companion_steps", "state_saves")
#: Passes of the adaptive run at most (each tightens the defect tolerance by the estimate).
MAX_PASSES = 3


def cosimulate_adaptive(string, config: CosimConfig = CosimConfig(), *, fmu=None, tol: Optional[float] = None,
                        h_min: Optional[float] = None, h_max: Optional[float] = None) -> CosimResult:
    """:func:`cosimulate` with ``adaptive=True`` (and ``tol``, ``h_min``, ``h_max`` if given)."""
    ch = {"adaptive": True}
    for k, v in (("tol", tol), ("h_min", h_min), ("h_max", h_max)):
        if v is not None:
            ch[k] = v
    return cosimulate(string, config.replace(**ch), fmu=fmu)


def _run(side: StringSide, c: CosimConfig, *, fmu, hammer, defect_tol) -> CosimResult:
    ts = _time.perf_counter()
    if c.check_step:
        H_chk = c.step_range[1] if c.adaptive else min(c.step, c.stop - c.start)
        if c.adaptive:
            # the adaptive step never grows past what resolves the system
            from hammerbit.cosim.error import step_limits
            H_chk = min(H_chk, min(lim.max_step_s for lim in step_limits(side, c)))
            c = c.replace(h_max=max(min(c.step_range[1], H_chk), c.step_range[0]))
            check_step(side, c, c.step)
        else:
            check_step(side, c, H_chk)
    W = side.wob
    own = hammer is None
    if hammer is None:
        hammer = _hammer_side(fmu, c.rig, W, c, instance="hammer")
    lanes = [hammer]
    try:
        comp = _hammer_side(fmu, c.rig, W, c, instance="companion") if c.estimate else None
        if comp is not None:
            lanes.append(comp)
        H = c.step
        if comp is not None:
            side.discretisation(0.5 * H)        # first: the run's step is then its square
        if c.adaptive:
            # every power of two the run and its half-step companion may take, before the loop,
            # smallest first: one expm, the rest squares (set-up time)
            h_lo, h_hi = c.step_range
            h = 0.5 * h_lo
            while h <= h_hi * (1 + 1e-12):
                side.discretisation(h)
                h *= 2.0
        side.discretisation(H)
        main = _Lane(side, hammer, c, H)
        fine = _Lane(side, comp, c, 0.5 * H) if comp is not None else None
        n_full, rem = c.whole_steps
        n_est = n_full + 1 if not c.adaptive else int((c.stop - c.start) / H) + 1
        rec = _Recorder(c, n_est // c.record_every + 2, main)
        watch = _StabilityWatch(c, side, steady_start(c))
        setup = _time.perf_counter() - ts
        t_loop = _time.perf_counter()
        bar = _progress_bar(c.stop - c.start, c.progress, n_est)
        wob_m, wob_f, t_all = [main.out[4]], [fine.out[4] if fine is not None else 0.0], [c.start]
        rec.add(c.start, 0.0, 0.0, 0.0, 0.0)
        d_main, d_fine = [], []
        accepted = rejected = at_min = 0
        steps = csteps = saves = 0               # doSteps of the run (rolled back included), companion's
        h_used = (math.inf, 0.0)
        h_lo, h_hi = c.step_range
        t = c.start
        n = 0
        unit = h_lo / 2.0                   # adaptive times: t0 + k * unit (exact)
        k_t = 0
        # loop invariants, read once
        adaptive, start, stop, record_every = c.adaptive, c.start, c.stop, c.record_every
        at_stop = stop - 1e-12 * max(1.0, abs(stop))
        n_steps = n_full + (1 if rem > 0.0 else 0)
        update = watch.update
        try:
            while True:
                if adaptive:
                    if t >= at_stop:
                        break
                    h, last = _adaptive_step(H, stop - t, unit)
                else:
                    if n >= n_steps:
                        break
                    h = H if n < n_full else rem
                    t = start + n * H
                    last = True
                snap = main.snapshot() if defect_tol is not None else None
                saves += snap is not None
                steps += 1
                try:
                    main.step(t, h)
                except CouplingInstabilityError:
                    raise
                except Exception as err:
                    watch.hammer_failed(err, t, n, h, main.F_held)
                    raise
                defect = float(main.sc[3])
                if defect_tol is not None:
                    rel = abs(defect) / max(W, 1.0)
                    if not math.isfinite(rel):
                        main.free(snap)
                        raise CouplingInstabilityError(
                            f"coupling unstable: non-finite interface values at t = {t + h:.6g} s "
                            f"(H = {h:g} s)", time=t + h, step=n + 1, residual=math.inf, reference=W)
                    if rel > defect_tol and h > h_lo * (1 + 1e-12) and not last:
                        main.restore(snap)
                        main.free(snap)
                        rejected += 1
                        H = max(H / 2, h_lo)
                        continue
                    main.free(snap)
                    if rel > defect_tol:
                        at_min += 1
                t_end = stop if (adaptive and last) else (
                    start + (k_t + int(round(h / unit))) * unit if adaptive else
                    (start + (n + 1) * H if n < n_full else stop))
                if adaptive:
                    k_t += int(round(h / unit))
                if fine is not None:
                    fine.step(t, 0.5 * h)
                    d_fine.append(float(fine.sc[3]))
                    fine.step(t + 0.5 * h, t_end - (t + 0.5 * h))
                    d_fine.append(float(fine.sc[3]))
                    csteps += 2
                    wob_f.append(fine.out[4])
                    d_main.append(defect)           # the histories the estimate reads
                    wob_m.append(main.out[4])
                    t_all.append(t_end)
                update(t_end, n, h, main.F, main.out, float(main.sc[1]))
                n += 1
                accepted += 1
                if (n % record_every == 0) or t_end >= at_stop:
                    rec.add(t_end, h, float(main.sc[1]), defect,
                            main.out[4] - fine.out[4] if fine is not None else math.nan)
                if bar is not None:
                    bar.update(t_end - t)
                t = t_end
                if adaptive:
                    h_used = (min(h_used[0], h), max(h_used[1], h)) if not last or h == H else h_used
                    if abs(defect) / max(W, 1.0) < 0.1 * defect_tol:
                        H = min(2 * H, h_hi)
        finally:
            if bar is not None:
                bar.close()
        wall = _time.perf_counter() - t_loop
        counts = _hammer_counts(hammer)
        pen = float(main.out[2])
        data = rec.result()
        est = None
        if fine is not None:
            # both amplitudes on the run's communication points in the steady window
            sel = np.asarray(t_all) >= steady_start(c) - 1e-12
            amp = 0.5 * float(np.ptp(np.asarray(wob_m)[sel]))
            amp_f = 0.5 * float(np.ptp(np.asarray(wob_f)[sel]))
            p = measured_order(np.asarray(d_main), np.asarray(d_fine))
            est = richardson(amplitude=amp, amplitude_fine=amp_f,
                             penetration=pen, penetration_fine=float(fine.out[2]), order=p, tol=c.tol,
                             length_scale=c.rig.scales.length)
            if "wob_error_estimate" in data.dtype.names:
                data["wob_error_estimate"] *= est.factor
        stats = watch.stats()
        stats["string_states"] = side.n
        stats["modal"] = bool(side.modal)
        stats.update({"hammer_steps": steps, "companion_steps": csteps, "rollbacks": rejected,
                      "state_saves": saves})
        if c.adaptive:
            stats.update({"accepted": accepted, "rejected": rejected, "at_min_step": at_min,
                          "defect_tol": defect_tol, "passes": 1, "tol": c.tol,
                          "h_min_used": h_used[0], "h_max_used": h_used[1]})
        return CosimResult(data, c, accepted, wall, setup, pen, stats,
                           "cosim-adaptive" if c.adaptive else "cosim", counts=counts, estimate=est)
    finally:
        if own:
            hammer.close()
        if len(lanes) > 1:
            lanes[1].close()


def _adaptive_step(H: float, remaining: float, unit: float) -> tuple:
    """``(h, last)``: the adaptive step ``H``, or near the end the longest power of two of
    ``unit`` within the remaining time (its exact step is a square of a cached one, no new
    ``expm``), and the remaining time itself when less than one ``unit`` is left."""
    if remaining >= H:
        return H, abs(remaining - H) <= 1e-9 * unit
    k = int(math.floor(remaining / unit * (1.0 + 1e-12)))
    if k < 1:
        return remaining, True
    h = unit * 2.0 ** int(math.floor(math.log2(k)))
    if abs(remaining - h) <= 1e-9 * unit:
        return remaining, True
    return h, False


def monolithic(string, config: CosimConfig = CosimConfig()) -> CosimResult:
    """The same coupled system as one hybrid system (reference); see
    :func:`hammerbit.cosim.reference.monolithic`."""
    from hammerbit.cosim.reference import monolithic as _mono
    return _mono(string, config)


# ---------------------------------------------------------------------------
# linear modes of the coupled system (frequency sweeps: hammerbit.studies.sweep)
# ---------------------------------------------------------------------------
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
