"""Resumable stepping of the hybrid system: the Python side of the kernels.

:class:`Stepper` owns the solver state as plain numpy arrays (``y``,
``istate``, ``fstate``) and advances it with :func:`.kernel_driver.advance`.  The
library's ``simulate``, the FMU's ``doStep`` and the monolithic
drillstring reference all use it; only the recording buffers and the optional
linear subsystem differ.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import kernel_driver
from . import kernel_forces
from . import kernel_layouts as KL
from . import numba_compile_ahead
from . import numba_compile_lock
from .numba_compile_notice import compile_done, compile_notice, kernels_cached, notice_checked
from .params import Groups
from .solver_errors import raise_for_status
from .solver_options import SolverOptions, method_tableau
from .validation import RANGES, ParameterError, check

__all__ = ["LinearSubsystem", "Stepper", "EVENT_NAMES", "STATE_KEYS", "check_initial_state", "NO_POINCARE",
           "NO_SAMPLE_TIMES", "NO_SAMPLES", "NO_LOG"]

EVENT_NAMES = KL.EVENT_NAMES


@dataclass(frozen=True)
class LinearSubsystem:
    """A linear subsystem joined to the hammer (nondimensional).

    ``z' = A z + H[:, 0] x1 + H[:, 1] x2`` and the force on the hammer
    ``f_link = G . z + g[0] x1 + g[1] x2``, all in the hammer's scales.

    Attributes
    ----------
    A : scipy.sparse matrix or ndarray, shape (nz, nz)
    H : ndarray, shape (nz, 2)
    G : ndarray, shape (nz,)
    g : ndarray, shape (2,)
    z0 : ndarray, shape (nz,)
        Initial state.
    """

    A: object
    H: np.ndarray
    G: np.ndarray
    g: np.ndarray
    z0: np.ndarray

    def csr(self):
        """(indptr, indices, data) of A."""
        import scipy.sparse as sp
        A = sp.csr_matrix(self.A)
        A.sum_duplicates()
        return (A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data.astype(np.float64))

    @property
    def size(self) -> int:
        return int(np.asarray(self.G).shape[0])


#: RANGES keys and names of the four states of the hammer and the bit
STATE_KEYS = (("state.hammer_position", "hammer position x1"),
              ("state.hammer_velocity", "hammer velocity x2"),
              ("state.bit_position", "bit position x3"),
              ("state.bit_velocity", "bit velocity x4"))


def check_initial_state(y0, *, label: str = "y0") -> np.ndarray:
    """``y0`` as a float array of shape (4,), each state finite and in its range.

    Raises
    ------
    ParameterError
        Naming ``label[i]`` and the state, its value and the allowed range
        (positions and velocities in x0 and x0 Omega, the bit velocity >= 0).
    """
    try:
        arr = np.array(y0, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(label, y0, "4 real numbers (x1, x2, x3, x4)") from None
    if arr.shape != (4,):
        raise ParameterError(label, y0, f"4 real numbers (x1, x2, x3, x4), not an array of shape {arr.shape}")
    for i, (key, what) in enumerate(STATE_KEYS):
        check(key, arr[i], label=f"{label}[{i}] ({what})")
    return arr


def _check_finite_vector(label: str, values, n: int) -> np.ndarray:
    """A float vector of length ``n`` with finite entries (``state.subsystem``)."""
    try:
        arr = np.array(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(label, values, f"{n} real numbers") from None
    if arr.shape != (n,):
        raise ParameterError(label, values, f"{n} real numbers, not {arr.shape[0]}")
    for i in range(n):
        check("state.subsystem", arr[i], label=f"{label}[{i}]")
    return arr


_T_MAX = RANGES["state.time"].hi

_EMPTY_I = np.zeros(1, dtype=np.int64)
_EMPTY_F = np.zeros(0)
_EMPTY_H = np.zeros((0, 2))
_EMPTY_G2 = np.zeros(2)


class Stepper:
    """Resumable integrator of the hybrid hammer–bit–rock system.

    Parameters
    ----------
    groups : Groups
        Nondimensional parameters.
    solver : SolverOptions, optional
        Method and tolerances.
    linear : LinearSubsystem, optional
        A linear subsystem joined to the hammer (the monolithic reference).
    energy : bool
        Accumulate external work and dissipations as four extra states.
    y0 : array_like, shape (4,), optional
        Initial (x1, x2, x3, x4) [x0, x0 Omega]; zero by default (the
        paper's start).  Finite, within ``RANGES["state.*"]``, x4 >= 0.
    extra_force : float
        Constant extra force on the hammer / F0 (the FMU's ``harmonic_force`` input).
    compile_helper : bool
        On a first compile (a cache miss), let a second process compile part of the
        kernels (:mod:`.numba_compile_ahead`); the FMU says no (an FMI host is no
        place to start interpreters).

    Raises
    ------
    ParameterError
        A non-finite or out-of-range ``y0`` (or subsystem state), naming the
        component, its value and the allowed range.

    Notes
    -----
    The state is plain numbers: :meth:`get_state` returns a flat float64
    array that :meth:`set_state` restores exactly.
    """

    def __init__(self, groups: Groups, *, solver: SolverOptions = SolverOptions(),
                 linear: Optional[LinearSubsystem] = None, energy: bool = False,
                 y0=None, extra_force: float = 0.0, compile_helper: bool = True):
        y0 = None if y0 is None else check_initial_state(y0)
        z0 = None if linear is None else _check_finite_vector("linear.z0", linear.z0, linear.size)
        extra_force = check("state.extra_force", extra_force, label="extra_force")
        self.groups = groups
        self.solver = solver
        self.compile_helper = compile_helper
        self.p = groups.to_kernel(extra_force=extra_force)
        self._tab = method_tableau(solver.method)
        nz = 0
        if linear is not None:
            nz = linear.size
            Ap, Ai, Ax = linear.csr()
            self._lin = (Ap, Ai, Ax, np.ascontiguousarray(linear.H, dtype=np.float64).reshape(nz, 2),
                         np.ascontiguousarray(linear.G, dtype=np.float64),
                         np.ascontiguousarray(linear.g, dtype=np.float64))
        else:
            self._lin = (_EMPTY_I, _EMPTY_I[:0], _EMPTY_F, _EMPTY_H, _EMPTY_F, _EMPTY_G2)
        self.nz = nz
        self.ne = 4 if energy else 0
        # the kernel entry point: a hammer-only system runs the loop with its method bound as a constant
        self.entry = kernel_driver.HAMMER_ENTRY[solver.method] if nz == 0 and self.ne == 0 else "advance"
        n = 4 + nz + self.ne
        # y, istate and fstate are views of one buffer: snapshot() copies them in one call
        self.state_buffer = np.zeros(n + KL.N_ISTATE + KL.N_FSTATE)
        self.y = self.state_buffer[:n]
        self.istate = self.state_buffer[n:n + KL.N_ISTATE].view(np.int64)
        self.fstate = self.state_buffer[n + KL.N_ISTATE:]
        if y0 is not None:
            self.y[:4] = y0
        if z0 is not None:
            self.y[4:4 + nz] = z0
        period = groups.period
        if solver.method == "rk4":
            h0 = period / solver.steps_per_period
        else:
            h0 = min(0.01 * period, solver.max_step)
        self.fstate[KL.F_H] = h0
        self.opts = np.zeros(KL.N_OPTS)
        self.opts[KL.O_RTOL] = solver.rtol
        self.opts[KL.O_ATOL] = solver.atol
        self.opts[KL.O_HMAX] = solver.max_step
        self.opts[KL.O_HFIXED] = period / solver.steps_per_period if solver.method == "rk4" else 0.0
        self.opts[KL.O_EVCAP] = solver.max_events_per_period
        self.opts[KL.O_BISECT] = solver.bisection_tol
        self.opts[KL.O_MAXSTEPS] = solver.max_steps
        self.opts[KL.O_POIN_T0] = 0.0
        self.opts[KL.O_POIN_DT] = period
        self.opts[KL.O_GRAZE] = solver.graze_tol
        self.opts[KL.O_STEPCAP] = solver.max_steps_per_period
        self._init_modes()

    def _init_modes(self):
        """Modes consistent with the initial state (at rest: stick, free)."""
        ist, y, p = self.istate, self.y, self.p
        ist[KL.I_STICK] = KL.SLIP if y[KL.V_BIT] > 0.0 else KL.STICK
        if p[KL.P_CONTACT] > 0.0 and kernel_forces.overlap(y, p) > 0.0:
            ist[KL.I_CONTACT] = kernel_forces.contact_mode_at_impact(y, p)
        else:
            ist[KL.I_CONTACT] = KL.FREE
        ist[KL.I_WIN] = -1
        self.fstate[KL.F_DRIVE_MIN] = np.inf
        self.fstate[KL.F_T_STICK] = self.fstate[KL.F_T] if ist[KL.I_STICK] == KL.STICK else -1.0

    # ------------------------------------------------------------------
    @property
    def fast(self) -> bool:
        """The entry point is ``advance_hammer`` (DOP853, the hammer and the bit alone): the FMU's."""
        return self.entry == "advance_hammer"

    @property
    def time(self) -> float:
        """Current nondimensional time tau."""
        return float(self.fstate[KL.F_T])

    @property
    def counts(self) -> dict:
        """Event counts by kind name."""
        c = self.istate[KL.I_COUNT0:KL.I_COUNT0 + KL.N_EVENT_KINDS]
        return {name: int(c[i]) for i, name in enumerate(EVENT_NAMES)}

    def advance(self, t_end: float, *, poincare=None, sample_times=None, samples=None, log=None):
        """Advance to ``t_end`` (tau), filling the given record buffers.

        Parameters
        ----------
        t_end : float
            Final nondimensional time.
        poincare : ndarray, shape (n, 5), optional
            Poincaré rows [tau, x1, x2, x3, x4]; row k at ``opts[O_POIN_T0] + k T``.
        sample_times, samples : ndarray, shapes (m,) and (m, 8), optional
            Requested times (sorted) and their rows (``kernels.N_SAMPLE_COLS``).
        log : ndarray, shape (cap, 8), optional
            Event log; when full, :meth:`advance` returns ``'log_full'`` and a
            later call with a larger buffer continues.

        Returns
        -------
        str
            ``'done'``, or ``'log_full'`` (a later call continues).

        Raises
        ------
        ParameterError
            ``t_end`` not a finite number, before the current time or beyond
            ``RANGES["state.time"]``.
        MaxStepsError, EventStormError, StepSizeError, StepStormError, NonFiniteStateError
            The integration could not continue (the state stays where it stopped).
        """
        try:
            t_end = float(t_end)
        except (TypeError, ValueError):
            raise ParameterError("t_end", t_end, "a finite time tau") from None
        now = self.fstate[KL.F_T]
        if not (now <= t_end <= _T_MAX):  # also refuses NaN
            raise ParameterError("t_end", t_end, f"a finite time tau in [{now!r}, {_T_MAX:g}] "
                                                 f"(not before the current time)")
        poin = poincare if poincare is not None else NO_POINCARE
        st = sample_times if sample_times is not None else NO_SAMPLE_TIMES
        sa = samples if samples is not None else NO_SAMPLES
        lg = log if log is not None else NO_LOG
        if not notice_checked(self.entry) and compile_notice(self.entry):
            self._first_compile()
        return self.check_status(self._call(t_end, (poin, st, sa, lg)))

    def _call(self, t_end: float, rec) -> int:
        """The kernel entry point's call: the state advanced to ``t_end``, recording into ``rec``."""
        if self.entry == "advance":
            return self._advance_general(t_end, *rec)
        return getattr(kernel_driver, self.entry)(self.y, self.istate, self.fstate, t_end, self.p, self.opts, rec)

    def _first_compile(self) -> None:
        """Compile the entry point (a cache miss) with a call that does not move the state: under
        its compile lock, so a process that missed the cache at the same time waits and loads it,
        with a second process compiling part of it (:mod:`.numba_compile_ahead`)."""
        t0 = time.perf_counter()
        snap = self.snapshot()
        with numba_compile_lock.compiling(self.entry):
            helper = self.compile_helper and not kernels_cached(self.entry) and numba_compile_ahead.start(self.entry)
            try:
                self._call(self.fstate[KL.F_T], (NO_POINCARE, NO_SAMPLE_TIMES, NO_SAMPLES, NO_LOG))
            finally:
                self.restore(snap)
                if helper:
                    numba_compile_ahead.finish()
        compile_done(time.perf_counter() - t0)

    def load(self) -> bool:
        """Load the compiled kernel this stepper runs, if numba has it cached; True if it did.

        Nothing is compiled and the state does not change.  The first call of a
        kernel in a process pays numba's start-up and the cache load; a caller
        with other work to overlap (another process starting) pays it here.
        """
        if not kernels_cached(self.entry):
            return False
        snap = self.snapshot()
        try:
            self.advance(self.time)
        finally:
            self.restore(snap)
        return True

    def _advance_general(self, t_end, poin, st, sa, lg):
        Ap, Ai, Ax, Hz, Gz, g12 = self._lin
        return kernel_driver.advance(self.y, self.istate, self.fstate, t_end, self.p, self.opts,
                                     self._tab, (Hz.shape[0], self.ne, Ap, Ai, Ax, Hz, Gz, g12), (poin, st, sa, lg))

    def check_status(self, status: int) -> str:
        """``'done'`` or ``'log_full'`` for a kernel status, else the solver's error raised."""
        return raise_for_status(status, time=self.time, solver=self.solver, counts=lambda: self.counts)

    # ------------------------------------------------------------------
    def snapshot(self) -> bytes:
        """The integration state (y, istate, fstate) as bytes, for :meth:`restore`.

        The parameters ``p`` are not included (see :meth:`get_state` for the whole state).
        """
        return self.state_buffer.tobytes()

    def restore(self, data: bytes) -> None:
        """Put back, in place, the integration state of a :meth:`snapshot` of this stepper."""
        self.state_buffer[:] = np.frombuffer(data, dtype=np.float64)

    def get_state(self) -> np.ndarray:
        """Whole solver state as one flat float64 array (y, istate, fstate, p)."""
        return np.concatenate([self.y, self.istate.astype(np.float64), self.fstate, self.p])

    def set_state(self, s: np.ndarray) -> None:
        """Restore a state returned by :meth:`get_state` (same configuration).

        Raises
        ------
        ParameterError
            The array does not fit this stepper, or its state or time is not finite
            (nothing is changed then).
        """
        s = np.asarray(s, dtype=np.float64)
        n, ni, nf = self.y.shape[0], self.istate.shape[0], self.fstate.shape[0]
        size = n + ni + nf + self.p.shape[0]
        if s.shape != (size,):
            raise ParameterError("state", f"array of shape {s.shape}", f"a flat array of {size} numbers "
                                 f"from get_state() of the same configuration")
        if not (np.all(np.isfinite(s[:n])) and math.isfinite(s[n + ni + KL.F_T])):
            raise ParameterError("state", "non-finite entries", "finite states and time")
        self.y[:] = s[:n]
        self.istate[:] = s[n:n + ni].astype(np.int64)
        self.fstate[:] = s[n + ni:n + ni + nf]
        self.p[:] = s[n + ni + nf:]




#: Empty record buffers for a call of the kernels that records nothing: Poincaré rows, sample
#: times, samples and the event log.
NO_POINCARE = np.zeros((0, 5))
NO_SAMPLE_TIMES = np.zeros(0)
NO_SAMPLES = np.zeros((0, KL.N_SAMPLE_COLS))
NO_LOG = np.zeros((0, KL.N_LOG_COLS))
