"""The FMUs' causal regime verdict: the ``regime`` output's bits from the solver's state at the current time (a numba kernel).

What ``simulate`` reports once after a run (``hammerbit.scene.flags``), the FMU
reports at every communication point from what has happened so far, with the
same rules (``docs/model.md``, "Validity domain and the regime verdict"):

* bounce: a bit-bounce event has occurred (its counter is not zero);
* tension: the lowest drive on the bit so far is below zero;
* stall: the bit has stuck, without a slip, for ``STALL_PERIODS`` forcing
  periods up to now (the preload, the weight on bit, is held by the FMU's input);
* runaway: the bit slips and its state at this time passes the runaway
  certificate (:func:`hammerbit.model.regime.runaway_certified`) for the
  inputs as they are now (preload plus ``harmonic_force``, held): with them held,
  the bit can never stick again.

The verdict is a function of the solver's state and parameters only, so it is part
of the FMU state by construction: restoring a state restores it.  The native binary
calls this same kernel (``hb_regime``).
"""
from __future__ import annotations

import math

from numba import njit

from . import numba_cache  # noqa: F401  (registers the content-hash cache locator first)
from .kernel_layouts import (EV_BOUNCE, F_DRIVE_MIN, F_T, F_T_STICK, I_COUNT0, I_STICK, P_B, P_ETA, P_FEXT,
                             P_GAMMA, P_MU, SLIP, STICK)
from .regime import N_CERT, STALL_PERIODS, fill_certificate, friction_floor_of, runaway_certified
from .regime_codes import REGIME_BOUNCE, REGIME_RUNAWAY, REGIME_STALL, REGIME_TENSION

__all__ = ["causal_regime", "N_CERT"]


@njit(cache=True, _nrt=False)
def causal_regime(y, ist, fst, p, l1z, l1w, cert):
    """The regime bits (:mod:`.regime_codes`) known at the solver's current time.

    ``y``, ``ist``, ``fst``, ``p`` are the solver's state and parameters (the inputs
    applied), ``l1z, l1w`` the relative oscillator's L1 norms of the FMU's ``rho, xi``
    (:func:`hammerbit.model.regime.oscillator_l1`), ``cert`` scratch of shape ``(N_CERT,)``.
    """
    code = 0
    if ist[I_COUNT0 + EV_BOUNCE] > 0:
        code |= REGIME_BOUNCE
    if fst[F_DRIVE_MIN] < 0.0:
        code |= REGIME_TENSION
    t = fst[F_T]
    if ist[I_STICK] == STICK:
        # stuck since its last stick event (or from the start, never having slipped)
        if max(fst[F_T_STICK], 0.0) <= t - STALL_PERIODS * 2.0 * math.pi / p[P_ETA]:
            code |= REGIME_STALL
    elif ist[I_STICK] == SLIP:
        b = p[P_B] + p[P_FEXT]          # the constant drive on the hammer while the inputs are held
        if b > friction_floor_of(p[P_MU], p[P_GAMMA]):
            fill_certificate(p, b, l1z, l1w, cert)
            if runaway_certified(cert, t, y[0], y[1], y[2], y[3]):
                code |= REGIME_RUNAWAY
    return code
