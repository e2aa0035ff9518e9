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
  process, :class:`~hammerbit.cosim.hammer_inprocess.StepperHammer`): input ``preload`` = ``F_i`` (held
  constant over a macro step, FMI 2.0 co-simulation); outputs hammer and bit
  position and velocity.

Exact string step
-----------------
Over a macro step the hammer motion seen by the string is a polynomial
(degree 0, 1 or 2); the string and the interface are stepped exactly through
the matrix exponential of the string augmented by the polynomial and the
integral of the interface force (:mod:`hammerbit.cosim.string_side`), in modal
coordinates when the eigenbasis reproduces the step, else dense; one numba
kernel per step (:func:`~hammerbit.cosim.exchange.exchange_step`).  ``CosimConfig.f_max`` truncates to the
modes below ``f_max``.

Schemes
-------
* ``jacobi``: both sides step from the data at ``t_n``.  The hammer gets the
  mean over the step of the force extrapolated (order 0, 1, 2) through
  ``F(t_n), F(t_{n-1}), F(t_{n-2})`` (uniform steps: weights 1; 3/2, -1/2;
  23/12, -16/12, 5/12; any spacing: :func:`~hammerbit.cosim.exchange.extrapolation_weights`); the
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
not finite, :class:`~hammerbit.cosim.config.CouplingInstabilityError` is raised
(:mod:`hammerbit.cosim.stability`).

Field hammer
------------
:func:`~hammerbit.cosim.config.field_hammer` scales the rig of the paper to field size keeping all
dimensionless groups; see its docstring.
"""
from __future__ import annotations

import math
import sys
import time as _time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hammerbit.cosim.config import CosimConfig, CosimResult, CouplingInstabilityError, steady_start
from hammerbit.cosim.error import (check_step, measured_order, phase_dominated, richardson, step_limits, unclaimed,
                                   SAFETY_FACTOR)
from hammerbit.cosim.hammer_interface import OUT_BIT_POSITION, OUT_WOB, counts_of
from hammerbit.cosim.hammers import hammer_side
from hammerbit.cosim.lane import Lane
from hammerbit.cosim.recorder import Recorder
from hammerbit.cosim.stability import StabilityWatch
from hammerbit.cosim.string_side import StringSide

__all__ = ["cosimulate", "cosimulate_adaptive", "DEFECT_TOL_FACTOR", "MAX_PASSES"]


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
        if ``fmu`` is given, else :class:`~hammerbit.cosim.hammer_inprocess.StepperHammer` (the same kernels in
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
        return _claim(res)
    defect_tol = DEFECT_TOL_FACTOR * c.tol
    res = _run(side, c, fmu=fmu, hammer=hammer, defect_tol=defect_tol)
    setup = res.setup_time_s + t_side
    passes, wall = 1, res.wall_time_s
    total = {k: res.stats[k] for k in _SUMMED}
    while (res.estimate is not None and res.estimate.claimed and not res.estimate.meets_tolerance
           and math.isfinite(res.estimate.worst)
           and hammer is None and passes < MAX_PASSES):
        # the global error grows at least linearly with the defect tolerance
        defect_tol *= max(min(0.5 * c.tol / SAFETY_FACTOR / res.estimate.worst, 0.5), 1e-2)
        res = _run(side, c, fmu=fmu, hammer=None, defect_tol=defect_tol)
        setup += res.setup_time_s
        passes += 1
        wall += res.wall_time_s
        for k in _SUMMED:
            total[k] += res.stats[k]
    res.stats.update(passes=passes, **total)
    res.wall_time_s = wall
    res.setup_time_s = setup
    return _claim(res)


def _claim(res: CosimResult) -> CosimResult:
    """``res`` with its estimate unclaimed where step doubling cannot estimate the amplitude's error
    (:func:`~hammerbit.cosim.error.phase_dominated`)."""
    note = phase_dominated(res.estimate) if res.estimate is not None else ""
    if note:
        res.estimate = unclaimed(res.estimate, note)
    return res


#: Per-step force-defect tolerance of the adaptive step, relative to the WOB, per unit of ``tol``
#: (the first pass; a second pass tightens it when the run's estimate exceeds ``tol``).
DEFECT_TOL_FACTOR = 1.0 / 40.0
#: The adaptive run's first step is its nominal step divided by this (at least ``h_min``).
ADAPTIVE_START_DIVISOR = 16.0
#: Counts summed over the passes of an adaptive run.
_SUMMED = ("rejected", "rollbacks", "hammer_steps", "companion_steps", "state_saves")
#: Passes of the adaptive run at most (each tightens the defect tolerance by the estimate).
MAX_PASSES = 4


def cosimulate_adaptive(string, config: CosimConfig = CosimConfig(), *, fmu=None, tol: Optional[float] = None,
                        h_min: Optional[float] = None, h_max: Optional[float] = None) -> CosimResult:
    """:func:`cosimulate` with ``adaptive=True`` (and ``tol``, ``h_min``, ``h_max`` if given)."""
    ch = {"adaptive": True}
    for k, v in (("tol", tol), ("h_min", h_min), ("h_max", h_max)):
        if v is not None:
            ch[k] = v
    return cosimulate(string, config.replace(**ch), fmu=fmu)


@dataclass
class _Marched:
    """What the macro-step loop of :func:`_run` counted, and the histories the estimate reads."""

    accepted: int = 0
    rejected: int = 0                 # rollbacks
    at_min: int = 0                   # steps accepted at the smallest step above the defect tolerance
    steps: int = 0                    # doSteps of the run, rolled back included
    csteps: int = 0                   # the companion's doSteps
    saves: int = 0                    # state saves
    h_used: tuple = (math.inf, 0.0)   # smallest and largest adaptive step taken
    d_main: list = field(default_factory=list)
    d_fine: list = field(default_factory=list)


def _checked_steps(side: StringSide, c: CosimConfig) -> CosimConfig:
    """``c`` with an adaptive run's step range cut to what resolves the system, after the check
    that the step resolves it (``check_step``; raises otherwise)."""
    if not c.check_step:
        return c
    H_chk = c.step_range[1] if c.adaptive else min(c.step, c.stop - c.start)
    if not c.adaptive:
        check_step(side, c, H_chk)
        return c
    # the adaptive step never grows past what resolves the system
    H_chk = min(H_chk, min(lim.max_step_s for lim in step_limits(side, c)))
    lo = c.step_range[0]
    if H_chk < c.step:
        # a first step the system cannot take: start at the largest one it can
        lo = min(lo, H_chk / 64.0)
        c = c.replace(step=H_chk)
    c = c.replace(h_min=lo, h_max=max(min(c.step_range[1], H_chk), lo))
    check_step(side, c, c.step)
    return c


def _discretise(side: StringSide, c: CosimConfig, companion: bool) -> None:
    """Compute the exact string steps the run may take before its loop (set-up time)."""
    H = c.step
    if companion:
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


def _run(side: StringSide, c: CosimConfig, *, fmu, hammer, defect_tol) -> CosimResult:
    ts = _time.perf_counter()
    c = _checked_steps(side, c)
    own = hammer is None
    if hammer is None:
        hammer = hammer_side(fmu, c.rig, side.wob, c, instance="hammer")
    lanes = [hammer]
    try:
        comp = hammer_side(fmu, c.rig, side.wob, c, instance="companion") if c.estimate else None
        if comp is not None:
            lanes.append(comp)
        _discretise(side, c, comp is not None)
        H = c.step
        main = Lane(side, hammer, c, H)
        fine = Lane(side, comp, c, 0.5 * H) if comp is not None else None
        n_full, _ = c.whole_steps
        n_est = n_full + 1 if not c.adaptive else int((c.stop - c.start) / H) + 1
        if c.adaptive:
            # the start-up (the force switched on, histories without a past) in short steps; the
            # step then doubles as the defect allows
            H = max(c.step_range[0], c.step / ADAPTIVE_START_DIVISOR)
        rec = Recorder(c, n_est // c.record_every + 2, main)
        watch = StabilityWatch(c, side, steady_start(c))
        main.load_kernels(H)
        setup = _time.perf_counter() - ts
        t_loop = _time.perf_counter()
        bar = _progress_bar(c.stop - c.start, c.progress, n_est)
        try:
            m = _march(c, (main, fine), (rec, watch, bar), H, side.wob, defect_tol)
        finally:
            if bar is not None:
                bar.close()
        wall = _time.perf_counter() - t_loop
        counts = counts_of(hammer)
        pen = float(main.out[OUT_BIT_POSITION])
        data = rec.result()
        est = _estimate(c, (main, fine), m, pen, counts, data) if fine is not None else None
        return CosimResult(data, c, m.accepted, wall, setup, pen, _stats(side, c, watch, m, defect_tol),
                           "cosim-adaptive" if c.adaptive else "cosim", counts=counts, estimate=est,
                           steps=main.steps)
    finally:
        if own:
            hammer.close()
        if len(lanes) > 1:
            lanes[1].close()


def _march(c: CosimConfig, lanes: tuple, watchers: tuple, H: float, W: float, defect_tol) -> _Marched:
    """The macro steps of a run from ``c.start`` to ``c.stop``: the lanes ``(main, fine or
    None)`` stepped, recorded and watched (``watchers = (recorder, stability watch, progress bar
    or None)``), from the first step ``H``; an adaptive run (``defect_tol``) rolls back a step whose
    interface force defect exceeds ``defect_tol`` times the WOB ``W``."""
    main, fine = lanes
    rec, watch, bar = watchers
    m = _Marched()
    d_main, d_fine = m.d_main, m.d_fine
    rec.add(c.start, 0.0, 0.0, 0.0, 0.0)
    accepted = rejected = at_min = 0
    steps = csteps = saves = 0               # doSteps of the run (rolled back included), companion's
    h_used = (math.inf, 0.0)
    h_lo, h_hi = c.step_range
    t = c.start
    n = 0
    unit = h_lo / 2.0                   # adaptive times: t0 + k * unit (exact)
    k_t = 0
    # loop invariants, read once
    n_full, rem = c.whole_steps
    adaptive, start, stop, record_every = c.adaptive, c.start, c.stop, c.record_every
    at_stop = stop - 1e-12 * max(1.0, abs(stop))
    n_steps = n_full + (1 if rem > 0.0 else 0)
    update = watch.update
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
        defect = main.defect
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
            d_fine.append(fine.defect)
            fine.step(t + 0.5 * h, t_end - (t + 0.5 * h))
            d_fine.append(fine.defect)
            csteps += 2
            d_main.append(defect)           # the history the estimate reads
        update(t_end, n, h, main.F, main.out, main.residual)
        n += 1
        accepted += 1
        if (n % record_every == 0) or t_end >= at_stop:
            rec.add(t_end, h, main.residual, defect,
                    main.out[OUT_WOB] - fine.out[OUT_WOB] if fine is not None else math.nan)
        if bar is not None:
            bar.update(t_end - t)
        t = t_end
        if adaptive:
            h_used = (min(h_used[0], h), max(h_used[1], h)) if not last or h == H else h_used
            if abs(defect) / max(W, 1.0) < 0.1 * defect_tol:
                H = min(2 * H, h_hi)
    m.accepted, m.rejected, m.at_min, m.steps, m.csteps, m.saves, m.h_used = (accepted, rejected, at_min, steps,
                                                                               csteps, saves, h_used)
    return m


def _estimate(c: CosimConfig, lanes, m: _Marched, pen: float, counts: dict, data):
    """The run's error estimate from the lanes ``(main, fine)``, ``fine`` the half-step companion
    (scales the recorded ``wob_error_estimate`` in ``data`` by the estimate's factor)."""
    main, fine = lanes
    # each lane's amplitude from the WOB within its own steps
    t0 = steady_start(c)
    amp, amp_f = main.wob_amplitude(t0), fine.wob_amplitude(t0)
    p = measured_order(np.asarray(m.d_main), np.asarray(m.d_fine))
    est = richardson(amplitude=amp, amplitude_fine=amp_f, penetration=pen,
                     penetration_fine=float(fine.out[OUT_BIT_POSITION]), order=p, tol=c.tol,
                     length_scale=c.rig.scales.length, harmonic=main.wob_phasor(t0),
                     harmonic_fine=fine.wob_phasor(t0))
    if counts.get("impacts", 0) > 0:
        est = unclaimed(est, f"{counts['impacts']} impacts: step doubling does not resolve the "
                             f"contact spikes, so no tolerance is claimed for this run")
    if "wob_error_estimate" in data.dtype.names:
        data["wob_error_estimate"] *= est.factor
    return est


def _stats(side: StringSide, c: CosimConfig, watch: StabilityWatch, m: _Marched, defect_tol) -> dict:
    """The run's ``stats``: the stability watch's, the string's and the step counts."""
    stats = watch.stats()
    stats["string_states"] = side.n
    stats["modal"] = bool(side.modal)
    if side.gains is not None:
        stats["auto_driller"] = side.gains.to_dict()
    stats.update({"hammer_steps": m.steps, "companion_steps": m.csteps, "rollbacks": m.rejected,
                  "state_saves": m.saves})
    if c.adaptive:
        stats.update({"accepted": m.accepted, "rejected": m.rejected, "at_min_step": m.at_min,
                      "defect_tol": defect_tol, "passes": 1, "tol": c.tol,
                      "h_min_used": m.h_used[0], "h_max_used": m.h_used[1]})
    return stats


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
