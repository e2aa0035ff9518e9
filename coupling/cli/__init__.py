"""The ``hammerbit`` command line: one module per command group, the shared parser in :mod:`.common`.

* :mod:`.main` -- the parser, the entry point and ``simulate``;
* :mod:`.string` -- ``modes`` and ``check``;
* :mod:`.cosim` -- ``cosim``;
* :mod:`.studies` -- ``bifurcation``, ``sweep``, ``map``, ``optimize``;
* :mod:`.fmu` -- ``fmu build``;
* :mod:`.interrupt` -- Ctrl-C and the staged output files.

Importing this package imports nothing else: the executable's first statement
is :func:`console`, which makes a Ctrl-C during the imports that follow end the
process with one line and exit code 130.
"""

import os
import signal
import sys

__all__ = ["build_parser", "console"]


def _interrupted_early(signum, frame) -> None:
    print("hammerbit: interrupted", file=sys.stderr, flush=True)
    os._exit(130)


def console(argv=None) -> None:
    """The ``hammerbit`` executable (:func:`hammerbit.cli.main.console`)."""
    # first, before any import: nothing is written or started yet, so a Ctrl-C just ends the process
    signal.signal(signal.SIGINT, _interrupted_early)
    from hammerbit.cli.main import console as run
    run(argv)


def build_parser():
    """The ``hammerbit`` parser (:func:`hammerbit.cli.main.build_parser`)."""
    from hammerbit.cli.main import build_parser as build
    return build()
