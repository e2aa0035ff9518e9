"""Build ``Drillstring.fmu``: the FMI 2.0 co-simulation FMU of a drillstring and its hammer interface.

The string is described by a TOML file (or a built-in example).  The build
computes the library's string side (:class:`hammerbit.cosim.string_side.StringSide`)
at the file's damping ratio, writes its arrays and the description into the
FMU's resources, and ships :mod:`hammerbit.model` (the ``fmu_src`` runtime,
whose :mod:`~hammerbit.model.string_step` is the master's exact string step)
as the package ``hammerbit_string_runtime_<hash>``.  The pythonfmu flavour:
the FMU runs in a host with Python, numpy, scipy, numba and pythonfmu; its
native front (``binaries/linux64/Drillstring.so``, pythonfmu's binary beside it
as ``Drillstring_python.so``) loads that Python into a native host, as
HammerBitRock's does.

From Python::

    from hammerbit.fmu.build_string import build_string_fmu
    path = build_string_fmu("field-2200m", "dist/Drillstring.fmu")

From the shell: ``hammerbit fmu build-string --string FILE [--out PATH]``.
"""
from __future__ import annotations

import json
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Optional
from xml.etree import ElementTree as ET

import numpy as np

from hammerbit.fmu.compile_cache import cache_enabled
from hammerbit.fmu.guid import content_guid, replace_guid

from hammerbit.fmu.build import (add_native_front, build_hash, forget_staged_modules, pythonfmu_builder,
                                  runtime_files)

__all__ = ["MODEL_NAME", "StringBuild", "build_string_fmu", "string_build",
           "default_string_output", "string_fmu_path"]

MODEL_NAME = "Drillstring"
RUNTIME_PREFIX = "hammerbit_string_runtime"   # + "_<hash>": the runtime package inside the FMU
ENTRY_PREFIX = "hammerbit_string_slave"       # + "_<hash>": pythonfmu's slave module
#: damping ratio of the second side when the file's is 0 (the derivative in the ratio from two sides)
_DAMPING_PROBE = 0.5

_ENTRY_SOURCE = '''"""Entry module of the {model} FMU (runtime build {hash}), imported by pythonfmu from resources/."""
import ctypes as _ctypes

# pythonfmu 0.7.0's native findClass() runs this file's code again in this module's globals on
# every fmi2Instantiate and releases one reference to that dict it never owned: one extra
# reference per execution balances it.
_ctypes.pythonapi.Py_IncRef.argtypes = [_ctypes.py_object]
_ctypes.pythonapi.Py_IncRef.restype = None
_ctypes.pythonapi.Py_IncRef(globals())

import {pkg}.numba_cache  # noqa: E402,F401  (picks the CPU target before numba is imported)
from {pkg}.string_slave import {model}  # noqa: E402,F401
'''


def default_string_output() -> Path:
    """``dist/Drillstring.fmu`` in the current directory."""
    return Path("dist") / f"{MODEL_NAME}.fmu"


def string_fmu_path(out=None) -> Path:
    """Where a Drillstring FMU goes: ``out`` (a ``.fmu`` file, or a directory that gets
    ``Drillstring.fmu``; default :func:`default_string_output`), absolute, its folder created."""
    out = Path(out) if out is not None else default_string_output()
    if out.suffix != ".fmu":
        out = out / f"{MODEL_NAME}.fmu"
    out = out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


@dataclass(frozen=True)
class StringBuild:
    """What a Drillstring FMU is built from: the string, its source text, the co-simulation config
    (interface, WOB, hammer) and the string side's arrays."""

    string: object
    source_text: str
    config: object
    arrays: dict
    info: dict


def _source_text(string_arg) -> str:
    from hammerbit.drillstring.loading import example_names, example_path
    p = Path(string_arg)
    if p.is_file():
        return p.read_text(encoding="utf-8")
    if isinstance(string_arg, str) and string_arg in example_names():
        return example_path(string_arg).read_text(encoding="utf-8")
    return ""


def _rows(m, n_string: int, cv_fixed) -> np.ndarray:
    """Output rows of side matrices ``m``, in the order of ``string_model.OUTPUT_ROWS``: bottom u, v,
    top tension, top position, top velocity (the block's state and ``v_top = g . X`` for the
    auto-driller; zero rows otherwise)."""
    n = m.A1.shape[0]
    top_u, top_v = np.zeros(n), np.zeros(n)
    if n > n_string:
        top_u[n_string] = 1.0                      # the block's position is the state after the string's
        top_v[:] = m.Cv
        top_v[:n_string] -= cv_fixed               # cv = Cv + g: the controller's velocity row
    return np.vstack((m.Cu, m.Cv, m.Ct, top_u, top_v))


def _form(m, n_string, cv_fixed) -> dict:
    return {"A1": m.A1, "E": m.E, "frow": m.frow, "rows": _rows(m, n_string, cv_fixed), "d": {}}


def _derivative(form: dict, other, n_string, cv_fixed, dp: float) -> dict:
    rows = _rows(other, n_string, cv_fixed)
    return {"A1": (other.A1 - form["A1"]) / dp, "frow": (other.frow - form["frow"]) / dp,
            "rows": (rows - form["rows"]) / dp}


def string_build(string_arg, *, wob: Optional[float] = None, rig=None, top=None,
                 interface_stiffness: float = 2.0e6, interface_damping: float = 2.0e3) -> StringBuild:
    """The string side of ``string_arg`` (TOML path or example name) and its arrays.

    ``wob`` defaults to the hammer's preload; ``rig`` to the string's default hammer
    (:func:`hammerbit.cosim.config.default_hammer`); ``top`` (a
    ``TopCondition``, default fixed) gives the FMU's start values of the top condition.  Both
    forms are built (fixed hook, auto-driller at the default gains or the given ones), with
    their derivatives in the damping ratio and the gains (:mod:`hammerbit.model.string_model`)."""
    from hammerbit.cosim.config import CosimConfig, default_hammer
    from hammerbit.cosim.string_side import StringSide
    from hammerbit.drillstring import DrillStringError, load_string, state_space
    from hammerbit.drillstring.boundary import Boundary
    from hammerbit.drillstring.top import TopCondition, top_matrices
    from hammerbit.model.fmu_description import top_condition
    from hammerbit.model.string_step import BUILT_STEPS
    string = string_arg if not isinstance(string_arg, (str, Path)) else load_string(string_arg)
    rig = default_hammer(string) if rig is None else rig
    top = TopCondition.fixed() if top is None else top
    config = CosimConfig(rig=rig, wob=wob, interface_stiffness=interface_stiffness,
                         interface_damping=interface_damping, estimate=False)
    ki, ci, K = config.interface_stiffness, config.interface_damping, rig.stiffness
    side = StringSide(string, config)
    n_string = side.n
    cv_fixed = side.Cv
    zeta = float(string.modal_damping_ratio)
    zeta_other = 0.0 if zeta > 0.0 else _DAMPING_PROBE
    string_other = string.replace(modal_damping_ratio=zeta_other)
    ss_other = state_space(string_other, None, Boundary.hammer(ki, ci), mass=config.mass,
                           wob=config.weight_on_bit, f_max=config.f_max)

    def matrices(s, ss, t):
        return top_matrices(s, ss, t, interface_stiffness=ki, interface_damping=ci, hammer_stiffness=K,
                            mass=config.mass, check=False)
    forms = {"fixed": _form(side.matrices, n_string, cv_fixed)}
    forms["fixed"]["d"]["damping_ratio"] = _derivative(
        forms["fixed"], matrices(string_other, ss_other, TopCondition.fixed()), n_string, cv_fixed,
        zeta_other - zeta)
    gains = None
    refused = None
    try:
        # the gains of the checked closed loop (unstable default gains retuned, given ones refused)
        gains = StringSide(string, config.replace(
            top=top if top.kind == "auto-driller" else TopCondition.auto_driller())).gains
        kp, kI = gains.proportional_gain, gains.integral_gain
        auto_side = StringSide(string, config.replace(top=TopCondition.auto_driller(kp, kI)))
        f = forms["auto"] = _form(auto_side.matrices, n_string, cv_fixed)
        f["d"]["damping_ratio"] = _derivative(
            f, matrices(string_other, ss_other, TopCondition.auto_driller(kp, kI)), n_string, cv_fixed,
            zeta_other - zeta)
        f["d"]["proportional_gain"] = _derivative(
            f, matrices(string, side.ss, TopCondition.auto_driller(2.0 * kp, kI)), n_string, cv_fixed, kp)
        f["d"]["integral_gain"] = _derivative(
            f, matrices(string, side.ss, TopCondition.auto_driller(kp, 2.0 * kI)), n_string, cv_fixed, kI)
    except DrillStringError as e:          # a top that moves needs a string without viscous drag
        refused = str(e)
        if top.moves:
            raise
    W = config.weight_on_bit
    build_values = {"damping_ratio": zeta,
                    "proportional_gain": gains.proportional_gain if gains else 0.0,
                    "integral_gain": gains.integral_gain if gains else 0.0}
    scalars = {"interface_stiffness": ki, "interface_damping": ci, "damping_ratio": zeta, "wob": W,
               "hook_load": side.hook_eq, "buoyed_weight": side.hook_eq + W, "string_states": n_string}
    length = float(sum(s.length for s in string.sections))
    sections = "; ".join(f"{s.name or 'section'} {s.length:g} m x {s.od * 1e3:g} mm" for s in string.sections)
    info = {"name": string.name, "length_m": length, "sections": sections, "scalars": scalars,
            "hammer_position_at_rest": W / rig.stiffness,
            "top_condition": top_condition(top.kind).code, "feed_velocity": float(top.feed_velocity),
            "proportional_gain": build_values["proportional_gain"],
            "integral_gain": build_values["integral_gain"],
            "auto_driller": None if gains is None else gains.to_dict(), "auto_driller_refused": refused,
            "description": (f"Drillstring '{string.name}' ({length:g} m: {sections}) with its hammer "
                            f"interface k_i = {ki:g} N/m, c_i = {ci:g} N s/m; top boundary "
                            f"{string.top.spec()}; {n_string} states; geometry fixed at build time"),
            "toml": _source_text(string_arg),
            # the step lengths whose exponentials are the build's; the FMU takes any other too
            "steps": list(BUILT_STEPS)}
    arrays = {"forms": forms, "build_values": build_values}
    return StringBuild(string, info["toml"], config, arrays, info)


#: modules the Drillstring FMU's runtime cannot do without
STRING_RUNTIME_MODULES = ("string_slave.py", "string_step.py", "string_kernels.py", "string_exponentials.py",
                          "string_model.py",
                          "numba_cache.py")


def build_string_fmu(string_arg, out=None, *, build: Optional[StringBuild] = None, **kw) -> Path:
    """Build ``Drillstring.fmu`` of ``string_arg`` (TOML path or example name) and return its path.

    ``out``: the ``.fmu`` file or a directory (default ``dist/Drillstring.fmu``); ``kw`` go to
    :func:`string_build` (``wob``, ``rig``, ``top``, ``interface_stiffness``, ``interface_damping``)."""
    FmuBuilder = pythonfmu_builder()
    cache_enabled()                       # a bad HAMMERBIT_BUILD_CACHE is refused before any work
    from hammerbit.model.string_model import INFO_FILE, MODEL_FILE, save_model
    build = string_build(string_arg, **kw) if build is None else build
    out = string_fmu_path(out)
    files = runtime_files(needed=STRING_RUNTIME_MODULES)
    tag = build_hash(files)
    pkg_name, entry_name = f"{RUNTIME_PREFIX}_{tag}", f"{ENTRY_PREFIX}_{tag}"
    with tempfile.TemporaryDirectory(prefix="hammerbit_string_fmu_") as tmp:
        work = Path(tmp)
        staging = work / "stage"
        pkg = staging / pkg_name
        pkg.mkdir(parents=True)
        for f in files:
            shutil.copy2(f, pkg / f.name)
        save_model(staging / MODEL_FILE, build.arrays["forms"], build.arrays["build_values"])
        (staging / INFO_FILE).write_text(json.dumps(build.info, indent=1) + "\n")
        (staging / "string.toml").write_text(build.source_text)
        script = staging / f"{entry_name}.py"
        script.write_text(_ENTRY_SOURCE.format(model=MODEL_NAME, hash=tag, pkg=pkg_name))
        forget_staged_modules(staging, (entry_name, pkg_name))
        try:
            raw = FmuBuilder.build_FMU(script, dest=work / f"{MODEL_NAME}.fmu",
                                       project_files=[pkg, staging / MODEL_FILE, staging / INFO_FILE,
                                                      staging / "string.toml"],
                                       canHandleVariableCommunicationStepSize=True)
        finally:
            forget_staged_modules(staging, (entry_name, pkg_name))
        with zipfile.ZipFile(raw) as zf:
            contents = {n: zf.read(n) for n in zf.namelist() if not n.endswith("/")}
        # the native front, as HammerBitRock's: loads Python into a native host (pythonfmu's own
        # binary expects the host to be Python) and keeps the FMI calling sequence
        md = contents["modelDescription.xml"]
        md = replace_guid(md, content_guid(md, tag))
        contents["modelDescription.xml"] = md
        from hammerbit.fmu.table_check import check_description
        from hammerbit.model.fmu_description import STRING_VARIABLES
        check_description(md, STRING_VARIABLES, out.name)
        model_identifier = ET.fromstring(md).find("CoSimulation").get("modelIdentifier")
        add_native_front(contents, md.decode("utf-8"), model_identifier, work)
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            for name in sorted(contents):
                zf.writestr(name, contents[name])
        tmp_out.replace(out)
    return out
