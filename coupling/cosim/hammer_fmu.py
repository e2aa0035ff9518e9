"""The FMU hammer side of the co-simulation: ``HammerBitRock.fmu`` driven through fmpy."""
from __future__ import annotations

import math
import zipfile
from dataclasses import fields
from pathlib import Path

from hammerbit.model.params import RigParameters

from hammerbit.cosim.hammer_interface import (OUT_BIT_POSITION, OUT_BIT_VELOCITY, OUT_HAMMER_POSITION,
                                              OUT_HAMMER_VELOCITY, OUT_WOB)

__all__ = ["FMUHammer", "FMUStepError", "FMU_NAMES", "check_fmu_file", "fmu_start_values"]


class FMUStepError(RuntimeError):
    """The hammer FMU's ``fmi2DoStep`` failed: the run stops there, with the FMU's message."""


def check_fmu_file(path) -> None:
    """A clear error for a path that is not an FMU (before fmpy's own)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"fmu {str(path)!r}: no such file (build it with `hammerbit fmu build` "
                                f"or python build_fmu.py)")
    if not zipfile.is_zipfile(p):
        raise ValueError(f"fmu {str(path)!r}: not an FMU (an FMU is a zip archive with a "
                         f"modelDescription.xml)")
    with zipfile.ZipFile(p) as z:
        if "modelDescription.xml" not in z.namelist():
            raise ValueError(f"fmu {str(path)!r}: the archive has no modelDescription.xml: not an FMU")


def fmu_start_values(causality: dict, rig: RigParameters, wob: float, rtol: float) -> tuple:
    """``(reals, booleans)``: the start values the master gives a hammer FMU with the variables
    ``causality`` ({name: causality}): every ``RigParameters`` field the FMU has as a parameter,
    the gap and ``impact_enabled``, ``tolerance = rtol``, the hammer's start position ``W/K`` (the
    static equilibrium) and ``preload = W``."""
    reals, booleans = {}, {}
    for f in fields(RigParameters):
        if f.name in ("preload", "gap") or causality.get(f.name) != "parameter":
            continue
        reals[f.name] = float(getattr(rig, f.name))
    if "gap" in causality and math.isfinite(rig.gap):
        reals["gap"] = float(rig.gap)
    if "tolerance" in causality:
        reals["tolerance"] = float(rtol)
    if "impact_enabled" in causality:
        booleans["impact_enabled"] = bool(math.isfinite(rig.gap))
    for nm in FMU_NAMES["hammer_position_start"]:
        if nm in causality:
            reals[nm] = wob / rig.stiffness
            break
    reals["preload"] = float(wob)
    return reals, booleans


#: Candidate variable names of the FMU (first match wins).
FMU_NAMES = {
    "preload": ("preload",),
    "hammer_position": ("hammer_position", "x_hammer", "hammer.position"),
    "hammer_velocity": ("hammer_velocity", "v_hammer", "hammer.velocity"),
    "bit_position": ("bit_position", "x_bit", "bit.position", "penetration"),
    "bit_velocity": ("bit_velocity", "v_bit", "bit.velocity"),
    "contact_force": ("contact_force", "impact_force"),
    "rock_force": ("rock_force", "drive_on_bit"),
    "hammer_position_start": ("hammer_position_start", "initial_hammer_position", "hammer_position0",
                              "x_hammer_start"),
}


class FMUHammer:
    """The hammer FMU driven through fmpy's ``FMU2Slave``.

    Value references come from ``read_model_description`` by name.  The
    hammer's parameters are set from the ``RigParameters`` fields the FMU
    exposes (same names); ``preload`` is the input.  If the FMU exposes a
    start value of the hammer position (``hammer_position_start`` or the
    names in :data:`FMU_NAMES`), the run starts in equilibrium
    (``W/K``); otherwise the initial preload step is the FMU's own start-up.

    ``force_input="harmonic_force"``: ``preload`` stays at the WOB and the held
    force's change from it goes to ``harmonic_force`` (the wiring of the SSP
    package, where the Drillstring FMU's ``held_force_change`` feeds it).
    """

    def __init__(self, path, rig: RigParameters, wob: float, *, t0: float = 0.0, rtol: float = 1e-8,
                 instance: str = "hammer", force_input: str = "preload"):
        from fmpy.fmi1 import FMICallException

        from hammerbit.fmu.host import FMUInstance
        self._call_error = FMICallException
        self.path = str(path)
        self._host = FMUInstance(self.path, instance, start_time=t0, init=False)
        md, self.fmu = self._host.md, self._host.fmu
        self.md = md
        self.vr = dict(self._host.vr)
        self.causality = {v.name: v.causality for v in md.modelVariables}
        reals, booleans = fmu_start_values(self.causality, rig, wob, rtol)
        self.equilibrium_start = any(nm in reals for nm in FMU_NAMES["hammer_position_start"])
        if reals:
            self.fmu.setReal([self.vr[k] for k in reals], list(reals.values()))
        if booleans:
            self.fmu.setBoolean([self.vr[k] for k in booleans], list(booleans.values()))
        self.vr_in = self._find("preload")
        self.force_input = force_input
        self.wob = wob
        self.vr_force = self.vr_in if force_input == "preload" else self.vr["harmonic_force"]
        self._vr_preload = [self.vr_in] if force_input == "preload" else None   # step() sets it every step
        self.fmu.exitInitializationMode()
        out = [self._find(k) for k in ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity")]
        self.vr_rock = self._find("rock_force", required=False)
        self.vr_fc = None if self.vr_rock is not None else self._find("contact_force", required=False)
        extra = self.vr_rock if self.vr_rock is not None else self.vr_fc
        self.vr_out = out + ([extra] if extra is not None else [])
        self.rig = rig
        self.x_eq = wob / rig.stiffness if self.equilibrium_start else 0.0
        self._K, self._C = rig.stiffness, rig.damping
        self._flag_vrs = (self.vr.get("stick_slip"), self.vr.get("in_contact"))
        #: maxOutputDerivativeOrder of the FMU (0: none)
        self.output_derivative_order = int(md.coSimulation.maxOutputDerivativeOrder or 0)

    def _find(self, key: str, *, required: bool = True):
        for nm in FMU_NAMES[key]:
            if nm in self.vr:
                return self.vr[nm]
        if required:
            raise KeyError(f"FMU {self.path}: no variable for {key!r} (tried {FMU_NAMES[key]}); "
                           f"it has {sorted(self.vr)}")
        return None

    master_harmonic = None

    def _set_input(self, t: float, H: float, force: float) -> None:
        if self.master_harmonic is not None:
            self.fmu.setReal([self.vr_in, self.vr["harmonic_force"]],
                             [force, self.master_harmonic.mean(t, H)])
        elif self._vr_preload is not None:
            self.fmu.setReal(self._vr_preload, [force])
        else:
            self.fmu.setReal([self.vr_force], [force - self.wob])

    def step(self, t: float, H: float, force: float) -> None:
        self._set_input(t, H, force)
        try:
            self.fmu.doStep(t, H)
        except self._call_error as e:        # the run stops here: say what the FMU said
            said = self._host.errors()
            raise FMUStepError(f"FMU {self.path}: the step from t = {t:.9g} s (h = {H:.6g} s) failed: "
                               f"{said[-1] if said else e}") from None

    def motion_derivatives(self, t: float, H: float, force: float) -> list:
        """``[x', v', x'', v'']`` of the hammer at ``t`` [m/s, m/s^2, m/s^2, m/s^3] with the input of
        the step ``[t, t + H]`` set (``fmi2GetRealOutputDerivatives``; the native flavour)."""
        if self.output_derivative_order < 2:
            raise ValueError(f"FMU {self.path}: no output derivatives of order 2 (maxOutputDerivativeOrder = "
                             f"{self.output_derivative_order}; the native flavour has them)")
        self._set_input(t, H, force)
        x, v = self.vr_out[OUT_HAMMER_POSITION], self.vr_out[OUT_HAMMER_VELOCITY]
        return self.fmu.getRealOutputDerivatives([x, v, x, v], [1, 1, 2, 2])

    def get_state(self):
        """fmi2GetFMUstate (the FMU saves its whole hidden state)."""
        return self.fmu.getFMUState()

    def set_state(self, state) -> None:
        """fmi2SetFMUstate: roll the FMU back."""
        self.fmu.setFMUState(state)

    def free_state(self, state) -> None:
        self.fmu.freeFMUState(state)

    def read(self) -> list:
        """The outputs laid out by the ``OUT_*`` indexes, as a list of floats (the master indexes it
        a few times a step: a list's items are cheaper to read than an array's)."""
        v = self.fmu.getReal(self.vr_out)
        if self.vr_rock is not None:
            return v                         # the rock force is the WOB
        # without a rock force, the WOB's slot holds the contact force (zero when absent)
        fc = v[OUT_WOB] if len(v) > OUT_WOB else 0.0
        wob = (self._K * (v[OUT_HAMMER_POSITION] - v[OUT_BIT_POSITION])
               + self._C * (v[OUT_HAMMER_VELOCITY] - v[OUT_BIT_VELOCITY]) + fc)
        return [v[OUT_HAMMER_POSITION], v[OUT_HAMMER_VELOCITY], v[OUT_BIT_POSITION], v[OUT_BIT_VELOCITY], wob]

    def flags(self) -> tuple:
        """(stick, contact): 1.0 while the bit sticks / while the gap is closed (0.0 for a flag
        the FMU does not expose)."""
        stick_vr, contact_vr = self._flag_vrs
        s = 0.0
        if stick_vr is not None:
            s = 1.0 if self.fmu.getInteger([stick_vr])[0] == 0 else 0.0
        ct = 0.0
        if contact_vr is not None:
            ct = 1.0 if self.fmu.getBoolean([contact_vr])[0] else 0.0
        return s, ct

    def counts(self) -> dict:
        """Event counts the FMU exposes (:func:`~hammerbit.cosim.config.event_counts` names)."""
        out = {}
        for key, name in (("slips", "slip_count"), ("impacts", "impact_count"),
                          ("bounce_violations", "bounce_count")):
            if name in self.vr:
                out[key] = int(self.fmu.getInteger([self.vr[name]])[0])
        return out

    def close(self):
        self._host.close()
