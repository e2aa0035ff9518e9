"""Confirmation of an operating point by co-simulation with the drillstring, its hook on the auto-driller.

The optimizer's ROP is that of the hammer on a rigid support with a constant
preload.  On a string, the preload is the weight on bit that the string
carries: as the bit drills, the string unloads it unless the hook follows.
:func:`confirm` therefore co-simulates the point with the hook on the
auto-driller (:mod:`hammerbit.drillstring.top`), which lowers the block to
hold the static WOB (the point's preload).  It lets the controller settle
(:attr:`~hammerbit.drillstring.top.AutoDrillerGains.settling_time_s`, as the frequency sweep does) and then
measures the *sustained* ROP over whole slip cycles
(:func:`hammerbit.studies.sweep.steady_rop`), beside the dynamic WOB and the
bounce margin.
"""
from __future__ import annotations

import math
import time
from typing import Optional

from hammerbit.cosim.config import CosimConfig
from hammerbit.cosim.master import cosimulate
from hammerbit.cosim.string_side import StringSide
from hammerbit.drillstring.top import TopCondition
from hammerbit.model.params import Groups

from .sweep import steady_rop

__all__ = ["confirm", "STEPS_PER_PERIOD", "TRUNCATION_FACTOR", "STEPS_PER_TRUNCATION"]

#: Macro steps per forcing period, at least.
STEPS_PER_PERIOD = 200
#: The string is truncated above this factor times the fastest coupled motion (the hammer on
#: the interface spring) and 50 forcing frequencies.
TRUNCATION_FACTOR = 2.0
#: Macro steps per period of the truncation frequency, at least.
STEPS_PER_TRUNCATION = 20


def confirm(groups: Groups, string, *, periods: int = 20, interface_stiffness: Optional[float] = None,
            interface_damping: Optional[float] = None, fmu=None) -> dict:
    """Co-simulate an operating point on ``string`` with the auto-driller and report its sustained ROP.

    Parameters
    ----------
    groups : Groups
        The operating point (its SI rig: preload, amplitude, frequency ...).
    string : DrillString
    periods : int
        Forcing periods measured after the auto-driller has settled.
    interface_stiffness, interface_damping : float, optional
        The string-hammer interface [N/m], [N s/m] (default: the co-simulation's).
    fmu : optional
        A hammer FMU (default: the same kernels in process).

    Returns
    -------
    dict
        ``rop_m_per_h`` (sustained, over whole slip cycles after the settling),
        ``rop_steady`` and ``rop_change`` (the two halves of the measurement
        agree within 10 %), ``settle_s``, ``stop_s``, the dynamic WOB
        (``wob_mean_n``, ``wob_amplitude_n``, ``wob_min_n``), the bounce
        margin ``1 + min(WOB)/F_s``, the step and truncation, the auto-driller's
        gains and the wall time.
    """
    rig = groups.to_rig()
    T = 1.0 / rig.frequency
    kw = {}
    if interface_stiffness is not None:
        kw["interface_stiffness"] = interface_stiffness
    if interface_damping is not None:
        kw["interface_damping"] = interface_damping
    base = CosimConfig(rig=rig, wob=rig.preload, top=TopCondition.auto_driller(), **kw)
    # the hammer on the interface spring is the fastest coupled motion: the string is truncated
    # above it (and 50 x the forcing) and the step resolves the truncation
    f_i = math.sqrt((base.interface_stiffness + rig.stiffness) / rig.hammer_mass) / (2 * math.pi)
    f_max = max(TRUNCATION_FACTOR * f_i, 50.0 * rig.frequency)
    step = min(T / STEPS_PER_PERIOD, 1.0 / (STEPS_PER_TRUNCATION * f_max))
    cfg = base.replace(step=step, f_max=f_max, record=("wob", "bit_position", "stick"), progress=False,
                       estimate=False, stop=step * 2)
    side = StringSide(string, cfg)
    gains = side.gains
    settle = 0.0 if gains is None else gains.settling_time_s
    stop = settle + periods * T
    cfg = cfg.replace(stop=stop)
    t0 = time.perf_counter()
    r = cosimulate(string, cfg, fmu=fmu, side=side)
    w = r.window(settle)
    wmin = float(w["wob"].min())
    rop = steady_rop(r.data, settle)
    return {"periods": periods, "settle_s": settle, "stop_s": stop, "step_s": step, "f_max_hz": f_max,
            "top": "auto-driller", "auto_driller": None if gains is None else gains.to_dict(),
            "interface_stiffness_n_per_m": cfg.interface_stiffness,
            "hammer": "in-process" if fmu is None else "fmu",
            "wob_mean_n": r.wob_mean(settle), "wob_amplitude_n": r.wob_amplitude(settle), "wob_min_n": wmin,
            "bounce_margin": 1.0 + wmin / rig.scales.friction_force,
            "rop_m_per_h": rop["rop_m_per_h"], "rop_steady": rop["rop_steady"], "rop_change": rop["rop_change"],
            "wall_time_s": time.perf_counter() - t0}
