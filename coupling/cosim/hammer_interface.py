"""What a hammer side of the co-simulation provides, and the layout of its outputs.

A hammer side (:class:`~hammerbit.cosim.hammer_inprocess.StepperHammer`,
:class:`~hammerbit.cosim.hammer_fmu.FMUHammer`, or one a user passes to
:func:`~hammerbit.cosim.master.cosimulate`) has ``step(t, H, force)``,
``read()`` (a sequence of floats, list or array, laid out by the ``OUT_*`` indexes below), ``flags()``,
``counts()``, ``get_state``/``set_state``/``free_state``, ``close()``, the
hammer's equilibrium position ``x_eq`` [m] and ``master_harmonic`` (a
:class:`~hammerbit.cosim.harmonic.MasterHarmonic` or None).
"""
from __future__ import annotations

__all__ = ["OUT_HAMMER_POSITION", "OUT_HAMMER_VELOCITY", "OUT_BIT_POSITION", "OUT_BIT_VELOCITY", "OUT_WOB",
           "flags_of", "counts_of"]

#: Indexes of a hammer side's ``read()``: hammer position [m], hammer velocity [m/s], bit position
#: [m], bit velocity [m/s], the force on the bit (the WOB) [N].
OUT_HAMMER_POSITION, OUT_HAMMER_VELOCITY, OUT_BIT_POSITION, OUT_BIT_VELOCITY, OUT_WOB = 0, 1, 2, 3, 4


def flags_of(hammer) -> tuple:
    """(stick, contact) flags of a hammer side (1.0/0.0)."""
    return hammer.flags()


def counts_of(hammer) -> dict:
    """Event counts of a hammer side (:func:`~hammerbit.cosim.config.event_counts` names); empty
    for a user's hammer side without ``counts()``."""
    counts = getattr(hammer, "counts", None)
    return counts() if counts is not None else {}
