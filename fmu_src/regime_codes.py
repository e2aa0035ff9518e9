"""The codes of the regime verdict: one bit per way a run leaves ordinary drilling (FMU ``regime``, JSON).

One verdict serves every face (simulate, the studies, the co-simulation, the FMUs): it is an
integer whose bits say which of these hold at the current time.  Plain integers, so that numba
kernels and the generated C read the same numbers; :data:`REGIME_BITS` names them for people.
"""
from __future__ import annotations

__all__ = ["REGIME_RUNAWAY", "REGIME_BOUNCE", "REGIME_TENSION", "REGIME_STALL", "REGIME_TRANSIENT",
           "REGIME_BITS", "regime_names", "regime_json"]

#: the bit cannot stick again: the drive beats the friction at every phase, the drift accelerates
REGIME_RUNAWAY = 1
#: the bit leaves the rock (the drive on it falls below the rock's reaction)
REGIME_BOUNCE = 2
#: the drive on the bit turns tensile (negative) at some phase
REGIME_TENSION = 4
#: the bit no longer slips although the weight on it is held
REGIME_STALL = 8
#: the motion has not settled within the horizon seen so far
REGIME_TRANSIENT = 16

#: name of each bit, in bit order
REGIME_BITS = {"runaway": REGIME_RUNAWAY, "bounce": REGIME_BOUNCE, "tension": REGIME_TENSION,
               "stall": REGIME_STALL, "transient": REGIME_TRANSIENT}


def regime_names(code: int) -> list:
    """The names of the bits set in ``code``, in bit order."""
    return [name for name, bit in REGIME_BITS.items() if int(code) & bit]


def regime_json(code: int) -> dict:
    """The verdict in JSON: ``{"regime": code, "regime_names": [...]}`` (every face writes it so)."""
    return {"regime": int(code), "regime_names": regime_names(code)}
