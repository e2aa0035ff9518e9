"""The ``hammerbit`` command line: one module per command group, the shared parser in :mod:`.common`.

* :mod:`.main` -- the parser, the entry point and ``simulate``;
* :mod:`.string` -- ``modes`` and ``check``;
* :mod:`.cosim` -- ``cosim``;
* :mod:`.studies` -- ``bifurcation``, ``sweep``, ``map``, ``optimize``;
* :mod:`.fmu` -- ``fmu build``.
"""
from hammerbit.cli.main import build_parser, console

__all__ = ["build_parser", "console"]
