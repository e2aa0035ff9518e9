"""``DrillingSystem.fmu``: hammer, bit, string and top condition as one native FMU (FMI 2.0 CS).

The FMU integrates the whole drilling system as one hybrid system, as the
co-simulation's reference does (:func:`hammerbit.cosim.reference.monolithic`):
the string with the interface spring (and the feed's block or the
auto-driller's states) is the linear subsystem of the library's
event-located adaptive solver, compiled into the binary
(:mod:`hammerbit.fmu.native_system_kernels`) and driven by
``native/model_system.c`` behind the native FMI 2.0 front.  The master's
communication step is only where it reads and writes: the solver's own steps
and events do not depend on it.

The build computes the subsystem (CSR matrix, couplings, the solver's
initial arrays) with the library and writes it into a generated C header
(``hsys_data.h``); the inputs that change it between steps (``feed_velocity``
with the feed, ``wob_set_point`` with the auto-driller) enter only the
constant state's column, affinely, so the header carries that column's
derivative with respect to each.

The string's block of the subsystem is dense (the consistent mass matrix's
inverse couples every node), so the build writes it in its real modal form
where that is well conditioned (:mod:`hammerbit.cosim.modal_form`), as the
reference does.  The outputs read the string through rows transformed the
same way (the hook load: ``row . T``).  The variables are those of
:data:`hammerbit.model.fmu_description.SYSTEM_VARIABLES`; the
``modelDescription.xml`` is generated from them.
"""
from __future__ import annotations

import hashlib
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from hammerbit.fmu.guid import content_guid

__all__ = ["MODEL_NAME", "SYSTEM_TOOL", "SYSTEM_SOURCES", "system_data",
           "system_model_description", "system_header", "build_system_fmu"]

MODEL_NAME = "DrillingSystem"
#: ``generationTool`` of the model description
SYSTEM_TOOL = "hammerbit fmu build-system"
#: the solver's rtol is the FMU's tolerance times this (its global error stays below the tolerance)
RTOL_PER_TOLERANCE = 0.1
#: the solver's atol is its rtol times this (as the reference's)
ATOL_PER_RTOL = 1e-2


def _sources():
    from hammerbit.fmu.native import FRONT_SOURCES, SOURCE_DIR
    return tuple(SOURCE_DIR / f for f in (*FRONT_SOURCES, "model_backend.c", "model_common.c", "model_system.c",
                                          "model_system_access.c", "model_system_regime.c", "real_repr.c", "nrt_shim.c", "glibc_compat.c"))


#: C sources of the FMU (front, resource URIs, the system model, repr, runtime shim)
SYSTEM_SOURCES = _sources()


def _with_impulse(lin):
    """The subsystem with one more state, q' = the link force on the hammer (its integral over a
    step gives the mean WOB through the hammer's momentum balance); q feeds back nowhere."""
    from hammerbit.model.stepping import LinearSubsystem
    A = np.asarray(lin.A, dtype=float)
    n = A.shape[0]
    Ae = np.zeros((n + 1, n + 1))
    Ae[:n, :n] = A
    Ae[n, :n] = lin.G
    He = np.vstack((lin.H, lin.g))
    return LinearSubsystem(A=Ae, H=He, G=np.r_[lin.G, 0.0], g=np.asarray(lin.g, float), z0=np.r_[lin.z0, 0.0])


def system_data(string, config, *, tolerance: float = 1e-3) -> dict:
    """The arrays and scalars of the FMU for ``string`` and ``config`` (a
    :class:`~hammerbit.cosim.config.CosimConfig`: rig, WOB, interface, top condition)."""
    from hammerbit.cosim.modal_form import in_modal_form
    from hammerbit.cosim.reference import monolithic_subsystem
    from hammerbit.cosim.string_side import StringSide
    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model.regime import friction_floor
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.model.stepping import Stepper
    side = StringSide(string, config)
    top = config.top.kind
    lin0, x1eq = monolithic_subsystem(string, side, config)
    rtol = tolerance * RTOL_PER_TOLERANCE
    physical = _with_impulse(lin0)
    n = side.n
    ext0, Tz = in_modal_form(physical, n, rtol)
    Tz_inv_rows = (lambda v: v) if Tz is None else (lambda v: np.linalg.solve(Tz, v))
    ic, iq = n + 1, n + 2
    nz = iq + 1

    def column(lin):
        # the change of the constant state's column (the rows of z' transform with Tz^-1; T leaves
        # the constant state itself alone)
        e = _with_impulse(lin)
        return (Tz_inv_rows(np.asarray(e.A)[:, ic] - np.asarray(physical.A)[:, ic]),
                float(e.G[ic] - physical.G[ic]))

    zero = (np.zeros(nz), 0.0)
    V0 = float(side.feed[0])
    dV = column(monolithic_subsystem(string, side, config, feed_velocity=V0 + 1.0)[0]) if top == "feed" else zero
    dW = column(monolithic_subsystem(string, side, config, set_point_offset=1.0)[0]) if top == "auto-driller" else zero
    # CSR with the constant state's column present in every row it may reach
    A = np.asarray(ext0.A)
    mask = A != 0.0
    mask[:, ic] |= (dV[0] != 0.0) | (dW[0] != 0.0)
    indptr, indices, data, pos_ic = [0], [], [], np.full(nz, -1, dtype=np.int64)
    for i in range(nz):
        cols = np.flatnonzero(mask[i])
        for j in cols:
            if j == ic:
                pos_ic[i] = len(data)
            indices.append(j)
            data.append(A[i, j])
        indptr.append(len(data))
    grp = config.rig.to_groups().replace(b=0.0)
    st = Stepper(grp, solver=SolverOptions(rtol=rtol, atol=rtol * ATOL_PER_RTOL), linear=ext0,
                 y0=[x1eq, 0.0, 0.0, 0.0], compile_helper=False)
    s = config.rig.scales
    F0, x0, Om = s.friction_force, s.length, s.omega
    scale = {"x": x0, "v": s.velocity, "z": F0 / Om}
    D = np.array([scale[k] for k in side.matrices.kinds])
    hook_row = np.zeros(nz)
    hook_row[:n] = np.asarray(side.Ct) * D
    if Tz is not None:
        hook_row = hook_row @ Tz
    from hammerbit.drillstring.top import MAX_FEED
    return {"nz": nz, "ic": ic, "iq": iq, "csr": np.r_[indptr, indices].astype(np.int64),
            "ax": np.array(data), "h": np.ascontiguousarray(ext0.H, dtype=float).ravel(), "g_sub": ext0.G,
            "g_link": np.asarray(ext0.g, dtype=float), "pos_ic": pos_ic, "col_ic": A[:, ic].copy(),
            "dcol_v": dV[0], "dcol_w": dW[0], "g_ic": float(ext0.G[ic]), "dg_v": dV[1], "dg_w": dW[1],
            "y0": st.y.copy(), "ist0": st.istate.copy(), "fst0": st.fstate.copy(), "p": st.p.copy(),
            "opts": st.opts.copy(), "hook_row": hook_row, "hook_eq": float(side.ss.hook_load),
            "buoyed": float(side.ss.hook_load) + side.wob, "wob": float(side.wob), "feed": V0,
            "F0": F0, "x0": x0, "Om": Om, "amplitude": float(config.rig.amplitude),
            "frequency": float(config.rig.frequency), "top": top, "tolerance": float(tolerance),
            "max_feed": float(MAX_FEED), "string": string.name, "string_states": int(side.n), "stepper": st,
            "modal": Tz is not None, "friction_floor": friction_floor(grp),
            "layout": {k: int(getattr(KL, k)) for k in _LAYOUT}}


_LAYOUT = ("N_P", "N_ISTATE", "N_FSTATE", "N_OPTS", "I_STICK", "I_CONTACT", "I_BOUNCE", "I_WIN", "I_SWIN",
           "I_COUNT0", "N_EVENT_KINDS", "EV_IMPACT", "EV_SLIP_START", "EV_BOUNCE", "F_T", "F_H", "F_DRIVE_MIN",
           "F_ERRACC", "F_T_STICK", "O_RTOL", "O_ATOL", "P_A", "P_ETA", "P_PHI", "STICK", "SLIP", "FREE",
           "CLAMPED", "ST_DONE", "ST_MAX_STEPS", "P_B", "P_FEXT", "X_HAMMER", "V_HAMMER", "X_BIT", "V_BIT")


#: the build values a bound of the table may name, and their keys in :func:`system_data`'s dict
_BUILD_BOUNDS = {"buoyed_weight": "buoyed", "max_feed": "max_feed"}


def _bounds(v, data: dict) -> tuple:
    """``(min, max)`` of a variable as the FMU declares and enforces them (None: unbounded): the
    table's, a named build value resolved from ``data``."""
    def value(bound):
        if not isinstance(bound, str):
            return bound
        sign = -1.0 if bound.startswith("-") else 1.0
        return sign * float(data[_BUILD_BOUNDS[bound.lstrip("-")]])
    return value(v.min), value(v.max)


def _starts(data: dict) -> dict:
    return {"tolerance": data["tolerance"], "amplitude": data["amplitude"], "frequency": data["frequency"],
            "wob_set_point": data["wob"], "feed_velocity": data["feed"]}


def system_model_description(data: dict, guid: str) -> bytes:
    """``modelDescription.xml`` from :data:`~hammerbit.model.fmu_description.SYSTEM_VARIABLES`."""
    from hammerbit.model.fmu_description import FMI2_TYPE, SYSTEM_VARIABLES
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": MODEL_NAME, "guid": guid, "generationTool": SYSTEM_TOOL,
        "description": f"hammer, bit and string {data['string']} ({data['top']} top) integrated as one "
                      f"hybrid system", "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": MODEL_NAME, "canHandleVariableCommunicationStepSize": "true",
        "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true", "canNotUseMemoryManagementFunctions": "true"})
    units = ET.SubElement(root, "UnitDefinitions")
    dims = {"N": {"kg": "1", "m": "1", "s": "-2"}, "Hz": {"s": "-1"}, "m": {"m": "1"}, "m/s": {"m": "1", "s": "-1"}}
    for u, d in dims.items():
        ET.SubElement(ET.SubElement(units, "Unit", {"name": u}), "BaseUnit", d)
    cats = ET.SubElement(root, "LogCategories")
    for c in ("logStatusError", "logStatusWarning", "logAll"):
        ET.SubElement(cats, "Category", {"name": c})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0", "stopTime": "20", "stepSize": "0.01"})
    mv = ET.SubElement(root, "ModelVariables")
    starts = _starts(data)
    outputs = []
    for vr, v in enumerate(SYSTEM_VARIABLES):
        attrs = {"name": v.name, "valueReference": str(vr), "causality": v.causality, "description": v.description}
        attrs["variability"] = {"parameter": "fixed", "input": "continuous"}.get(v.causality, "continuous" if v.type == "Float64" else "discrete")
        if v.causality == "output":
            attrs["initial"] = "calculated"
            outputs.append(vr + 1)
        sv = ET.SubElement(mv, "ScalarVariable", attrs)
        t = {}
        if v.unit:
            t["unit"] = v.unit
        lo, hi = _bounds(v, data)
        if lo is not None:
            t["min"] = repr(float(lo))
        if hi is not None:
            t["max"] = repr(float(hi))
        if v.causality != "output":
            t["start"] = repr(float(starts[v.name]))
        if v.name in _UNUSED_INPUTS.get(data["top"], ()):
            # the front accepts only the start value of an input the built top condition ignores
            t["min"] = t["max"] = t["start"]
        ET.SubElement(sv, FMI2_TYPE[v.type], t)
    ms = ET.SubElement(root, "ModelStructure")
    out = ET.SubElement(ms, "Outputs")
    for i in outputs:
        ET.SubElement(out, "Unknown", {"index": str(i), "dependencies": ""})
    init = ET.SubElement(ms, "InitialUnknowns")
    for i in outputs:
        ET.SubElement(init, "Unknown", {"index": str(i), "dependencies": ""})
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


#: per top condition, the inputs it does not use (model_system_access.c refuses any other value
#: than their start): declared with min = max = start
_UNUSED_INPUTS = {"fixed": ("wob_set_point", "feed_velocity"), "feed": ("wob_set_point",),
                  "auto-driller": ("feed_velocity",)}


def _array(ctype: str, name: str, values) -> str:
    vals = np.asarray(values).ravel()
    def real(v):
        v = float(v)
        if np.isinf(v):
            return "HUGE_VAL" if v > 0 else "-HUGE_VAL"
        return repr(v)
    fmt = real if ctype == "double" else (lambda v: f"{int(v)}")
    body = ",\n".join(", ".join(fmt(v) for v in vals[i:i + 8]) for i in range(0, len(vals), 8)) or "0"
    return f"static const {ctype} {name}[{max(len(vals), 1)}] = {{\n{body}}};"


def system_header(data: dict) -> str:
    """Text of ``hsys_data.h``: value references, layout, the subsystem and the initial arrays."""
    from hammerbit.fmu.native import c_string
    from hammerbit.model.fmu_description import SYSTEM_VARIABLES, top_condition
    from hammerbit.model.regime import STALL_PERIODS, STALL_WOB_FRACTION
    from hammerbit.scene.flags import MIN_WINDOW, RUNAWAY_WINDOWS
    lines = ["/* generated by hammerbit.fmu.build_system: do not edit */",
             "#ifndef HSYS_DATA_H", "#define HSYS_DATA_H", "#include <stdint.h>"]
    lines += [f"#define HSYS_VR_{v.name} {vr}u" for vr, v in enumerate(SYSTEM_VARIABLES)]
    lines += [f"#define HSYS_{k} {v}" for k, v in data["layout"].items()]
    ints = {"NZ": data["nz"], "NNZ": len(data["ax"]), "IC": data["ic"], "IQ": data["iq"],
            "TOP": top_condition(data["top"]).code, "RUNAWAY_WINDOWS": RUNAWAY_WINDOWS}
    lines += [f"#define HSYS_{k} {v}" for k, v in ints.items()]
    reals = {"F0": data["F0"], "X0": data["x0"], "OMEGA": data["Om"], "HOOK_EQ": data["hook_eq"],
             "BUOYED": data["buoyed"], "WOB_BUILD": data["wob"], "FEED_BUILD": data["feed"],
             "G_IC": data["g_ic"], "DG_V": data["dg_v"], "DG_W": data["dg_w"], "MAX_FEED": data["max_feed"],
             "RTOL_PER_TOLERANCE": RTOL_PER_TOLERANCE, "ATOL_PER_RTOL": ATOL_PER_RTOL,
             "FRICTION_FLOOR": data["friction_floor"], "STALL_PERIODS": STALL_PERIODS,
             "STALL_WOB_FRACTION": STALL_WOB_FRACTION, "MIN_WINDOW": MIN_WINDOW}
    lines += [f"#define HSYS_{k} {float(v)!r}" for k, v in reals.items()]
    for v in SYSTEM_VARIABLES:
        if v.causality != "output":
            lo, hi = _bounds(v, data)
            lines.append(f"#define HSYS_NAME_{v.name} {c_string(v.name)}")
            lines.append(f"#define HSYS_UNIT_{v.name} {c_string(v.unit)}")
            lines.append(f"#define HSYS_START_{v.name} {float(_starts(data)[v.name])!r}")
            lines.append(f"#define HSYS_MIN_{v.name} {float(lo)!r}" if lo is not None else
                         f"#define HSYS_MIN_{v.name} (-HUGE_VAL)")
            lines.append(f"#define HSYS_MAX_{v.name} {float(hi)!r}" if hi is not None else
                         f"#define HSYS_MAX_{v.name} HUGE_VAL")
    lines.append(f"#define HSYS_TOP_TEXT {c_string(data['top'])}")
    lines += [_array("int64_t", "HSYS_CSR", data["csr"]), _array("double", "HSYS_AX", data["ax"]),
              _array("double", "HSYS_H", data["h"]), _array("double", "HSYS_G", data["g_sub"]),
              _array("double", "HSYS_GLINK", data["g_link"]), _array("int64_t", "HSYS_POS_IC", data["pos_ic"]),
              _array("double", "HSYS_COL_IC", data["col_ic"]), _array("double", "HSYS_DCOL_V", data["dcol_v"]),
              _array("double", "HSYS_DCOL_W", data["dcol_w"]), _array("double", "HSYS_Y0", data["y0"]),
              _array("int64_t", "HSYS_IST0", data["ist0"]), _array("double", "HSYS_FST0", data["fst0"]),
              _array("double", "HSYS_P", data["p"]), _array("double", "HSYS_OPTS", data["opts"]),
              _array("double", "HSYS_HOOK_ROW", data["hook_row"]), "#endif", ""]
    return "\n".join(lines)


def build_system_fmu(string, config, out=None, *, tolerance: float = 1e-3, log=print,
                     fmi_version: int = 2) -> Path:
    """Build ``DrillingSystem.fmu`` for ``string`` (a DrillString) and ``config`` (CosimConfig);
    its path (``out``: a .fmu path or a directory, default ``dist/DrillingSystem.fmu``).

    ``fmi_version``: 2, or 3 for FMI 3.0 (:mod:`hammerbit.fmu.fmi3_description`; Co-Simulation
    only, without early return or Event Mode: the solver's events stay inside the step)."""
    from hammerbit.fmu.c_description import write_description_header
    from hammerbit.fmu.fmi3_description import FMI3_PLATFORMS, fmi3_header, fmi3_model_description
    from hammerbit.fmu.native import generate_header, read_model_description
    from hammerbit.fmu.table_check import check_description
    from hammerbit.model.fmu_description import SYSTEM_VARIABLES
    from hammerbit.fmu.native_build import FMI3_DEFINES, FMI3_SOURCES, link_platforms, platform_compilers, \
        select_platforms
    from hammerbit.fmu.native_kernels import build_objects, sources_key
    from hammerbit.fmu.reference_results import system_results
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version = {fmi_version!r} is out of range: allowed 2 or 3")
    from hammerbit.fmu.compile_cache import cache_enabled
    cache_enabled()                       # a bad HAMMERBIT_BUILD_CACHE is refused before any work
    out = Path("dist") / f"{MODEL_NAME}.fmu" if out is None else Path(out)
    if out.is_dir():
        out = out / f"{MODEL_NAME}.fmu"
    out.parent.mkdir(parents=True, exist_ok=True)
    data = system_data(string, config, tolerance=tolerance)
    # the GUID: a fingerprint of the description and the kernels' and C sources (same build, same GUID)
    code = sources_key(["linux64"], "system") + "".join(
        hashlib.sha256(f.read_bytes()).hexdigest() for f in SYSTEM_SOURCES)
    md = system_model_description(data, "{" + content_guid(system_model_description(data, ""), code) + "}")
    with tempfile.TemporaryDirectory(prefix="hammerbit_system_") as tmp:
        tmp = Path(tmp)
        spec = read_model_description(md)
        (tmp / "hb_model.h").write_text(generate_header(spec, wrapper_file="", python_modules=()))
        write_description_header(tmp)
        (tmp / "hsys_data.h").write_text(system_header(data))
        md3, sources, defines = None, SYSTEM_SOURCES, ()
        if fmi_version == 3:
            md3 = fmi3_model_description(md, (), SYSTEM_VARIABLES)
            (tmp / "hb_fmi3.h").write_text(fmi3_header(md3, 0))
            sources, defines = SYSTEM_SOURCES + FMI3_SOURCES, FMI3_DEFINES
        check_description(md if md3 is None else md3, SYSTEM_VARIABLES, out.name)
        compilers = platform_compilers(select_platforms(log, fmi_version), fmi3=fmi_version == 3)
        build_objects(tmp, list(compilers), kernels="system")
        built = link_platforms(compilers, tmp, tmp / "bin", MODEL_NAME, sources, defines)
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", md if md3 is None else md3)
            # the front requires the resources directory; the model reads nothing from it
            zf.writestr(zipfile.ZipInfo("resources/"), "")
            for plat, path in sorted(built.items()):
                zf.write(path, f"binaries/{plat if md3 is None else FMI3_PLATFORMS[plat]}/{path.name}")
            for name, blob in system_results(MODEL_NAME, data, md).files().items():
                zf.writestr(name, blob)
        tmp_out.replace(out)
    return out
