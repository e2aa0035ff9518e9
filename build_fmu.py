#!/usr/bin/env python
"""Build ``dist/HammerBitRock.fmu`` (a thin call of ``hammerbit fmu build``).

Usage::

    python build_fmu.py [--out PATH] [--set NAME=VALUE ...]

From Python: ``build_fmu(dest_dir)`` -> ``dest_dir/HammerBitRock.fmu``; the
build itself is :func:`hammerbit.fmu.build.build_fmu`.
"""
from __future__ import annotations

import sys

from hammerbit.fmu.build import build_fmu  # noqa: F401  (re-exported for scripts and tests)


def main(argv=None) -> int:
    from hammerbit.cli.main import main as cli_main
    return cli_main(["fmu", "build", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
