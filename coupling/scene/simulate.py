"""One simulation request (a *scene*) of the hammer–bit–rock model.

:func:`simulate` takes the parameters, a horizon in forcing periods and a
small :class:`Record` specification, and returns a :class:`SimResult` that
holds exactly what was asked for, as numpy structured arrays with ``time``
first.  Buffers are sized for the request: a scene that wants only the
penetration allocates no trajectory.
"""
from __future__ import annotations

import math
import time as _time
import warnings
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hammerbit.model import kernel_forces, kernel_layouts
from hammerbit.model.params import Groups
from hammerbit.model.validation import ParameterError
from hammerbit.model.solver_options import SolverOptions
from hammerbit.model.stepping import EVENT_NAMES, Stepper
from hammerbit.model.validation import RANGES, check

__all__ = ["Record", "SimResult", "simulate", "BounceWarning", "POINCARE_DTYPE",
           "SAMPLE_DTYPE", "EVENT_DTYPE", "SI_SAMPLE_COLUMNS", "samples_si", "write_samples_csv"]


class BounceWarning(UserWarning):
    """The drive on the bit fell below -F_s while stuck: the rock would have to
    pull the bit back (bit bounce, outside the model).  m2 is kept stuck and the
    violation is counted, never hidden."""


POINCARE_DTYPE = np.dtype([("time", "f8"), ("hammer_position", "f8"), ("hammer_velocity", "f8"),
                           ("bit_position", "f8"), ("bit_velocity", "f8")])
SAMPLE_DTYPE = np.dtype([("time", "f8"), ("hammer_position", "f8"), ("hammer_velocity", "f8"),
                         ("bit_position", "f8"), ("bit_velocity", "f8"), ("contact_force", "f8"),
                         ("link_force", "f8"), ("slip", "i1"), ("contact", "i1")])
EVENT_DTYPE = np.dtype([("time", "f8"), ("kind", "U12"), ("hammer_position", "f8"),
                        ("hammer_velocity", "f8"), ("bit_position", "f8"), ("bit_velocity", "f8"),
                        ("relative_velocity", "f8"), ("peak_contact_force", "f8")])


@dataclass(frozen=True)
class Record:
    """What a scene wants back (everything nondimensional).

    Attributes
    ----------
    poincare : bool
        Stroboscopic samples once per forcing period.
    poincare_phase : float
        Sampling phase as a fraction of the forcing period, in [0, 1).
    times : array_like, optional
        Sorted times tau at which to sample the state densely.
    events : bool
        An event log (slip starts and stops, impacts with their relative
        velocity, separations with the peak contact force, ...).
    energy : bool
        Integrate the energy balance (external work and dissipations).
    """

    poincare: bool = False
    poincare_phase: float = 0.0
    times: Optional[np.ndarray] = None
    events: bool = False
    energy: bool = False

    def __post_init__(self):
        if not (0.0 <= self.poincare_phase < 1.0):
            raise ParameterError("poincare_phase", self.poincare_phase, "[0, 1)")
        if self.times is not None:
            t = np.asarray(self.times, dtype=float)
            if t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0) or (t.size and t[0] < 0):
                raise ParameterError("times", "array", "a 1-D sorted array of finite times >= 0")
            object.__setattr__(self, "times", t)


@dataclass
class SimResult:
    """Result of :func:`simulate`.

    Attributes
    ----------
    groups : Groups
        Parameters of the scene.
    periods : float
        Horizon in forcing periods.
    final : ndarray, shape (4,)
        Final (x1, x2, x3, x4).
    poincare, samples, events : structured ndarray or None
        Only when requested (``POINCARE_DTYPE``, ``SAMPLE_DTYPE``, ``EVENT_DTYPE``).
    counts : dict
        Event counts by kind (``slip_start``, ``stick``, ``impact``, ``bounce`` ...).
    stats : dict
        Accepted and rejected steps, right-hand-side evaluations.
    energy : dict or None
        ``work``, ``kinetic``, ``spring``, ``contact``, ``damper``, ``contact_loss``,
        ``friction`` and the residual ``balance`` of the energy equation.
    wall_time_s : float
        Solver time, excluding compilation and set-up.
    open_contact_peak : float
        Peak contact force [F0] of a contact still open at the end of the run (no separation
        logged it); 0 when the run ends out of contact.
    """

    groups: Groups
    periods: float
    final: np.ndarray
    counts: dict
    stats: dict
    wall_time_s: float
    poincare: Optional[np.ndarray] = None
    samples: Optional[np.ndarray] = None
    events: Optional[np.ndarray] = None
    energy: Optional[dict] = None
    open_contact_peak: float = 0.0

    @property
    def penetration(self) -> float:
        """Bit position x3 at the end [x0]."""
        return float(self.final[2])

    @property
    def penetration_m(self) -> float:
        """Bit position at the end [m], with the scene's own length scale x0 = F0/K."""
        return self.groups.length_m(self.penetration)

    @property
    def time_s(self) -> float:
        """Horizon [s]: ``periods`` forcing periods of the scene."""
        return self.periods * self.groups.period_s

    def rop(self, *, window: float = 0.5) -> Optional[dict]:
        """Rate of penetration over the last ``window`` of the horizon, from the Poincaré samples.

        The start-up transient is left out: the rate is the bit's advance between
        the Poincaré sample at ``(1 - window) * periods`` and the last one, divided
        by the number of forcing periods between them.

        Returns
        -------
        dict or None
            ``{"x0_per_period", "mm_per_period", "m_per_h"}`` (:meth:`Groups.rop`,
            with the scene's own scales), or None without Poincaré samples
            (``Record(poincare=True)``) or with fewer than two in the window.
        """
        if not (0.0 < window <= 1.0):
            raise ParameterError("window", window, "(0, 1]")
        p = self.poincare
        if p is None or len(p) < 2:
            return None
        k0 = min(int(math.floor(len(p) * (1.0 - window))), len(p) - 2)
        dt = (p["time"][-1] - p["time"][k0]) / self.groups.period
        if dt <= 0:
            return None
        return self.groups.rop(float((p["bit_position"][-1] - p["bit_position"][k0]) / dt))

    def peak_contact_force_n(self) -> Optional[float]:
        """Largest contact force of the run [N] (from the event log), None without ``Record(events=True)``."""
        if self.events is None:
            return None
        peaks = self.events["peak_contact_force"][self.events["kind"] == "separation"]
        # a contact that lasts to the end (a zero gap: the hammer rests on the bit) has no separation
        peak = max(float(peaks.max()) if peaks.size else 0.0, self.open_contact_peak)
        return peak * self.groups.scales.friction_force


def _energy_terms(y, ne_start, g: Groups) -> dict:
    x1, x2, x3, x4 = y[:4]
    d = x1 - x3 - g.r
    e = y[ne_start:ne_start + 4]
    contact = g.kc * d ** (g.n + 1.0) / (g.n + 1.0) if (g.has_gap and d > 0) else 0.0
    terms = {
        "work": float(e[0]),
        "kinetic": float(0.5 * x2 * x2 + 0.5 * g.rho * x4 * x4),
        "spring": float(0.5 * (x1 - x3) ** 2),
        "contact": float(contact),
        "damper": float(e[1]),
        "contact_loss": float(e[2]),
        "friction": float(e[3]),
    }
    terms["balance"] = terms["work"] - sum(terms[k] for k in ("kinetic", "spring", "contact", "damper",
                                                              "contact_loss", "friction"))
    return terms


def simulate(groups: Groups, periods: float, *, record: Record = Record(),
             solver: SolverOptions = SolverOptions(), y0=None) -> SimResult:
    """Simulate a scene of the hammer–bit–rock model from rest.

    Parameters
    ----------
    groups : Groups
        Nondimensional parameters (see :func:`hammerbit.model.presets.preset`).
    periods : float
        Horizon in forcing periods (> 0).
    record : Record
        What to return besides the final state and the counters.
    solver : SolverOptions
        Method (``adaptive``, ``dp54`` or ``rk4``) and tolerances.
    y0 : array_like, shape (4,), optional
        Initial state; zero by default.

    Returns
    -------
    SimResult

    Raises
    ------
    ParameterError
        Bad horizon or record.
    EventStormError, StepSizeError, NonFiniteStateError
        The integration could not continue; the message says where and why.
    """
    if isinstance(periods, (bool, np.bool_)):
        raise ParameterError("periods", periods, "a number in " + RANGES["simulate.periods"].text())
    periods = check("simulate.periods", periods, label="periods")
    T = groups.period
    tau_end = periods * T
    st = Stepper(groups, solver=solver, energy=record.energy, y0=y0)
    st.opts[kernel_layouts.O_POIN_T0] = record.poincare_phase * T
    poin = samp_t = samp = None
    if record.poincare:
        n_poin = int(math.floor(periods - record.poincare_phase + 1e-9)) + 1
        poin = np.zeros((n_poin, 5))
    if record.times is not None:
        samp_t = np.ascontiguousarray(record.times[record.times <= tau_end * (1 + 1e-15)])
        samp = np.zeros((samp_t.shape[0], kernel_layouts.N_SAMPLE_COLS))
    # the log starts small and doubles when full (status "log_full"), so a long run costs what it logs
    log = np.zeros((min(max(64, int(8 * periods)), 65536) if record.events else 0, kernel_layouts.N_LOG_COLS))
    st.advance(st.time, poincare=poin, sample_times=samp_t, samples=samp, log=log)  # load compiled code
    t0 = _time.perf_counter()
    while True:
        status = st.advance(tau_end, poincare=poin, sample_times=samp_t, samples=samp, log=log)
        if status != "log_full":
            break
        log = np.concatenate([log, np.zeros_like(log)])
    wall = _time.perf_counter() - t0
    counts = st.counts
    if counts["bounce"] > 0:
        warnings.warn(f"bit bounce: the drive on the bit fell below -F_s {counts['bounce']} time(s) "
                      f"(a={groups.a:g} >= b={groups.b:g}?); the bit was held stuck, outside the "
                      f"model's validity", BounceWarning, stacklevel=2)
    res = SimResult(
        groups=groups, periods=periods, final=st.y[:4].copy(), counts=counts,
        stats={"steps": int(st.istate[kernel_layouts.I_STEPS]), "rejected": int(st.istate[kernel_layouts.I_REJECTS]),
               "rhs": int(st.istate[kernel_layouts.I_RHS])},
        wall_time_s=wall,
        open_contact_peak=float(st.fstate[kernel_layouts.F_PEAK]) if counts["impact"] > counts["separation"] else 0.0,
    )
    if poin is not None:
        k = int(st.istate[kernel_layouts.I_POIN_NEXT])
        res.poincare = np.rec.fromarrays(poin[:k].T, dtype=POINCARE_DTYPE).view(np.ndarray)
    if samp is not None:
        out = np.zeros(samp_t.shape[0], dtype=SAMPLE_DTYPE)
        out["time"] = samp_t
        for i, name in enumerate(SAMPLE_DTYPE.names[1:]):
            out[name] = samp[:, i]
        res.samples = out
    if record.events:
        n = int(st.istate[kernel_layouts.I_NLOG])
        ev = np.zeros(n, dtype=EVENT_DTYPE)
        rows = log[:n]
        ev["time"] = rows[:, kernel_layouts.L_T]
        ev["kind"] = np.asarray(EVENT_NAMES)[rows[:, kernel_layouts.L_KIND].astype(int)] if n else []
        for name, col in (("hammer_position", kernel_layouts.L_X1), ("hammer_velocity", kernel_layouts.L_X2),
                          ("bit_position", kernel_layouts.L_X3), ("bit_velocity", kernel_layouts.L_X4),
                          ("relative_velocity", kernel_layouts.L_VREL), ("peak_contact_force", kernel_layouts.L_PEAK)):
            ev[name] = rows[:, col]
        res.events = ev
    if record.energy:
        res.energy = _energy_terms(st.y, 4, groups)
    return res


#: Columns of :func:`samples_si` / :func:`write_samples_csv`: (name, unit).
SI_SAMPLE_COLUMNS = (
    ("time", "s"), ("hammer_position", "mm"), ("hammer_velocity", "m/s"),
    ("bit_position", "mm"), ("bit_velocity", "m/s"), ("relative_position", "mm"),
    ("spring_damper_force", "N"), ("contact_force", "N"), ("slip", "1"), ("contact", "1"),
)


def samples_si(result: SimResult) -> np.ndarray:
    """Dense samples of a result in SI, with the scene's own scales.

    Parameters
    ----------
    result : SimResult
        A result with ``samples`` (``Record(times=...)``).

    Returns
    -------
    ndarray, shape (n, len(SI_SAMPLE_COLUMNS))
        One row per sample, columns :data:`SI_SAMPLE_COLUMNS`: time [s],
        positions [mm] (the bit position is the penetration), velocities [m/s],
        the relative position x_b - x_s [mm], the spring + damper force F_k and
        the contact force F_c on the bit [N], and the stick/slip (1 = slip) and
        contact (1 = gap closed) states.
    """
    s = result.samples
    if s is None:
        raise ParameterError("samples", None, "a result recorded with Record(times=...)")
    g = result.groups
    sc = g.scales
    p = g.to_kernel()
    y = np.empty(4)
    fk = np.empty(s.shape[0])
    for i in range(s.shape[0]):
        y[0], y[1], y[2], y[3] = (s["hammer_position"][i], s["hammer_velocity"][i],
                                  s["bit_position"][i], s["bit_velocity"][i])
        fk[i] = kernel_forces.spring_damper_force(y, p)
    mm = sc.length * 1e3
    return np.column_stack([
        s["time"] * sc.time, s["hammer_position"] * mm, s["hammer_velocity"] * sc.velocity,
        s["bit_position"] * mm, s["bit_velocity"] * sc.velocity,
        (s["hammer_position"] - s["bit_position"]) * mm,
        fk * sc.friction_force, s["contact_force"] * sc.friction_force,
        (s["slip"] == kernel_layouts.SLIP).astype(float), (s["contact"] != kernel_layouts.FREE).astype(float),
    ])


def write_samples_csv(result: SimResult, path) -> int:
    """Write :func:`samples_si` as CSV with a header of ``name [unit]``; returns the number of rows."""
    data = samples_si(result)
    header = ",".join(f"{name} [{unit}]" for name, unit in SI_SAMPLE_COLUMNS)
    fmt = ["%.9g"] * (len(SI_SAMPLE_COLUMNS) - 2) + ["%d", "%d"]
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt=fmt)
    return data.shape[0]
