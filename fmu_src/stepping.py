"""Resumable stepping of the hybrid system: the Python side of the kernels.

:class:`Stepper` owns the solver state as plain numpy arrays (``y``,
``istate``, ``fstate``) and advances it with :func:`kernels.advance`.  The
library's ``simulate``, the FMU's ``doStep`` and the monolithic
drillstring reference all use it; only the recording buffers and the optional
linear subsystem differ.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import _numba_cache
from . import compile_ahead
from . import kernels as K
from . import tableaux as T
from .params import Groups, ParameterError
from .validation import RANGES, check

__all__ = [
    "SolverOptions", "LinearSubsystem", "Stepper", "SolverError", "EventStormError",
    "StepSizeError", "NonFiniteStateError", "MaxStepsError", "StepStormError", "EVENT_NAMES",
    "method_tableau",
]

EVENT_NAMES = K.EVENT_NAMES


class SolverError(RuntimeError):
    """The integration could not continue.

    Attributes
    ----------
    time : float
        Nondimensional time tau where it stopped.
    status : int
        Kernel status code.
    """

    def __init__(self, message: str, *, time: float, status: int):
        self.time = time
        self.status = status
        super().__init__(message)


class EventStormError(SolverError):
    """More events in one forcing period than ``max_events_per_period`` allows."""


class StepSizeError(SolverError):
    """The adaptive step fell below the floating-point resolution of t."""


class NonFiniteStateError(SolverError):
    """The state became NaN or infinite."""


class MaxStepsError(SolverError):
    """More steps than ``max_steps`` in one call."""


class StepStormError(SolverError):
    """More accepted steps in one forcing period than ``max_steps_per_period``: the
    solver crawls (a stiff or nearly singular regime) instead of hanging."""


METHODS = ("adaptive", "dp54", "rk4")


def method_tableau(name: str):
    """Tableau arrays of a method name: (A, B, C, E, E3, W, ns, err_kind, err_exp) (``tableaux.METHODS``)."""
    key = "dop853" if name == "adaptive" else name
    if key not in T.METHODS:
        raise ParameterError("method", name, "one of " + ", ".join(METHODS))
    return T.METHODS[key]


@dataclass(frozen=True)
class SolverOptions:
    """Options of the hybrid integrators.

    Attributes
    ----------
    method : {'adaptive', 'dp54', 'rk4'}
        ``adaptive``: DOP853 with 7th-order dense output, events located on the
        dense output to a few ulp.  ``dp54``: Dormand–Prince 5(4), same event
        logic.  ``rk4``: the paper's fixed-step RK4 with bisection.
    rtol, atol : float
        Tolerances of the adaptive methods [-].
    steps_per_period : int
        rk4: N in dtau = 2 pi / (N eta) (the paper: 1000).
    bisection_tol : float
        rk4: event-time tolerance of the bisection in tau (the paper: 1e-6).
    max_events_per_period : int
        Events allowed in one forcing period before :class:`EventStormError`.
    max_step : float
        Largest step in tau (inf: no limit).
    graze_tol : float
        A grazing extremum of an indicator counts as an event above this value.
    max_steps : int
        Accepted steps allowed in one call (0: no limit).
    max_steps_per_period : int
        Accepted steps allowed in one forcing period before :class:`StepStormError`
        (0: no limit): a crawling solver fails loudly instead of hanging.
    """

    method: str = "adaptive"
    rtol: float = 1e-8
    atol: float = 1e-10
    steps_per_period: int = 1000
    bisection_tol: float = 1e-6
    max_events_per_period: int = 2000
    max_step: float = math.inf
    graze_tol: float = 1e-13
    max_steps: int = 0
    max_steps_per_period: int = 100_000

    def __post_init__(self):
        if self.method not in METHODS:
            raise ParameterError("method", self.method, "one of " + ", ".join(METHODS))
        check("solver.rtol", self.rtol, label="rtol")
        check("solver.atol", self.atol, label="atol")
        check("solver.steps_per_period", self.steps_per_period, label="steps_per_period")
        check("solver.bisection_tol", self.bisection_tol, label="bisection_tol")
        check("solver.max_events_per_period", self.max_events_per_period, label="max_events_per_period")
        check("solver.max_step", self.max_step, label="max_step")
        check("solver.graze_tol", self.graze_tol, label="graze_tol")
        check("solver.max_steps", self.max_steps, label="max_steps")
        check("solver.max_steps_per_period", self.max_steps_per_period, label="max_steps_per_period")


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
                 y0=None, extra_force: float = 0.0):
        y0 = None if y0 is None else check_initial_state(y0)
        z0 = None if linear is None else _check_finite_vector("linear.z0", linear.z0, linear.size)
        extra_force = check("state.extra_force", extra_force, label="extra_force")
        self.groups = groups
        self.solver = solver
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
        self._fast = solver.method == "adaptive" and nz == 0 and self.ne == 0
        self._entry = "advance_hammer" if self._fast else "advance"
        n = 4 + nz + self.ne
        # y, istate and fstate are views of one buffer: snapshot() copies them in one call
        self.state_buffer = np.zeros(n + K.N_ISTATE + K.N_FSTATE)
        self.y = self.state_buffer[:n]
        self.istate = self.state_buffer[n:n + K.N_ISTATE].view(np.int64)
        self.fstate = self.state_buffer[n + K.N_ISTATE:]
        if y0 is not None:
            self.y[:4] = y0
        if z0 is not None:
            self.y[4:4 + nz] = z0
        period = groups.period
        if solver.method == "rk4":
            h0 = period / solver.steps_per_period
        else:
            h0 = min(0.01 * period, solver.max_step)
        self.fstate[K.F_H] = h0
        self.opts = np.zeros(K.N_OPTS)
        self.opts[K.O_RTOL] = solver.rtol
        self.opts[K.O_ATOL] = solver.atol
        self.opts[K.O_HMAX] = solver.max_step
        self.opts[K.O_HFIXED] = period / solver.steps_per_period if solver.method == "rk4" else 0.0
        self.opts[K.O_EVCAP] = solver.max_events_per_period
        self.opts[K.O_BISECT] = solver.bisection_tol
        self.opts[K.O_MAXSTEPS] = solver.max_steps
        self.opts[K.O_POIN_T0] = 0.0
        self.opts[K.O_POIN_DT] = period
        self.opts[K.O_GRAZE] = solver.graze_tol
        self.opts[K.O_STEPCAP] = solver.max_steps_per_period
        self._init_modes()

    def _init_modes(self):
        """Modes consistent with the initial state (at rest: stick, free)."""
        ist, y, p = self.istate, self.y, self.p
        ist[K.I_STICK] = K.SLIP if y[K.V_BIT] > 0.0 else K.STICK
        if p[K.P_CONTACT] > 0.0 and K.overlap(y, p) > 0.0:
            ist[K.I_CONTACT] = K.contact_mode_at_impact(y, p)
        else:
            ist[K.I_CONTACT] = K.FREE
        ist[K.I_WIN] = -1

    # ------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Current nondimensional time tau."""
        return float(self.fstate[K.F_T])

    @property
    def counts(self) -> dict:
        """Event counts by kind name."""
        c = self.istate[K.I_COUNT0:K.I_COUNT0 + K.N_EVENT_KINDS]
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
        now = self.fstate[K.F_T]
        if not (now <= t_end <= _T_MAX):  # also refuses NaN
            raise ParameterError("t_end", t_end, f"a finite time tau in [{now!r}, {_T_MAX:g}] "
                                                 f"(not before the current time)")
        poin = poincare if poincare is not None else _NO_POIN
        st = sample_times if sample_times is not None else _EMPTY_F
        sa = samples if samples is not None else _NO_SAMP
        lg = log if log is not None else _NO_LOG
        notice = self._entry not in _NOTICE_CHECKED and compile_notice(self._entry)
        helper = notice and compile_ahead.start(self._entry)  # a second process compiles part of it
        t0 = time.perf_counter()
        if self._fast:
            status = K.advance_hammer(self.y, self.istate, self.fstate, t_end, self.p, self.opts,
                                      poin, st, sa, lg)
        else:
            status = self._advance_general(t_end, poin, st, sa, lg)
        if helper:
            compile_ahead.finish()
        if notice:
            compile_done(time.perf_counter() - t0)
        return self._status(status)

    def load(self) -> bool:
        """Load the compiled kernel this stepper runs, if numba has it cached; True if it did.

        Nothing is compiled and the state does not change.  The first call of a
        kernel in a process pays numba's start-up and the cache load; a caller
        with other work to overlap (another process starting) pays it here.
        """
        if not kernels_cached(self._entry):
            return False
        snap = self.snapshot()
        try:
            self.advance(self.time)
        finally:
            self.restore(snap)
        return True

    def _advance_general(self, t_end, poin, st, sa, lg):
        A, B, C, E, E3, W, ns, ek, ee = self._tab
        Ap, Ai, Ax, Hz, Gz, g12 = self._lin
        return K.advance(self.y, self.istate, self.fstate, t_end, self.p, self.opts,
                         A, B, C, E, E3, W, ns, ek, ee, Ap, Ai, Ax, Hz, Gz, g12, self.ne,
                         poin, st, sa, lg)

    def _status(self, status):
        if status == K.ST_DONE:
            return "done"
        if status == K.ST_LOG_FULL:
            return "log_full"
        t = self.time
        if status == K.ST_MAX_STEPS:
            raise MaxStepsError(f"more than max_steps={self.solver.max_steps} steps in one call; stopped "
                                f"at tau = {t:.9g}", time=t, status=status)
        if status == K.ST_EVENT_STORM:
            raise EventStormError(
                f"event storm: more than {self.solver.max_events_per_period} events in the forcing "
                f"period around tau = {t:.9g} (counts {self.counts}); raise max_events_per_period "
                f"or check the parameters (e.g. a chattering contact or a force at the friction threshold)",
                time=t, status=status)
        if status == K.ST_STEP_TOO_SMALL:
            raise StepSizeError(f"step size fell below the resolution of t at tau = {t:.9g} "
                                f"(rtol={self.solver.rtol:g}); the problem is too stiff for these "
                                f"tolerances", time=t, status=status)
        if status == K.ST_STEP_STORM:
            raise StepStormError(
                f"step storm: more than {self.solver.max_steps_per_period} accepted steps in the "
                f"forcing period around tau = {t:.9g} (rtol={self.solver.rtol:g}); the regime is too "
                f"stiff for these tolerances, or raise max_steps_per_period", time=t, status=status)
        if status == K.ST_NONFINITE:
            raise NonFiniteStateError(f"state became non-finite at tau = {t:.9g}", time=t, status=status)
        if status == K.ST_BAD_INPUT:
            raise SolverError(f"the kernel refused its input at tau = {t:.9g}: a non-finite state or "
                              f"end time, or an end time before the current time", time=t, status=status)
        raise SolverError(f"solver stopped with status {status} at tau = {t:.9g}", time=t, status=status)

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
        if not (np.all(np.isfinite(s[:n])) and math.isfinite(s[n + ni + K.F_T])):
            raise ParameterError("state", "non-finite entries", "finite states and time")
        self.y[:] = s[:n]
        self.istate[:] = s[n:n + ni].astype(np.int64)
        self.fstate[:] = s[n + ni:n + ni + nf]
        self.p[:] = s[n + ni + nf:]


_NOTICE_CHECKED = set()


def kernels_cached(entry: str) -> bool:
    """True if numba will load the kernel entry point ``entry`` from its cache.

    Reads numba's cache index of the entry point (a small pickle; numba itself
    reads it on the first call): an entry for this machine's code generator
    and the current source means no compile.  Unknown (numba internals changed):
    True, so no notice is shown rather than a wrong one.
    """
    disp = getattr(K, entry)
    try:
        if disp.signatures:
            return True
        cache = disp._cache
        index = cache._cache_file._load_index()
        magic = disp.targetctx.codegen().magic_tuple()
        return any(key[1] == magic for key in index)
    except Exception:  # pragma: no cover - numba internals
        return True


def compile_notice(entry: str, stream=None) -> bool:
    """Say once per process on stderr that ``entry`` is about to compile (a cache miss).

    Returns True if the notice was printed.
    """
    if entry in _NOTICE_CHECKED:
        return False
    _NOTICE_CHECKED.add(entry)
    if kernels_cached(entry):
        return False
    stream = sys.stderr if stream is None else stream
    # no duration is promised: it ranges from seconds to minutes with the machine and its load;
    # compile_done says how long it took
    print(f"hammerbit: compiling the solver kernels for this machine (once; cached in "
          f"{_numba_cache.cache_root()})", file=stream, flush=True)
    return True


def compile_done(seconds: float, stream=None) -> None:
    """Say on stderr how long the compile that :func:`compile_notice` announced took."""
    stream = sys.stderr if stream is None else stream
    print(f"hammerbit: compiled the solver kernels in {seconds:.1f} s", file=stream, flush=True)


_NO_POIN = np.zeros((0, 5))
_NO_SAMP = np.zeros((0, K.N_SAMPLE_COLS))
_NO_LOG = np.zeros((0, K.N_LOG_COLS))
