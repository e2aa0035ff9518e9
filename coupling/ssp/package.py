"""Build ``drilling.ssp``: the Drillstring and HammerBitRock FMUs as one SSP 1.0 system.

The package holds ``SystemStructure.ssd`` and the two FMUs in ``resources/``.
The wiring (see ``docs/cosim.md``)::

    hammer.hammer_position  -> string.hammer_position
    hammer.hammer_velocity  -> string.hammer_velocity
    string.held_force_change -> hammer.harmonic_force     (hammer.preload held at the WOB)

so every connector starting at 0 (FMPy's SSP runner) is the static
equilibrium.  The parameter values are in the SSD and are also the FMUs'
own start values (the FMUs are built with them): a runner that ignores the
SSD's parameter bindings (FMPy's ``simulate_ssp``) runs the same system.
"""
from __future__ import annotations

import math
import shutil
import tempfile
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from hammerbit.ssp.document import SSD_NAME, Component, Connection, SystemDescription, write_ssd

__all__ = ["SSPOptions", "RUNTIMES", "build_ssp", "STRING", "HAMMER", "CONNECTIONS", "hammer_parameters"]

#: component names in the system
STRING, HAMMER = "string", "hammer"
#: (output component, output, input component, input)
CONNECTIONS = (
    (HAMMER, "hammer_position", STRING, "hammer_position"),
    (HAMMER, "hammer_velocity", STRING, "hammer_velocity"),
    (STRING, "held_force_change", HAMMER, "harmonic_force"),
)
_HAMMER_CONNECTORS = {"harmonic_force": ("input", "N"), "hammer_position": ("output", "m"),
                      "hammer_velocity": ("output", "m/s"), "bit_position": ("output", "m"),
                      "rock_force": ("output", "N")}
_STRING_CONNECTORS = {"hammer_position": ("input", "m"), "hammer_velocity": ("input", "m/s"),
                      "held_force_change": ("output", "N"), "interface_force": ("output", "N"),
                      "hook_load": ("output", "N")}
#: extrapolation order of the string's exchange in the system (the Drillstring FMU's default)
STRING_EXTRAPOLATION = 2
#: the flavours of the packed FMUs
RUNTIMES = ("pythonfmu", "native")
#: tolerance of the hammer FMU's integrator in the system (the master's default ``rtol``)
HAMMER_TOLERANCE = 1e-10


@dataclass(frozen=True)
class SSPOptions:
    """Options of :func:`build_ssp` (SI units).

    ``hammer``: an existing HammerBitRock FMU (default: built with the system's start values);
    ``stop``, ``step``: the default experiment and libcosim's fixed step [s]; ``wob``: weight on
    bit [N] (default: the hammer's preload); ``rig``: the hammer's ``RigParameters`` (default:
    :func:`hammerbit.cosim.config.default_hammer` of the string); ``top``: the string's
    ``TopCondition`` (default fixed); ``runtime``: the FMUs' flavour, ``pythonfmu`` (the host
    needs Python) or ``native`` (both FMUs compiled: no Python on the target; the string FMU
    carries the package's step size)."""

    hammer: Optional[str] = None
    stop: float = 2.0
    step: float = 1e-3
    wob: Optional[float] = None
    rig: Optional[object] = None
    top: Optional[object] = None
    runtime: str = "pythonfmu"

    def __post_init__(self):
        if self.runtime not in RUNTIMES:
            raise ValueError(f"--runtime = {self.runtime!r}: allowed {', '.join(RUNTIMES)}")
        for name in ("stop", "step"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"--{name} = {v!r}: allowed a finite number > 0 s")
        if self.step > self.stop:
            raise ValueError(f"--step = {self.step!r}: allowed (0, --stop = {self.stop!r}] s")


def hammer_parameters(hammer_fmu, rig, wob: float) -> dict:
    """The hammer's parameter values in the system: what the master sets (:func:`fmu_start_values`)."""
    from fmpy import read_model_description
    from hammerbit.cosim.hammer_fmu import fmu_start_values
    md = read_model_description(str(hammer_fmu), validate=False)
    causality = {v.name: v.causality for v in md.modelVariables}
    reals, booleans = fmu_start_values(causality, rig, wob, HAMMER_TOLERANCE)
    return {**reals, **booleans}


def _system_hammer_values(rig, wob: float) -> dict:
    """:func:`hammer_parameters` of the HammerBitRock FMU this install builds (from its variables)."""
    from hammerbit.cosim.hammer_fmu import fmu_start_values
    from hammerbit.model.fmu_variables import INPUTS, start_values
    inputs = {v.name for v in INPUTS}
    causality = {name: "input" if name in inputs else "parameter" for name in start_values()}
    reals, booleans = fmu_start_values(causality, rig, wob, HAMMER_TOLERANCE)
    return {**reals, **booleans}


def _hammer_defaults(hammer_fmu) -> dict:
    from fmpy import read_model_description
    md = read_model_description(str(hammer_fmu), validate=False)
    out = {}
    for v in md.modelVariables:
        if v.start is None:
            continue
        out[v.name] = (v.start.lower() == "true") if v.type == "Boolean" else float(v.start)
    return out


def build_ssp(string_arg, out, options: SSPOptions = SSPOptions()) -> Path:
    """Build ``drilling.ssp`` for the string ``string_arg`` (TOML path or example name); its path.

    With ``options.hammer`` the given FMU is packed as it is; when its start values differ
    from the system's, a warning names them (runners that ignore the SSD's parameter
    bindings, such as FMPy's, would then run other values)."""
    from hammerbit.fmu.build import BuildOptions, build_fmu
    from hammerbit.fmu.build_string import MODEL_NAME, build_string_fmu, string_build
    out = Path(out).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    sb = string_build(string_arg, wob=options.wob, rig=options.rig, top=options.top)
    rig, W = sb.config.rig, sb.config.weight_on_bit
    with tempfile.TemporaryDirectory(prefix="hammerbit_ssp_") as tmp:
        work = Path(tmp)
        if options.runtime == "native":
            from hammerbit.fmu.native_string import build_native_string_fmu
            string_fmu = build_native_string_fmu(string_arg, work / f"{MODEL_NAME}.fmu", build=sb,
                                                 steps=(options.step,), log=lambda m: None)
        else:
            string_fmu = build_string_fmu(string_arg, work / f"{MODEL_NAME}.fmu", build=sb)
        if options.hammer is None:
            params = _system_hammer_values(rig, W)
            hammer_fmu = build_fmu(work / "HammerBitRock.fmu",
                                   options=BuildOptions(start_values=dict(params), runtime=options.runtime))
        else:
            hammer_fmu = work / "HammerBitRock.fmu"
            shutil.copy2(options.hammer, hammer_fmu)
            params = hammer_parameters(hammer_fmu, rig, W)
            defaults = _hammer_defaults(hammer_fmu)
            differ = sorted(k for k, v in params.items() if defaults.get(k) != v)
            if differ:
                warnings.warn(f"--hammer {options.hammer}: its start values of {', '.join(differ)} differ "
                              f"from the system's; the SSD sets them, but a runner that ignores the SSD's "
                              f"parameter bindings (FMPy's simulate_ssp) runs the FMU's own", stacklevel=2)
        info = sb.info
        string_params = {"damping_ratio": info["scalars"]["damping_ratio"], "wob": W,
                         "hammer_position_at_rest": info["hammer_position_at_rest"],
                         "extrapolation": STRING_EXTRAPOLATION, "top_condition": int(info["top_condition"]),
                         "feed_velocity": info["feed_velocity"], "proportional_gain": info["proportional_gain"],
                         "integral_gain": info["integral_gain"]}
        system = SystemDescription(
            name="drilling",
            components=[Component(STRING, f"resources/{MODEL_NAME}.fmu", dict(_STRING_CONNECTORS), string_params),
                        Component(HAMMER, "resources/HammerBitRock.fmu", dict(_HAMMER_CONNECTORS), params)],
            connections=[Connection(*c) for c in CONNECTIONS],
            stop_time=float(options.stop), step_size=float(options.step))
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr(SSD_NAME, write_ssd(system))
            zf.write(string_fmu, f"resources/{MODEL_NAME}.fmu")
            zf.write(hammer_fmu, "resources/HammerBitRock.fmu")
        tmp_out.replace(out)
    return out
