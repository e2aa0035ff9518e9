"""The end of ``hammerbit cosim`` and ``cosim --ssp``: what is recorded, the CSV of ``--out``, the summary.

One piece for both faces of the co-simulation (:mod:`hammerbit.cli.cosim`,
:mod:`hammerbit.cli.ssp`), so that their outputs cannot drift apart.
"""
from __future__ import annotations

import json

from hammerbit.cli.common import staged

__all__ = ["RECORD", "NOT_IN_MONOLITHIC", "recorded", "write_and_report"]

#: What ``cosim --out`` writes besides the time (``stick`` and ``contact`` only where the hammer runs in
#: process or as this project's FMU, not through an SSP package).
RECORD = ("wob", "interface_force", "hammer_position", "hammer_velocity", "bit_position", "bit_velocity",
          "stick", "contact", "hook_load")
#: Not computed by the monolithic reference (``--monolithic``): left out of its CSV instead of a NaN column.
NOT_IN_MONOLITHIC = ("hook_load",)


def recorded(*, monolithic: bool, ssp: bool = False) -> tuple:
    """The recorded variables of a ``cosim`` run (:data:`RECORD`, less what the run cannot give)."""
    drop = (NOT_IN_MONOLITHIC if monolithic else ()) + (("stick", "contact") if ssp else ())
    return tuple(r for r in RECORD if r not in drop)


def write_and_report(res, out: dict, args, print_text) -> None:
    """The end of ``cosim`` and ``cosim --ssp``: ``meets_tolerance``, the CSV of ``--out``, then the
    summary as JSON (``--json``) or ``print_text(out)``."""
    est = res.estimate
    out["meets_tolerance"] = None if est is None else est.meets_tolerance
    if args.out:
        res.to_csv(staged(args.out))
        out["csv"] = str(args.out)
    if args.json:
        print(json.dumps(out, indent=2, default=float))
    else:
        print_text(out)
