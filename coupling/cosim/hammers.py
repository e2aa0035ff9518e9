"""The choice of a run's hammer side: the FMU through fmpy, or the same kernels in process."""
from __future__ import annotations

from hammerbit.model.params import RigParameters

from hammerbit.cosim.config import CosimConfig
from hammerbit.cosim.hammer_fmu import FMUHammer, check_fmu_file
from hammerbit.cosim.hammer_inprocess import StepperHammer
from hammerbit.cosim.harmonic import MasterHarmonic

__all__ = ["hammer_side"]


def hammer_side(fmu, rig: RigParameters, W: float, c: CosimConfig, instance: str = "hammer") -> object:
    """The hammer side of a run: the FMU (fmpy) or the same kernels in process.

    With a ramp the FMU's fixed amplitude cannot follow it: the master feeds the
    (ramped) harmonic force; in process the amplitude is set per step."""
    use_master = c.harmonic_source == "master" or (c.ramp > 0.0 and fmu is not None)
    master = MasterHarmonic(rig, c) if use_master else None
    if master is not None:
        rig = rig.replace(amplitude=0.0)       # the FMU's internal source off
    if fmu is not None:
        check_fmu_file(fmu)
        h = FMUHammer(fmu, rig, W, t0=c.start, rtol=c.rtol, instance=instance)
    else:
        h = StepperHammer(rig, W, rtol=c.rtol, t0=c.start, ramp=c if (c.ramp > 0.0 and master is None) else None)
    h.master_harmonic = master
    return h
