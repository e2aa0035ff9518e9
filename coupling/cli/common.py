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
"""
from __future__ import annotations

import os
import sys
import traceback

__all__ = ["EXIT_OK", "EXIT_FAILURE", "EXIT_BAD_INPUT", "EXIT_UNSTABLE", "EXIT_CHECK_FAILED",
           "EXIT_INACCURATE", "EXIT_INTERRUPTED", "UsageError", "RunFailure", "parse_settings",
           "add_set_argument", "SET_HELP", "run_command", "error"]

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_UNSTABLE = 3
EXIT_CHECK_FAILED = 4
EXIT_INACCURATE = 5
EXIT_INTERRUPTED = 130


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


def run_command(func, args, *, prog: str = "hammerbit") -> int:
    """Run ``func(args)``; map every exception to a one-line message and an exit code."""
    try:
        return int(func(args) or 0)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except SystemExit:
        raise
    except BaseException as exc:  # noqa: BLE001 -- the CLI never shows a traceback
        code = _classify(exc)
        if os.environ.get("HAMMERBIT_DEBUG"):
            traceback.print_exc()
        msg = str(exc) or type(exc).__name__
        if code == EXIT_FAILURE and not isinstance(exc, RunFailure):
            msg = f"{type(exc).__name__}: {msg}"
        return error(msg, code, prog=prog)
