"""``hammerbit cosim --ssp``: the project's master on the system of a ``drilling.ssp``.

The package's Drillstring FMU carries the string side's arrays; the master
builds its string side from them (:class:`~hammerbit.cosim.string_side.StringSide`
on the same arrays, so the same exact step) and drives the package's
HammerBitRock FMU with the SSD's parameter values, wired as the SSD wires
them (``exchange='fmi'``, ``hammer_input='harmonic_force'``).  With a fixed
step and the Jacobi scheme this is what a fixed-step runner (libcosim,
FMPy) does with the two FMUs; without ``step`` the master's adaptive step
and error estimate run on the same system.
"""
from __future__ import annotations

import math
import tempfile
import zipfile
from dataclasses import dataclass, fields
from pathlib import Path

from hammerbit.ssp.document import SSD_NAME, read_ssd
from hammerbit.ssp.package import HAMMER, STRING

__all__ = ["SSPSystem", "load_ssp", "cosimulate_ssp", "monolithic_ssp", "hammer_output_derivative_order"]


@dataclass
class SSPSystem:
    """A ``drilling.ssp`` unpacked: its description, the string's arrays and info, the hammer FMU's
    path, and the co-simulation config of the system."""

    description: object
    arrays: dict
    info: dict
    hammer_fmu: Path
    config: object
    workdir: object

    def close(self) -> None:
        self.workdir.cleanup()


def _string_resources(fmu_path: Path, dest: Path) -> tuple:
    """``(arrays, info)`` of the package's Drillstring FMU: from its ``string_model.npz`` (the
    pythonfmu flavour) or the generator blocks of its ``string_native.bin`` (the native one)."""
    import json

    from hammerbit.fmu.native_string import DATA_FILE, read_string_arrays
    from hammerbit.model.string_model import INFO_FILE, MODEL_FILE, load_model
    with zipfile.ZipFile(fmu_path) as z:
        names = set(z.namelist())
        if f"resources/{MODEL_FILE}" not in names:
            info = json.loads(z.read(f"resources/{INFO_FILE}"))
            return read_string_arrays(z.read(f"resources/{DATA_FILE}"), info), info
        for name in (MODEL_FILE, INFO_FILE):
            (dest / name).write_bytes(z.read(f"resources/{name}"))
    return load_model(str(dest))


def _rig(params: dict):
    from hammerbit.model.params import RigParameters
    kw = {f.name: float(params[f.name]) for f in fields(RigParameters)
          if f.name in params and f.name not in ("preload", "gap")}
    kw["preload"] = float(params["preload"])
    kw["gap"] = float(params["gap"]) if params.get("impact_enabled") and "gap" in params else math.inf
    return RigParameters(**kw)


def _top(params: dict, info: dict):
    """The string's top condition from its parameter values (the FMU's start values where absent)."""
    from hammerbit.drillstring.top import TopCondition
    from hammerbit.model.string_model import TOP_CONDITIONS
    kind = TOP_CONDITIONS[int(params.get("top_condition", info["top_condition"]))]
    if kind == "feed":
        return TopCondition.feed(float(params.get("feed_velocity", info["feed_velocity"])))
    if kind == "auto-driller":
        return TopCondition.auto_driller(float(params.get("proportional_gain", info["proportional_gain"])),
                                         float(params.get("integral_gain", info["integral_gain"])))
    return TopCondition.fixed()


def load_ssp(path, **config) -> SSPSystem:
    """Unpack ``path`` and make the system's :class:`~hammerbit.cosim.config.CosimConfig` (``config``
    overrides its fields: ``stop``, ``step``, ``adaptive``, ``tol``, ``record`` ...)."""
    from hammerbit.cosim.config import CosimConfig
    path = Path(path)
    if not path.is_file() or not zipfile.is_zipfile(path):
        raise ValueError(f"--ssp {str(path)!r}: not an SSP package (a zip archive with {SSD_NAME})")
    work = tempfile.TemporaryDirectory(prefix="hammerbit_ssp_run_")
    try:
        root = Path(work.name)
        with zipfile.ZipFile(path) as z:
            if SSD_NAME not in z.namelist():
                raise ValueError(f"--ssp {str(path)!r}: the archive has no {SSD_NAME}")
            z.extractall(root)
        desc = read_ssd((root / SSD_NAME).read_bytes())
        string, hammer = desc.component(STRING), desc.component(HAMMER)
        arrays, info = _string_resources(root / string.source, root)
        sp, hp = string.parameters, hammer.parameters
        sc = info["scalars"]
        kw = dict(rig=_rig(hp), wob=float(sp["wob"]), interface_stiffness=sc["interface_stiffness"],
                  top=_top(sp, info),
                  interface_damping=sc["interface_damping"], extrapolation=int(sp.get("extrapolation", 2)),
                  exchange="fmi", hammer_input="harmonic_force", scheme="jacobi", start=desc.start_time,
                  stop=desc.stop_time, step=desc.step_size, rtol=float(hp.get("tolerance", 1e-10)))
        kw.update(config)
        cfg = CosimConfig(**kw)
        return SSPSystem(desc, arrays, info, root / hammer.source, cfg, work)
    except Exception:
        work.cleanup()
        raise


def _side(system: SSPSystem):
    from hammerbit.cosim.string_side import StringSide
    from hammerbit.model.string_model import PARAMETERS
    params = system.description.component(STRING).parameters
    values = {p: float(params.get(p, system.info[p] if p in system.info else system.info["scalars"][p]))
              for p in PARAMETERS}
    return StringSide.from_arrays(system.arrays, system.info, values, system.config)


def hammer_output_derivative_order(system: SSPSystem) -> int:
    """``maxOutputDerivativeOrder`` of the package's HammerBitRock.fmu (0: none, the pythonfmu flavour)."""
    from fmpy import read_model_description
    return int(read_model_description(str(system.hammer_fmu)).coSimulation.maxOutputDerivativeOrder or 0)


def cosimulate_ssp(path, **config):
    """Run the system of ``path`` with the master (a :class:`~hammerbit.cosim.config.CosimResult`).
    ``output_derivatives=True`` needs a hammer FMU with output derivatives of order 2 (the native
    flavour): else a ValueError before the run."""
    from hammerbit.cosim.master import cosimulate
    system = load_ssp(path, **config)
    try:
        if system.config.output_derivatives and (order := hammer_output_derivative_order(system)) < 2:
            raise ValueError(f"--output-derivatives: the package's {HAMMER} ({system.hammer_fmu.name}) declares "
                             f"maxOutputDerivativeOrder = {order} (the pythonfmu flavour has none); build the "
                             f"package with `hammerbit ssp build --runtime native`")
        return cosimulate(None, system.config, fmu=str(system.hammer_fmu), side=_side(system))
    finally:
        system.close()


def monolithic_ssp(path, **config):
    """The monolithic reference of the system of ``path`` (the string from the TOML the FMU carries)."""
    from hammerbit.cosim.reference import monolithic
    from hammerbit.drillstring.loading import loads_string
    system = load_ssp(path, **config)
    try:
        zeta = system.description.component(STRING).parameters["damping_ratio"]
        string = loads_string(system.info["toml"], source="string.toml").replace(modal_damping_ratio=zeta)
        return monolithic(string, system.config.replace(exchange="master", hammer_input="preload"))
    finally:
        system.close()
