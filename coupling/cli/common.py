"""What every ``hammerbit`` sub-command shares: the ``--set`` parser, exit codes, error handling.

Exit codes (the same for every command; ``docs/cli.md`` lists them):

====  =====================================================================
0     success
1     the run failed (solver error, FMU failure, ...)
2     bad input: an unknown or out-of-range parameter, a missing file, a path
      that cannot be written; the message names what was typed
3     the co-simulation became unstable (``CouplingInstabilityError``)
4     ``check --strict``: the hammer-frequency verdict is FAIL
5     the run finished, but its own error estimate exceeds the tolerance
130   interrupted (Ctrl-C)
====  =====================================================================

No input gives a Python traceback; set ``HAMMERBIT_DEBUG=1`` to see one.

Outputs are checked before any work (:func:`check_output`): the format
(figures: those matplotlib saves), a path that is an existing directory or
not a regular file is refused, and missing parent directories are created
(the one policy of every command), after which the file is probed for
writing.  Requests that cannot fit are refused before allocating
(:func:`check_fits`), and ``--workers`` is capped at
:data:`MAX_WORKERS_PER_CORE` times the cores (:func:`check_workers`).
"""
from __future__ import annotations

import contextlib
import os
import sys
import threading
import traceback

from hammerbit.cli.interrupt import (EXIT_INTERRUPTED, INTERRUPT_GRACE_S, Staging, interrupt_or_exit,
                                     say_interrupted, staged)

__all__ = ["EXIT_OK", "EXIT_FAILURE", "EXIT_BAD_INPUT", "EXIT_UNSTABLE", "EXIT_CHECK_FAILED",
           "EXIT_INACCURATE", "EXIT_INFEASIBLE", "EXIT_INTERRUPTED", "UsageError", "RunFailure", "parse_settings",
           "add_set_argument", "SET_HELP", "run_command", "error", "NETCDF_SUFFIXES",
           "MAX_WORKERS_PER_CORE", "MEMORY_FRACTION", "MAX_CPU_SECONDS", "max_workers", "check_workers",
           "check_output", "check_input_file", "output_errors", "available_memory", "check_fits",
           "interruptible", "human_bytes", "human_seconds", "one_blas_thread", "interrupt_or_exit",
           "INTERRUPT_GRACE_S", "staged"]

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_UNSTABLE = 3
EXIT_CHECK_FAILED = 4
EXIT_INACCURATE = 5
EXIT_INFEASIBLE = 6


class UsageError(ValueError):
    """Bad command-line input (exit code 2); the message is shown as is."""


class RunFailure(RuntimeError):
    """The run itself failed (exit code 1, or ``code``); the message is shown as is."""

    def __init__(self, message: str, code: int = EXIT_FAILURE):
        super().__init__(message)
        self.code = code


SET_HELP = ("override a parameter, NAME=VALUE (repeatable). NAME is a nondimensional group "
            "(a, b, eta, r, mu, xi, rho, gamma_hat, kc, n, lam_hat, phi), an SI symbol "
            "(m1 [kg], m2 [kg], K [N/m], C [N s/m], mu_e, mu_d, gamma [s/m], F_N [N], Kc, n, lam [s/m], "
            "R [m], B [N], A [N], f [Hz]) or an SI/FMU variable name (hammer_mass, preload, amplitude, "
            "frequency, ...)")


def add_set_argument(parser) -> None:
    """The one ``--set NAME=VALUE`` option, identical on every command."""
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help=SET_HELP)


def parse_settings(pairs) -> dict:
    """``["a=0.1", "K=4340"]`` -> ``{"a": 0.1, "K": 4340.0}`` (order kept).

    Raises :class:`UsageError` naming the item as typed.
    """
    out = {}
    for item in pairs or []:
        if "=" not in item:
            raise UsageError(f"--set expects NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        k = k.strip()
        if not k:
            raise UsageError(f"--set expects NAME=VALUE, got {item!r}")
        if k in out:
            raise UsageError(f"--set {item}: {k} is already set (--set {k}={out[k]:g}); give each name once")
        try:
            out[k] = float(v)
        except ValueError:
            raise UsageError(f"--set {k}={v}: {v!r} is not a number") from None
    return out


def error(message: str, code: int = EXIT_BAD_INPUT, *, prog: str = "hammerbit") -> int:
    """Print ``prog: error: message`` on stderr and return ``code``."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    return code


def _classify(exc: BaseException) -> int:
    """Exit code of an exception that escaped a command."""
    from hammerbit.model.solver_errors import SolverError
    from hammerbit.model.validation import ParameterError
    if isinstance(exc, (UsageError, ParameterError)):
        return EXIT_BAD_INPUT
    if isinstance(exc, RunFailure):
        return exc.code
    try:
        from hammerbit.drillstring import DrillStringError
        if isinstance(exc, DrillStringError):
            return EXIT_BAD_INPUT
    except ImportError:  # pragma: no cover
        pass
    try:
        from hammerbit.cosim.config import CouplingInstabilityError
        if isinstance(exc, CouplingInstabilityError):
            return EXIT_UNSTABLE
    except ImportError:  # pragma: no cover
        pass
    if isinstance(exc, SolverError):
        return EXIT_FAILURE
    if isinstance(exc, (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError)):
        return EXIT_BAD_INPUT
    return EXIT_FAILURE


def run_command(func, args, *, prog: str = "hammerbit", before=None, rephrase=None) -> int:
    """Run ``before(args)`` (the checks before any work), then ``func(args)``; map every exception,
    after ``rephrase(exc, args)`` (the user's words), to a one-line message and an exit code.

    Every output file the command writes through :func:`staged` is renamed onto
    its name only when ``func`` returns; a Ctrl-C before then (exit 130) or an
    error leaves no file and changes none (:mod:`hammerbit.cli.interrupt`).
    """
    guard = None
    try:
        with Staging() as outputs, interrupt_or_exit(prog=prog, always=False) as guard:
            if before is not None:
                before(args)
            code = int(func(args) or 0)
            if guard is not None:
                guard.finish()          # complete: a Ctrl-C from now on is ignored
            outputs.commit()
            return code
    except KeyboardInterrupt:
        say_interrupted(prog)
        return EXIT_INTERRUPTED
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 -- the CLI never shows a traceback
        if guard is not None and guard.pending:
            # the Ctrl-C surfaced as another error (an extension module's import it cut short)
            say_interrupted(prog)
            return EXIT_INTERRUPTED
        if rephrase is not None:
            exc = rephrase(exc, args)
        code = _classify(exc)
        if os.environ.get("HAMMERBIT_DEBUG"):
            traceback.print_exc()
        msg = str(exc) or type(exc).__name__
        if code == EXIT_FAILURE and not isinstance(exc, RunFailure):
            msg = f"{type(exc).__name__}: {msg}"
        return error(msg, code, prog=prog)


# ---------------------------------------------------------------------------
# outputs, inputs and sizes, checked before the run
# ---------------------------------------------------------------------------
#: Extensions of a netCDF file (``map --out``).
NETCDF_SUFFIXES = frozenset({"nc", "nc4", "cdf", "netcdf"})
#: ``--workers`` may be at most this many times the cores: more processes only share the same cores.
MAX_WORKERS_PER_CORE = 4
#: A request may use at most this share of the memory available when it starts.
MEMORY_FRACTION = 0.5
#: A request estimated to need more CPU time than this (one year) is refused.
MAX_CPU_SECONDS = 365.0 * 86400.0


def max_workers() -> int:
    """The largest ``--workers`` accepted: :data:`MAX_WORKERS_PER_CORE` x the cores."""
    return MAX_WORKERS_PER_CORE * (os.cpu_count() or 1)


def check_workers(value, option: str = "--workers") -> None:
    """Refuse a worker count below 1 or above :func:`max_workers` (exit 2)."""
    if value is None:
        return
    cap = max_workers()
    if not 1 <= value <= cap:
        raise UsageError(f"{option} {value}: allowed 1 to {cap} ({MAX_WORKERS_PER_CORE} x the "
                         f"{os.cpu_count() or 1} cores of this machine)")


def check_output(path, option: str, *, formats=None) -> str:
    """Refuse, before a run, an output file that cannot be written; returns its absolute path.

    The policy of every command: a path that is an existing directory, or
    exists and is not a regular file (a device, a pipe), is refused; with
    ``formats`` the extension must be one of them; missing parent directories
    are created; the file is then probed for writing (created and removed if
    it did not exist).  Errors are :class:`UsageError` naming ``option``.
    """
    text = str(path)
    if not text.strip():
        raise UsageError(f"{option}: an empty file name")
    full = os.path.abspath(os.path.expanduser(text))
    if os.path.isdir(full):
        raise UsageError(f"{option} {text}: is an existing directory; give a file name")
    if os.path.exists(full) and not os.path.isfile(full):
        raise UsageError(f"{option} {text}: exists and is not a regular file")
    if formats is not None:
        ext = os.path.splitext(full)[1].lower().lstrip(".")
        if ext not in formats:
            raise UsageError(f"{option} {text}: unsupported format {ext or '(no extension)'!r}; "
                             f"allowed: {', '.join(sorted(formats))}")
    parent = os.path.dirname(full)
    top = parent
    while not os.path.exists(top):
        top = os.path.dirname(top)
    if not os.path.isdir(top):
        raise UsageError(f"{option} {text}: {top} is a file, not a directory")
    created = parent != top
    try:
        os.makedirs(parent, exist_ok=True)
    except OSError as e:
        raise UsageError(f"{option} {text}: cannot create the directory {parent}: {e.strerror}") from None
    try:
        if os.path.exists(full):
            os.close(os.open(full, os.O_WRONLY))
        else:
            os.close(os.open(full, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            os.unlink(full)
    except OSError as e:
        if created:
            with contextlib.suppress(OSError):
                os.removedirs(parent)
        raise UsageError(f"{option} {text}: cannot write there: {e.strerror}") from None
    return full


def check_input_file(path, option: str, *, names=()) -> None:
    """Refuse an input that is a directory, or a file that is not UTF-8 text (exit 2).

    ``names`` are built-in names the option also takes (they are not files).
    """
    text = str(path)
    if text in names:
        return
    full = os.path.expanduser(text)
    if os.path.isdir(full):
        raise UsageError(f"{option} {text}: is a directory, not a file")
    if os.path.isfile(full):
        try:
            with open(full, "rb") as fh:
                data = fh.read()
        except OSError as e:
            raise UsageError(f"{option} {text}: cannot read it: {e.strerror}") from None
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as e:
            raise UsageError(f"{option} {text}: not UTF-8 text (byte 0x{data[e.start]:02x} at offset "
                             f"{e.start}); save it as UTF-8") from None


@contextlib.contextmanager
def output_errors(option: str, path):
    """Writing ``path``: an OSError becomes a :class:`UsageError` naming ``option`` (exit 2)."""
    try:
        yield
    except OSError as e:
        raise UsageError(f"{option} {path}: cannot write it: {e.strerror or e}") from None


def available_memory() -> int:
    """Bytes of memory available now (``MemAvailable``; else the physical memory)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return 1 << 34


def human_bytes(n: float) -> str:
    """``1.5 GiB``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024.0 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024.0
    return f"{n:.3g} PiB"  # pragma: no cover


def human_seconds(s: float) -> str:
    """``3.2 h``, ``41 days``."""
    if s < 120:
        return f"{s:.3g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    if s < 2 * 86400:
        return f"{s / 3600:.3g} h"
    if s < 2 * 365 * 86400:
        return f"{s / 86400:.3g} days"
    return f"{s / (365 * 86400):.3g} years"


def check_fits(what: str, *, bytes_needed: float, cpu_seconds: float, hint: str) -> None:
    """Refuse a request that needs more than :data:`MEMORY_FRACTION` of the memory available or
    more than :data:`MAX_CPU_SECONDS` of CPU (exit 2); ``what`` names the options as typed."""
    limit = MEMORY_FRACTION * available_memory()
    if bytes_needed > limit or cpu_seconds > MAX_CPU_SECONDS:
        raise UsageError(f"{what}: needs about {human_bytes(bytes_needed)} of memory and "
                         f"{human_seconds(cpu_seconds)} of CPU; the limits are {human_bytes(limit)} "
                         f"({MEMORY_FRACTION:.0%} of the memory available) and "
                         f"{human_seconds(MAX_CPU_SECONDS)}: {hint}")


def interruptible(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` in a worker thread, so that Ctrl-C interrupts at once.

    A compiled kernel holds the interpreter until it returns, and Python runs
    its SIGINT handler only then; a kernel that releases the GIL (``nogil``)
    runs in the thread while this thread waits, and a Ctrl-C raises
    ``KeyboardInterrupt`` here immediately (the process then exits; the
    daemon thread does not hold it).  The result, or the exception of ``fn``.
    """
    box = {}

    def target():
        try:
            box["value"] = fn(*args, **kwargs)
        except BaseException as e:  # noqa: BLE001 -- raised in the caller
            box["error"] = e

    th = threading.Thread(target=target, name="hammerbit-run", daemon=True)
    th.start()
    th.join()
    if "error" in box:
        raise box["error"]
    return box["value"]


def one_blas_thread(func):
    """``func`` with BLAS/LAPACK limited to one thread (:func:`hammerbit.model.string_step.one_blas_thread`).

    The eigenproblems of ``modes`` and ``check`` are small (hundreds to a few
    thousand degrees of freedom): their threads hand work over more than they
    share it, and on a busy machine each hand-over waits for a core.
    """
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from hammerbit.model.string_step import one_blas_thread as limited  # noqa: PLC0415 -- numba
        with limited():
            return func(*args, **kwargs)
    return wrapper
