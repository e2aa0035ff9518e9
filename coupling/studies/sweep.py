"""Frequency sweeps of the co-simulated hammer on a drillstring.

One co-simulation (:func:`hammerbit.cosim.master.cosimulate`) per excitation
frequency, on the study executor.  Each worker process discretises the
string once (the exact step's matrix exponential and modal form do not
depend on the hammer frequency) and reuses it for every frequency it runs.

Steady state is detected, not assumed: the WOB amplitude is measured over
the last two windows of ``window_periods`` forcing periods; when they differ
by more than ``steady_tol`` (relative) the run is repeated with twice the
duration, up to ``max_duration``.  The figures come from those two windows,
and rows that never settle are flagged ``steady = 0``.  The ROP is taken over
whole slip cycles, two windows of :data:`ROP_SLIPS` slips each, and must
agree between them within :data:`ROP_TOL` too (:func:`steady_rop`): slips come
every few forcing periods, so a window of a few periods can hold none.
"""
from __future__ import annotations

import copy
import hashlib
import math
import pickle
from pathlib import Path
from typing import Optional

import numpy as np

from hammerbit.model.validation import ParameterError

from hammerbit.model.regime_codes import REGIME_TRANSIENT

from hammerbit.cosim.config import CosimConfig, cosim_regime
from hammerbit.cosim.linear_modes import coupled_system
from hammerbit.cosim.amplitude import fundamental
from hammerbit.cosim.master import cosimulate
from hammerbit.cosim.string_side import StringSide
from .executor import Executor, ExecutorOptions

__all__ = ["SWEEP_DTYPE", "sweep", "plot_sweep", "write_sweep_csv", "wob_frf", "steady_figures", "steady_rop",
           "ROP_SLIPS", "ROP_TOL"]

SWEEP_DTYPE = np.dtype([("frequency_hz", "f8"), ("wob_mean_n", "f8"), ("wob_amplitude_n", "f8"),
                        ("wob_min_n", "f8"), ("bounce_margin", "f8"), ("rop_m_per_h", "f8"),
                        ("penetration_m", "f8"), ("duration_s", "f8"), ("amplitude_change", "f8"),
                        ("steady", "i1"), ("regime", "i2")])


# one discretised string side per worker process, keyed by what it depends on
_SIDES: dict = {}


def _side_key(string, config: CosimConfig) -> str:
    c = config.replace(rig=config.rig.replace(frequency=1.0), stop=config.start + 1.0)
    return hashlib.sha1(pickle.dumps((string, c))).hexdigest()


def _side_for(string, config: CosimConfig, fmu=None) -> StringSide:
    """A copy of this worker's discretised string side.

    The template is warmed by a one-step run, so it holds the discretisations
    a run computes, in the order it computes them; every frequency gets its own
    copy, so a result does not depend on which frequencies the worker ran
    before (the same bits whatever the chunking).  The one step runs in
    process, except in a process on the FMU's portable CPU target
    (:mod:`hammerbit.model.numba_target`, ``sweep --fmu``), where it runs
    through ``fmu``: there the in-process kernels are not compiled, while
    elsewhere they are loaded already (:func:`~hammerbit.studies.executor.warm_worker`)
    and a second FMU instance would only cost its start-up.
    """
    from hammerbit.model.numba_target import runs_portable
    key = _side_key(string, config)
    side = _SIDES.get(key)
    if side is None:
        _SIDES.clear()
        side = StringSide(string, config)
        cosimulate(string, config.replace(stop=config.start + config.step, record=("wob",)), side=side,
                   fmu=fmu if runs_portable() else None)
        _SIDES[key] = side
    return copy.deepcopy(side)


def steady_figures(data: np.ndarray, frequency: float, window_periods: int, friction_force: float) -> dict:
    """Figures of the last two windows of ``window_periods`` forcing periods each.

    ``data`` has ``time``, ``wob`` and ``bit_position`` (SI).  Returns the WOB
    mean, amplitude (the fundamental harmonic at the forcing frequency,
    :func:`hammerbit.cosim.amplitude.fundamental`) and minimum over both windows, the bounce
    margin ``1 + min(WOB)/F_s``, the ROP [m/h] and ``amplitude_change``, the
    relative change of the amplitude from the earlier window to the later.
    """
    t = data["time"]
    tw = window_periods / frequency
    t_end = t[-1]
    last = t >= t_end - tw - 1e-12
    prev = (t >= t_end - 2 * tw - 1e-12) & (t <= t_end - tw + 1e-12)
    both = last | prev
    w = data["wob"]

    def amp(m):
        tm = t[m]
        return fundamental(tm, w[m], frequency, float(tm[0]))[0]

    a_last, a_prev = amp(last), amp(prev)
    change = abs(a_last - a_prev) / max(a_last, a_prev, 1e-9 * max(abs(w[both]).max(), 1.0))
    tb, xb = t[both], data["bit_position"][both]
    wmin = float(w[both].min())
    return {"wob_mean_n": float(w[both].mean()), "wob_amplitude_n": amp(both), "wob_min_n": wmin,
            "bounce_margin": 1.0 + wmin / friction_force,
            "rop_m_per_h": float((xb[-1] - xb[0]) / (tb[-1] - tb[0]) * 3600.0),
            "amplitude_change": change}


#: Slip cycles in each of the two windows the ROP is measured and compared over.
ROP_SLIPS = 5
#: Allowed relative change of the ROP between those two windows.
ROP_TOL = 0.1


def steady_rop(data: np.ndarray, t_from: float, slips: int = ROP_SLIPS) -> dict:
    """The ROP over whole slip cycles, and whether it is steady.

    ``data`` has ``time``, ``bit_position`` and ``stick``.  The bit advances in
    slips, every few forcing periods, so the ROP is taken between slip starts:
    over the last ``2 slips`` slip cycles after ``t_from`` [s], and compared
    between the earlier and the later ``slips`` cycles.  No slip in the later
    half of the run: ROP 0, steady (the bit is stuck).  Returns
    ``rop_m_per_h``, ``rop_change`` (relative) and ``rop_steady``.
    """
    t, x, st = data["time"], data["bit_position"], data["stick"]
    starts = np.flatnonzero((st[:-1] > 0.5) & (st[1:] < 0.5)) + 1
    starts = starts[t[starts] >= t_from]
    t_half = 0.5 * (t[0] + t[-1])
    if starts.size == 0 or t[starts[-1]] < t_half:
        return {"rop_m_per_h": 0.0, "rop_change": 0.0, "rop_steady": True}
    if starts.size < 2 * slips + 1:
        i0 = starts[0]
        rop = (x[starts[-1]] - x[i0]) / max(t[starts[-1]] - t[i0], 1e-300) if starts.size > 1 else 0.0
        return {"rop_m_per_h": float(rop * 3600.0), "rop_change": 1.0, "rop_steady": False}
    a, m, b = starts[-2 * slips - 1], starts[-slips - 1], starts[-1]
    r1 = (x[m] - x[a]) / (t[m] - t[a])
    r2 = (x[b] - x[m]) / (t[b] - t[m])
    change = abs(r2 - r1) / max(abs(r1), abs(r2), 1e-300)
    return {"rop_m_per_h": float((x[b] - x[a]) / (t[b] - t[a]) * 3600.0), "rop_change": float(change),
            "rop_steady": bool(change <= ROP_TOL)}


def _settling_time(side) -> float:
    """Time [s] the top condition needs to settle: 0 for a fixed hook or a feed."""
    return 0.0 if side.gains is None else side.gains.settling_time_s


def _sweep_one(string, f, config, fmu, window_periods, steady_tol, max_duration):
    rig = config.rig.replace(frequency=float(f))
    # at least three windows after the force ramp
    dur = max(config.stop - config.start, config.ramp + 3.0 * window_periods / f)
    F_s = config.rig.scales.friction_force
    while True:
        cfg = config.replace(rig=rig, stop=config.start + dur, record=("wob", "bit_position", "stick"),
                             record_every=1, progress=False)
        side = _side_for(string, cfg, fmu)
        settle = _settling_time(side)
        if dur < settle + 3.0 * window_periods / f and dur < max_duration:
            # an auto-driller settles over several of its time constants: measure after them
            dur = min(max_duration, settle + 3.0 * window_periods / f)
            continue
        r = cosimulate(string, cfg, fmu=fmu, side=side)
        fig = steady_figures(r.data, f, window_periods, F_s)
        rop = steady_rop(r.data, config.start + max(config.ramp + window_periods / f, settle))
        fig["rop_m_per_h"] = rop["rop_m_per_h"]
        steady = fig["amplitude_change"] <= steady_tol and rop["rop_steady"]
        if steady or 2 * dur > max_duration + 1e-12:
            break
        dur *= 2
    code = cosim_regime(r)["code"] | (0 if steady else REGIME_TRANSIENT)
    return (f, fig["wob_mean_n"], fig["wob_amplitude_n"], fig["wob_min_n"], fig["bounce_margin"],
            fig["rop_m_per_h"], r.penetration_m, dur, fig["amplitude_change"], int(steady), code)


def _sweep_chunk(freqs, string, config, fmu, window_periods, steady_tol, max_duration):
    return [_sweep_one(string, f, config, fmu, window_periods, steady_tol, max_duration) for f in freqs]


def sweep(string, frequencies, config: CosimConfig = CosimConfig(), *, fmu=None, window_periods: int = 5,
          steady_tol: float = 0.01, max_duration: Optional[float] = None,
          executor: Optional[Executor] = None,
          options: ExecutorOptions = ExecutorOptions(workers=1)) -> np.ndarray:
    """Frequency sweep of the hammer excitation (one co-simulation per frequency).

    For each frequency ``f`` the hammer's harmonic source runs at ``f`` from
    the static equilibrium for ``config.stop - config.start`` seconds (at
    least three windows), doubled up to ``max_duration`` until the WOB
    amplitude settles (see the module docstring).  Over the last two windows:

    * ``wob_amplitude_n``: dynamic WOB amplitude at the bit, (max - min)/2 [N];
    * ``bounce_margin``: ``1 + min(WOB)/F_s`` with ``F_s = mu_e F_N`` the static
      friction threshold; <= 0 means bit bounce (the rock would have to pull
      the bit back);
    * ``rop_m_per_h``: rate of penetration [m/h];
    * ``duration_s``, ``amplitude_change``, ``steady``: the simulated time
      used, the relative amplitude change between the two windows and whether
      it is within ``steady_tol``;
    * ``regime``: the co-simulation's verdict
      (:func:`hammerbit.cosim.config.cosim_regime`), with ``transient`` also
      set where ``steady`` is 0.

    Parameters
    ----------
    string : DrillString
    frequencies : array_like
        Excitation frequencies [Hz].
    config : CosimConfig
        Co-simulation options; its rig's frequency is replaced.
    fmu : path, optional
        The hammer FMU (default: the same kernels in process).
    window_periods : int
        Forcing periods per window.
    steady_tol : float
        Allowed relative change of the amplitude between the two windows.
    max_duration : float, optional
        Longest simulated time per frequency [s]; default the initial duration
        (no repetition: unsettled rows are only flagged).
    executor, options
        Where the frequencies run (default: in this process).

    Returns
    -------
    ndarray
        :data:`SWEEP_DTYPE`, one row per frequency.
    """
    freqs = np.atleast_1d(np.asarray(frequencies, dtype=float))
    if freqs.ndim != 1 or freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs <= 0):
        raise ParameterError("frequencies", frequencies, "a non-empty list of frequencies > 0 Hz")
    if not (isinstance(window_periods, (int, np.integer)) and window_periods >= 1):
        raise ParameterError("window_periods", window_periods, "an integer >= 1")
    if not 0 < steady_tol < 1:
        raise ParameterError("steady_tol", steady_tol, "(0, 1)")
    dur0 = config.stop - config.start
    max_duration = dur0 if max_duration is None else float(max_duration)
    if not max_duration >= dur0:
        raise ParameterError("max_duration", max_duration, f">= the initial duration {dur0:g} s")
    fmu = None if fmu is None else str(fmu)
    own = executor is None
    ex = Executor(options) if own else executor
    try:
        rows = ex.run(_sweep_chunk, list(freqs), fixed=(string, config, fmu, int(window_periods),
                                                        float(steady_tol), max_duration),
                      cost_s=1.0, label="sweep")
    finally:
        if own:
            ex.close()
    return np.array(rows, dtype=SWEEP_DTYPE)


def plot_sweep(result: np.ndarray, path, *, modes: Optional[np.ndarray] = None, title: str = "") -> Path:
    """Sweep figure: WOB amplitude, bounce margin and ROP against frequency,
    with the coupled natural frequencies (bit on bottom) as vertical lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    f = result["frequency_hz"]
    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    ax[0].plot(f, result["wob_amplitude_n"] / 1e3, ".-")
    if "steady" in result.dtype.names and np.any(result["steady"] == 0):
        un = result["steady"] == 0
        ax[0].plot(f[un], result["wob_amplitude_n"][un] / 1e3, "rx", label="not settled")
        ax[0].legend()
    ax[0].set_ylabel("dynamic WOB amplitude [kN]")
    ax[1].plot(f, result["bounce_margin"], ".-")
    ax[1].axhline(0.0, color="r", lw=0.8)
    ax[1].set_ylabel("bounce margin [-]")
    ax[2].plot(f, result["rop_m_per_h"], ".-")
    ax[2].set_ylabel("ROP [m/h]")
    ax[2].set_xlabel("hammer excitation frequency [Hz]")
    if modes is not None:
        for a in ax:
            for fm in modes:
                if f.min() <= fm <= f.max():
                    a.axvline(fm, color="0.6", lw=0.6, ls="--")
    if title:
        ax[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_sweep_csv(result: np.ndarray, path) -> Path:
    """CSV of a sweep (header = field names)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.column_stack([result[n] for n in result.dtype.names]), delimiter=",",
               header=",".join(result.dtype.names), comments="", fmt="%.10g")
    return path


def wob_frf(string, frequencies, config: CosimConfig = CosimConfig()) -> np.ndarray:
    """Linear frequency response of the WOB at the bit per newton of hammer force
    (bit stuck, the system of :func:`hammerbit.cosim.linear_modes.coupled_modes`), complex (F,) [N/N].

    With a small harmonic amplitude the bit stays stuck, the coupled system is
    linear and :func:`sweep`'s ``wob_amplitude_n`` equals ``A |frf|``; its peaks
    are at :func:`hammerbit.cosim.linear_modes.coupled_modes`.
    """
    A, n, m1, K, C = coupled_system(string, config)
    b = np.zeros(n + 2)
    b[n + 1] = 1.0 / m1
    out = []
    I = np.eye(n + 2)
    for f in np.atleast_1d(np.asarray(frequencies, dtype=float)):
        x = np.linalg.solve(2j * math.pi * f * I - A, b)
        out.append(K * x[n] + C * x[n + 1])
    return np.array(out)
