"""The native runtime flavour of HammerBitRock.fmu: binaries with the compiled kernels, no Python.

``hammerbit fmu build --runtime native`` writes an FMU whose
``binaries/linux64/HammerBitRock.so`` and ``binaries/win64/HammerBitRock.dll``
hold the model's kernels compiled from the library's own numba source
(:mod:`hammerbit.fmu.native_kernels`), the front of :mod:`hammerbit.fmu.native`
(state machine, checks, logging, FMU-state header) and the native model
backend (``native/model_native.c``: what the Python slave does per call, in C
around the kernels).  Nothing in them links or loads libpython, numba or numpy.

The model description is the Python flavour's (the same variables, value
references and GUID), with the pythonfmu-specific parts left out and a
``<ModelExchange>`` element beside ``<CoSimulation>``.

Needs: a C compiler for linux64 (``$CC``, ``cc``, ``gcc`` or ``clang``) and
``x86_64-w64-mingw32-gcc`` for win64 (Debian: ``gcc-mingw-w64-x86-64``); when
the cross-compiler is missing the win64 binary is skipped with a message.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from hammerbit.fmu.native import FRONT_SOURCES, SOURCE_DIR, FrontBuildError, c_string, find_compiler, generate_header, \
    read_model_description
from hammerbit.fmu.c_description import write_description_header
from hammerbit.fmu.compile_cache import cache_enabled, compile_output
from hammerbit.fmu.native_kernels import TARGETS, ALLOWED_UNDEFINED, build_objects, undefined_symbols

__all__ = ["NATIVE_GENERATION_TOOL", "MINGW_CC", "MAX_OUTPUT_DERIVATIVE_ORDER", "C_FLAGS", "NATIVE_SOURCES", "GLIBC_COMPAT_SOURCE", "GLIBC_WRAPPED", "STATES", "NativeBuildError", "native_header", "native_value_references",
           "select_platforms", "build_binaries", "link_binary", "nm_for",
           "native_model_description", "assemble_native_fmu"]

#: ``generationTool`` of the native flavour's model description (how a host tells the flavours apart)
NATIVE_GENERATION_TOOL = "hammerbit fmu build --runtime native"
#: the cross-compiler of the win64 binary (Debian package gcc-mingw-w64-x86-64)
MINGW_CC = "x86_64-w64-mingw32-gcc"
#: the highest order of the output derivatives of the native HammerBitRock (model_derivatives.c)
MAX_OUTPUT_DERIVATIVE_ORDER = 2
#: C sources of the native flavour (front, resource URIs, model backend, runtime shim)
NATIVE_SOURCES = tuple(SOURCE_DIR / f for f in (*FRONT_SOURCES, "model_backend.c", "model_common.c",
                                                "model_native.c", "model_params.c", "model_checks.c",
                                                "model_values.c", "model_me.c", "model_derivatives.c",
                                                "model_state.c",
                                                "real_repr.c", "nrt_shim.c", "glibc_compat.c"))
#: the linux64 binaries' shim to glibc 2.17 (manylinux2014): the math functions glibc 2.27/2.29
#: re-versioned, bound to their oldest version (the link wraps every reference to them)
GLIBC_COMPAT_SOURCE = SOURCE_DIR / "glibc_compat.c"
GLIBC_WRAPPED = ("exp", "log", "pow", "exp2", "log2", "expf", "logf", "powf", "exp2f", "log2f")
#: the nondimensional group whose range bounds each input, in units of the static friction
#: threshold F0 (preload b = B/F0, forcing amplitude a = A/F0): |input| <= hi * F0
INPUT_GROUPS = {"preload": "group.b", "harmonic_force": "group.a"}
#: the cross-compiler of the aarch64-linux binary of the FMI 3.0 FMU (Debian gcc-aarch64-linux-gnu)
AARCH64_CC = "aarch64-linux-gnu-gcc"
#: compiler flags of every native binary: C11 with GNU extensions, optimised, and no fused
#: multiply-add, so that the generated formulas round as Python does (aarch64 has FMA)
C_FLAGS = ("-std=gnu11", "-O2", "-ffp-contract=off")


class NativeBuildError(RuntimeError):
    """The native flavour could not be built (the message says which step and what is missing)."""


# ---------------------------------------------------------------------------
# hb_native.h: layouts, variables, ranges and start values for model_native.c
# ---------------------------------------------------------------------------
def _c_double(v: float) -> str:
    if math.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    return repr(float(v))


def _c_range(r) -> str:
    return (f"{{{_c_double(r.lo)}, {_c_double(r.hi)}, {int(r.lo_open)}, {int(r.hi_open)}, "
            f"{int(r.allow_inf)}, {c_string(r.text())}}}")


def native_header(start_values: dict, layout: dict) -> str:
    """Text of ``hb_native.h``: kernel layout, value references (from the table,
    :func:`native_value_references`), ranges and start values."""
    from dataclasses import fields

    from hammerbit.model.fmu_description import GROUP_FORMULAS, SI_NAMES
    from hammerbit.model.fmu_variables import INPUTS, PARAMETERS, variable_range
    from hammerbit.model.fmu_variables import start_values as all_start_values
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.model.validation import RANGES

    vrs = native_value_references()
    starts = all_start_values(start_values)
    stored = [(v.name, "HB_INPUT") for v in INPUTS] + [
        (v.name, "HB_TUNABLE" if v.variability == "tunable" else "HB_FIXED") for v in PARAMETERS]
    lines = ["/* generated by hammerbit.fmu.native_build from the kernels and hammerbit.model.fmu_description */",
             "#include <math.h>", ""]
    lines += [f"#define HBK_{k} {v}" for k, v in sorted(layout.items())]
    lines += [""] + [f"#define HB_VR_{_c_name(name)} {vr}u" for name, vr in sorted(vrs.items())]
    lines += ["", "enum {"] + [f"    HBS_{n}," for n, _ in stored] + ["    HB_NSTORED", "};"]
    lines += ["static const hb_stored HB_STORED[HB_NSTORED] = {"]
    for n, kind in stored:
        lines.append(f"    {{{vrs[n]}u, {kind}, {c_string(n)}, {_c_double(starts[n])}, "
                     f"{_c_range(variable_range(n))}}},")
    # value reference -> slot in HB_STORED (-1: not stored), so that get and set find it at once
    slot_of = [-1] * (max(vrs.values()) + 1)
    for i, (n, _) in enumerate(stored):
        slot_of[vrs[n]] = i
    lines += ["};", f"#define HB_SLOT_INDEX_LEN {len(slot_of)}u",
              f"static const signed char HB_SLOT_OF_VR[HB_SLOT_INDEX_LEN] = {{{', '.join(map(str, slot_of))}}};",
              f"#define HB_START_IMPACT_ENABLED {int(bool(starts['impact_enabled']))}"]
    lines += [f"#define HB_INPUT_LIMIT_F0_{n} {_c_double(RANGES[g].hi)}" for n, g in INPUT_GROUPS.items()]
    slots = {n: i for i, (n, _) in enumerate(stored)}
    # the rig parameters of the formulas (hb_description.h, HB_SI_* order) as stored slots
    order = ", ".join("-1" if f == "preload" else f"HBS_{f}" for f in SI_NAMES)
    lines += [f"static const int HB_RIG_ORDER[HB_N_SI] = {{{order}}};",
              f"static const hb_range HB_RANGE_PRELOAD = {_c_range(RANGES['preload'])};",
              "static const hb_group HB_GROUPS[HB_NGROUPS] = {"]
    lines += [f"    {{{c_string(g)}, {_c_range(RANGES['group.' + g])}}}," for g, _ in GROUP_FORMULAS]
    lines += ["};",
              f"static const hb_range HB_RANGE_STATE_POSITION = {_c_range(RANGES['state.hammer_position'])};",
              f"static const hb_range HB_RANGE_RTOL = {_c_range(RANGES['solver.rtol'])};",
              f"static const hb_range HB_RANGE_ATOL = {_c_range(RANGES['solver.atol'])};"]
    if RANGES["state.hammer_position"] != RANGES["state.bit_position"]:
        raise NativeBuildError("the native model assumes one range for both initial positions")
    solver = SolverOptions()
    for f in fields(solver):
        if f.name in ("max_events_per_period", "max_step", "graze_tol", "max_steps",
                      "max_steps_per_period", "bisection_tol"):
            lines.append(f"#define HB_SOLVER_{f.name.upper()} {_c_double(float(getattr(solver, f.name)))}")
    from hammerbit.model.fmu_variables import MAX_PERIODS_PER_STEP
    lines.append(f"#define HB_MAX_PERIODS_PER_STEP {_c_double(float(MAX_PERIODS_PER_STEP))}")
    lines.append(f"#define HB_STATE_TIME_LIMIT {_c_double(RANGES['fmu.time'].hi)}")
    if set(slots) != {n for n, _ in stored}:
        raise NativeBuildError("duplicate stored variable")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------
# compile and link
# ---------------------------------------------------------------------------
def nm_for(platform: str) -> str:
    """The ``nm`` that reads the objects of ``platform``."""
    if platform == "win64":
        return shutil.which("x86_64-w64-mingw32-nm") or "nm"
    if platform == "aarch64-linux":
        return shutil.which("aarch64-linux-gnu-nm") or "nm"
    return "nm"


#: what the FMI 3.0 binaries add: the FMI 3.0 front over the FMI 2.0 front (fmi3_front.h)
FMI3_SOURCES = tuple(SOURCE_DIR / f for f in ("fmi3_front.c", "fmi3_values.c"))
#: the FMI 3.0 binaries compile the FMI 2.0 front's functions without exporting them
FMI3_DEFINES = ("-DEXPORT=",)


def link_binary(platform: str, cc: str, obj: Path, include: Path, out: Path, sources=NATIVE_SOURCES,
                defines=()) -> None:
    """Link ``sources`` and the kernel object ``obj`` (generated headers in ``include``) into ``out``.

    The object may reference only what the shim provides (libm, numba's error path, NRT): checked
    first, so a kernel that needs more fails with its symbols named rather than at link time."""
    extra = undefined_symbols(obj, nm=nm_for(platform)) - ALLOWED_UNDEFINED
    if extra:
        raise NativeBuildError(f"the {platform} kernel object {obj.name} needs symbols no shim provides: "
                               f"{sorted(extra)}")
    srcs = [str(s) for s in sources]
    # the build directory's name (a new temporary one per build) must not reach the binary: the
    # compile cache keys on its contents, not on its name
    common = [*C_FLAGS, "-Wall", "-Wextra", "-Wno-unused-parameter", "-DHB_NATIVE_MODEL", *defines,
              f"-ffile-prefix-map={include}=.", "-I", str(include), "-I", str(SOURCE_DIR)]
    if platform in ("linux64", "aarch64-linux"):
        # glibc_compat.c and --wrap: no symbol version above glibc 2.17 (see that file)
        wrap = "-Wl," + ",".join(f"--wrap={name}" for name in GLIBC_WRAPPED)
        cmd = [cc, *common, "-fPIC", "-shared", "-fvisibility=hidden", "-o", str(out), *srcs,
               str(obj), "-Wl,-Bsymbolic", "-Wl,--no-undefined", wrap, "-lm",
               "-lpthread"]
    else:
        # static libgcc/winpthread: the DLL needs only the system's KERNEL32 and msvcrt.  Same
        # inputs, same bytes: no link timestamp, and the fixed image base instead of one hashed
        # from the output's path (Windows relocates the DLL anyway: it is built DYNAMIC_BASE)
        cmd = [cc, *common, "-D__USE_MINGW_ANSI_STDIO=1", "-shared", "-static", "-Wl,--no-insert-timestamp",
               "-Wl,--disable-auto-image-base", "-o", str(out), *srcs, str(obj), "-Wl,--no-undefined", "-lm",
               "-lpthread"]
    compile_output(cmd, out, scratch=(include,), what=f"linking the {platform} binary", error=NativeBuildError)


def select_platforms(log=print, fmi_version: int = 2) -> list:
    """linux64, and win64 when ``x86_64-w64-mingw32-gcc`` is on PATH (else ``log`` says why not);
    for FMI 3.0 also aarch64-linux when ``aarch64-linux-gnu-gcc`` is."""
    platforms = ["linux64"]
    if shutil.which(MINGW_CC):
        platforms.append("win64")
    else:
        log(f"hammerbit fmu build: no {MINGW_CC} on PATH: the FMU gets no binaries/win64 (install "
            f"the mingw-w64 cross-compiler, Debian: apt-get install gcc-mingw-w64-x86-64)")
    if fmi_version == 3:
        if shutil.which(AARCH64_CC):
            platforms.append("aarch64-linux")
        else:
            log(f"hammerbit fmu build: no {AARCH64_CC} on PATH: the FMU gets no binaries/aarch64-linux "
                f"(Debian: apt-get install gcc-aarch64-linux-gnu)")
    return platforms


def build_binaries(model_description_xml, out_dir, *, start_values=None, platforms=None,
                   log=print, fmi3_xml=None) -> dict:
    """Build ``<out_dir>/<platform>/<modelIdentifier>.<so|dll>``; return ``{platform: path}``.

    ``platforms`` defaults to linux64, and win64 when ``x86_64-w64-mingw32-gcc``
    is on PATH (otherwise ``log`` says that it is skipped and why).  With ``fmi3_xml`` (the FMI
    3.0 description of :mod:`hammerbit.fmu.fmi3_description`) the binaries are FMI 3.0's.
    """
    spec = read_model_description(model_description_xml)
    if platforms is None:
        platforms = select_platforms(log, 3 if fmi3_xml is not None else 2)
    compilers = platform_compilers(platforms, fmi3=fmi3_xml is not None)
    out_dir = Path(out_dir)
    with tempfile.TemporaryDirectory(prefix="hammerbit_native_") as tmp:
        tmp = Path(tmp)
        summary = build_objects(tmp, platforms)
        (tmp / "hb_model.h").write_text(generate_header(spec, wrapper_file="", python_modules=()))
        write_description_header(tmp)
        (tmp / "hb_native.h").write_text(native_header(start_values or {}, summary["layout"]))
        sources, defines = NATIVE_SOURCES, ()
        if fmi3_xml is not None:
            from hammerbit.fmu.fmi3_description import fmi3_header
            (tmp / "hb_fmi3.h").write_text(fmi3_header(fmi3_xml, len(STATES)))
            sources, defines = NATIVE_SOURCES + FMI3_SOURCES, FMI3_DEFINES
        built = link_platforms(compilers, tmp, out_dir, spec.model_identifier, sources, defines)
    return built


def platform_compilers(platforms, *, fmi3: bool) -> dict:
    """``{platform: C compiler}`` for ``platforms``, before any work: a missing cross-compiler, an
    unknown platform or aarch64-linux for FMI 2.0 raises :class:`NativeBuildError` naming it
    (and a bad ``HAMMERBIT_BUILD_CACHE`` ValueError)."""
    cache_enabled()
    compilers = {}
    for plat in platforms:
        if plat not in TARGETS:
            raise NativeBuildError(f"unknown platform {plat!r}; known: {', '.join(TARGETS)}")
        if plat == "linux64":
            try:
                compilers[plat] = find_compiler()
            except FrontBuildError as e:
                raise NativeBuildError(str(e)) from None
        else:
            cross = MINGW_CC if plat == "win64" else AARCH64_CC
            cc = shutil.which(cross)
            if not cc:
                raise NativeBuildError(f"the {plat} binary needs {cross} (Debian: apt-get install "
                                       f"{'gcc-mingw-w64-x86-64' if plat == 'win64' else 'gcc-aarch64-linux-gnu'})")
            if plat == "aarch64-linux" and not fmi3:
                raise NativeBuildError("aarch64-linux is a platform of the FMI 3.0 FMU only (FMI 2.0 "
                                       "names no AArch64 platform)")
            compilers[plat] = cc
    return compilers


def link_platforms(compilers: dict, build_dir: Path, out_dir: Path, model_identifier: str, sources,
                   defines) -> dict:
    """Link each platform's binary from ``build_dir/kernels_<platform>.o`` (:func:`build_objects`)
    and the headers in ``build_dir`` into ``out_dir/<platform>/<modelIdentifier>.<so|dll>``;
    returns ``{platform: path}``."""
    built = {}
    for plat, cc in compilers.items():
        dest = Path(out_dir) / plat / f"{model_identifier}{TARGETS[plat].suffix}"
        dest.parent.mkdir(parents=True, exist_ok=True)
        link_binary(plat, cc, build_dir / f"kernels_{plat}.o", build_dir, dest, sources, defines)
        built[plat] = dest
    return built


# ---------------------------------------------------------------------------
# the FMU
# ---------------------------------------------------------------------------
#: the continuous states of Model Exchange (output variables), in the kernels' order x1..x4
STATES = (("hammer_position", "m/s"), ("hammer_velocity", "m/s2"), ("bit_position", "m/s"),
          ("bit_velocity", "m/s2"))
_UNIT_DEFS = {"m/s2": {"m": "1", "s": "-2"}}


def _c_name(name: str) -> str:
    """A variable name as a C identifier (``der(x)`` -> ``der_x``)."""
    return "".join(c if c.isalnum() or c == "_" else "_" for c in name).rstrip("_")


def native_value_references() -> dict:
    """``{name: value reference}`` of the native HammerBitRock: its table's, then ``der(<state>)``
    of each of :data:`STATES` after it."""
    from hammerbit.model.fmu_description import HAMMER_VARIABLES, value_references
    vrs = value_references(HAMMER_VARIABLES)
    return {**vrs, **{f"der({state})": len(vrs) + k for k, (state, _) in enumerate(STATES)}}


def native_model_description(xml: bytes) -> bytes:
    """The Python flavour's model description for the native binaries: Co-Simulation and Model
    Exchange in one description (the state derivatives ``der(<state>)``, one event indicator per
    event kind of the kernels)."""
    from hammerbit.model.kernel_layouts import N_EVENT_KINDS
    root = ET.fromstring(xml)
    root.set("generationTool", NATIVE_GENERATION_TOOL)
    root.set("numberOfEventIndicators", str(N_EVENT_KINDS))
    cs = root.find("CoSimulation")
    if cs is None:
        raise NativeBuildError("the model description has no <CoSimulation>")
    cs.attrib.pop("needsExecutionTool", None)
    # fmi2GetRealOutputDerivatives: the first and second derivatives of the Real outputs
    # (model_derivatives.c)
    cs.set("maxOutputDerivativeOrder", str(MAX_OUTPUT_DERIVATIVE_ORDER))
    me = ET.Element("ModelExchange", {
        "modelIdentifier": cs.get("modelIdentifier"), "completedIntegratorStepNotNeeded": "true",
        "canGetAndSetFMUstate": cs.get("canGetAndSetFMUstate", "true"),
        "canSerializeFMUstate": cs.get("canSerializeFMUstate", "true")})
    root.insert(list(root).index(cs), me)
    units = root.find("UnitDefinitions")
    if units is not None:
        have = {u.get("name") for u in units}
        for name, base in _UNIT_DEFS.items():
            if name not in have:
                ET.SubElement(ET.SubElement(units, "Unit", {"name": name}), "BaseUnit", base)
    variables = root.find("ModelVariables")
    svs = list(variables)
    index = {sv.get("name"): i + 1 for i, sv in enumerate(svs)}
    vrs, derivs = native_value_references(), []
    for k, (state, unit) in enumerate(STATES):
        sv = ET.SubElement(variables, "ScalarVariable", {
            "name": f"der({state})", "valueReference": str(vrs[f"der({state})"]), "causality": "local",
            "variability": "continuous", "initial": "calculated",
            "description": f"time derivative of {state} in the current hybrid mode"})
        ET.SubElement(sv, "Real", {"derivative": str(index[state]), "unit": unit})
        derivs.append(len(svs) + k + 1)
    structure = root.find("ModelStructure")
    outputs = structure.find("Outputs")
    der_el = ET.Element("Derivatives")
    for i in derivs:
        ET.SubElement(der_el, "Unknown", {"index": str(i)})
    structure.insert(list(structure).index(outputs) + 1 if outputs is not None else 0, der_el)
    init = structure.find("InitialUnknowns")
    if init is None:
        init = ET.SubElement(structure, "InitialUnknowns")
    for i in derivs:
        ET.SubElement(init, "Unknown", {"index": str(i)})
    init[:] = sorted(init, key=lambda u: int(u.get("index")))
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def assemble_native_fmu(python_fmu: Path, out: Path, start_values: dict, *, log=print,
                        fmi_version: int = 2) -> Path:
    """Write the native FMU ``out`` from the model description of the Python flavour's ``python_fmu``
    (an FMI 2.0 FMU, or with ``fmi_version=3`` an FMI 3.0 one)."""
    from hammerbit.fmu.fmi3_description import FMI3_PLATFORMS, fmi3_model_description
    from hammerbit.fmu.reference_results import slave_results
    from hammerbit.model.kernel_layouts import EVENT_NAMES
    from hammerbit.fmu.table_check import check_description
    from hammerbit.model.fmu_description import HAMMER_VARIABLES
    from hammerbit.model.slave import HammerBitRock
    with zipfile.ZipFile(python_fmu) as zf:
        md = native_model_description(zf.read("modelDescription.xml"))
    md3 = fmi3_model_description(md, EVENT_NAMES, HAMMER_VARIABLES) if fmi_version == 3 else None
    check_description(md if md3 is None else md3, HAMMER_VARIABLES, out.name)
    with tempfile.TemporaryDirectory(prefix="hammerbit_native_fmu_") as tmp:
        built = build_binaries(md, Path(tmp), start_values=start_values, log=log, fmi3_xml=md3)
        # the reference results (FMI-LS-REF) from the library's slave with the build's start values
        res = Path(tmp) / "reference_resources"
        res.mkdir()
        (res / "start_values.json").write_text(json.dumps(start_values))
        reference = slave_results(HammerBitRock, "HammerBitRock", md, res)
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", md3 if md3 is not None else md)
            for plat, path in sorted(built.items()):
                folder = FMI3_PLATFORMS[plat] if md3 is not None else plat
                zf.write(path, f"binaries/{folder}/{path.name}")
            # the resource directory every host passes to fmi2Instantiate: the build's start values
            zf.writestr("resources/start_values.json",
                        json.dumps(start_values, indent=1, sort_keys=True) + "\n")
            for name, blob in reference.files().items():
                zf.writestr(name, blob)
        os.replace(tmp_out, out)
    return out


if __name__ == "__main__":  # pragma: no cover
    sys.exit("use: hammerbit fmu build --runtime native")
