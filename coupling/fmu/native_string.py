"""The native flavour of ``Drillstring.fmu``: the string's exact step compiled, no Python on the target.

``hammerbit fmu build-string --runtime native`` builds the FMU whose
``binaries/linux64/Drillstring.so`` and ``binaries/win64/Drillstring.dll`` run
the library's own step kernels (:mod:`hammerbit.model.string_kernels`:
``exchange_step``, which also gives the held force, compiled through
:mod:`hammerbit.fmu.native_kernels`) behind the native FMI front
(``native/front.c``) with the string backend ``native/model_string.c``.

The exact step over a communication step ``h`` needs the matrix exponential
of the string side (and its eigendecomposition for the modal form): the build
computes them with the library, for each form (fixed hook and feed; the
auto-driller) and each step size it is given (default: the default
experiment's step), and writes them into ``resources/string_native.bin``,
with each form's generator (its matrices, and the kept modes' eigenvalues and
inputs).  The FMU takes any step ``h > 0``: one within 1e-9 (relative) of a
built step uses that step's exponentials, any other gets its own from the
compiled kernels of :mod:`hammerbit.model.string_exponentials` (closed form per mode,
or the Pade exponential of the dense form), kept in a cache of
``STEP_CACHE`` step lengths.  The parameters that change the matrices
(``damping_ratio``; the auto-driller's gains) keep their build values:
another value gives ``fmi2Error`` at ``fmi2ExitInitializationMode`` naming
the parameter (the Python flavour recomputes them).  The FMU ships
``string_native.bin`` and ``string_info.json`` (the description, which
``hammerbit cosim --ssp`` reads).  Everything else is the Python flavour's: the model
description's variables, causality, start values and messages.
"""
from __future__ import annotations

import json
import struct
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from hammerbit.model.string_step import BUILT_STEPS

__all__ = ["NATIVE_STRING_TOOL", "DATA_FILE", "STRING_SOURCES", "DEFAULT_STEPS", "string_tables",
           "write_tables", "read_string_arrays", "string_header", "build_native_string_fmu"]

#: ``generationTool`` of the native string FMU's model description
NATIVE_STRING_TOOL = "hammerbit fmu build-string --runtime native"
#: the exact step's matrices in the FMU's resources directory
DATA_FILE = "string_native.bin"
_DATA_MAGIC = b"HBSTRN02"
#: the kind of a form's generator block (step blocks: 0 dense, 1 modal)
GENERATOR = 2
#: the communication step sizes the FMU carries the exponentials of by default [s]
DEFAULT_STEPS = BUILT_STEPS


def _sources():
    from hammerbit.fmu.native import FRONT_SOURCES, SOURCE_DIR
    return tuple(SOURCE_DIR / f for f in (*FRONT_SOURCES, "model_backend.c", "model_common.c", "model_string.c",
                                          "model_string_table.c", "model_string_access.c", "real_repr.c",
                                          "nrt_shim.c", "glibc_compat.c"))


#: C sources of the native string FMU (front, resource URIs, string backend, repr, runtime shim)
STRING_SOURCES = _sources()


def string_tables(build, steps) -> list:
    """The exact step of every form of ``build`` (a :class:`~hammerbit.fmu.build_string.StringBuild`)
    over every step size of ``steps``: ``[(form index, step key, Discretisation, ExactStep)]``.

    The form (modal or dense) is decided at the first step size, as the Python flavour decides
    it at the first built step."""
    from hammerbit.model.string_model import FORMS, string_matrices
    from hammerbit.model.string_step import ExactStep, step_key
    arrays = build.arrays
    sc = build.info["scalars"]
    out = []
    for k, form in enumerate(FORMS):
        if form not in arrays["forms"]:
            continue
        A1, E, frow, rows = string_matrices(arrays, form, arrays["build_values"])
        side = ExactStep(A1, E, frow, sc["interface_stiffness"], sc["interface_damping"], rows, 0.0)
        for h in steps:
            out.append((k, step_key(h), side.discretisation(h), side))
    return out


def _complex_doubles(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.complex128).view(np.float64).ravel()


def _block(form: int, key: float, d, side) -> np.ndarray:
    """One step block of :data:`DATA_FILE` (as ``model_string.c`` reads it), as doubles."""
    if d.modal:
        parts = [side.m_frow, side.m_rows3, d.m_d, d.m_G, d.m_irow]
        n = side.m_frow.shape[0]
        body = [_complex_doubles(p) for p in parts]
        body.append(np.asarray(d.m_icol, dtype=float))
    else:
        n = side.n
        body = [side.frow, side.rows3, d.P]
        body = [np.ascontiguousarray(p, dtype=float).ravel() for p in body]
    return np.concatenate([np.array([form, key, 1.0 if d.modal else 0.0, n], dtype=float), *body])


def _generator(form: int, side) -> np.ndarray:
    """The generator block of a form: what the exponentials of any other step length are computed
    from (``A1, E, frow, rows`` of the string side, and the kept modes' eigenvalues and inputs
    ``V^-1 E`` in the modal form); ``hammerbit cosim --ssp`` reads the side from it too."""
    m = side.m_lam.shape[0] if side.modal else 0
    head = np.array([form, 0.0, float(GENERATOR), side.n, m], dtype=float)
    body = [np.ascontiguousarray(p, dtype=float).ravel() for p in (side.A1, side.E, side.frow, side.rows3)]
    if m:
        body += [_complex_doubles(side.m_lam), _complex_doubles(side.m_B)]
    return np.concatenate([head, *body])


def write_tables(path: Path, tables) -> None:
    """Write :func:`string_tables` and each form's generator into ``path`` (little-endian doubles
    behind a header)."""
    blocks = [_block(*t) for t in tables]
    sides = {}
    for form, _, _, side in tables:
        sides.setdefault(form, side)
    blocks += [_generator(form, side) for form, side in sides.items()]
    data = np.concatenate(blocks).astype("<f8")
    with open(path, "wb") as fh:
        fh.write(_DATA_MAGIC + struct.pack("<qq", len(blocks), data.size))
        fh.write(data.tobytes())


def read_string_arrays(data: bytes, info: dict) -> dict:
    """The string side's arrays (as :func:`hammerbit.model.string_model.load_model` gives them) from
    the generator blocks of a native FMU's :data:`DATA_FILE`: the matrices at the build's parameter
    values, without their derivatives (the native FMU takes no other values)."""
    from hammerbit.model.string_model import FORMS, PARAMETERS
    if data[:8] != _DATA_MAGIC:
        raise ValueError(f"{DATA_FILE}: not a string table of this version")
    nblocks, total = struct.unpack("<qq", data[8:24])
    x = np.frombuffer(data[24:], dtype="<f8", count=total)
    forms, p = {}, 0
    for _ in range(nblocks):
        form, kind, n = int(x[p]), int(x[p + 2]), int(x[p + 3])
        if kind == GENERATOR:
            m = int(x[p + 4])
            p += 5
            f = forms[FORMS[form]] = {"d": {}}
            for key, shape in (("A1", (n, n)), ("E", (n, 2)), ("frow", (n,)), ("rows", (5, n))):
                size = int(np.prod(shape))
                f[key] = x[p:p + size].reshape(shape).copy()
                p += size
            p += 6 * m
        else:
            p += 4 + (28 * n + 6 if kind else n + 5 * n + (n + 1) * (n + 6))   # as model_string.c reads it
    sc = info["scalars"]
    values = {"damping_ratio": sc["damping_ratio"], "proportional_gain": info["proportional_gain"],
              "integral_gain": info["integral_gain"]}
    return {"forms": forms, "build_values": {k: float(values[k]) for k in PARAMETERS}}


def _c_str(text: str) -> str:
    from hammerbit.fmu.native import c_string
    return c_string(text)


def _c_ident(name: str) -> str:
    return "".join(c if c.isalnum() or c == "_" else "_" for c in name)


def string_header(build, steps) -> str:
    """Text of ``hs_string.h``: value references (from the table), start and build values,
    ranges, constants."""
    from hammerbit.model.string_kernels import N_COEFFS
    from hammerbit.model.string_model import OUTPUT_ROWS
    from hammerbit.model.string_slave import INPUT_LIMIT, MAX_FEED, MAX_GAIN, TIME_TOLERANCE
    from hammerbit.model.validation import RANGES
    from hammerbit.model.string_exponentials import PADE_WORK
    from hammerbit.model.string_step import BUILT_STEP_MATCH, STEP_CACHE
    from hammerbit.model.fmu_description import STRING_VARIABLES, value_references
    vrs = value_references(STRING_VARIABLES)
    info, sc, bv = build.info, build.info["scalars"], build.arrays["build_values"]
    starts = {"damping_ratio": sc["damping_ratio"], "wob": sc["wob"],
              "hammer_position_at_rest": info["hammer_position_at_rest"],
              "feed_velocity": info["feed_velocity"], "proportional_gain": info["proportional_gain"],
              "integral_gain": info["integral_gain"], "extrapolation": 2,
              "top_condition": info["top_condition"], "hook_load": sc["hook_load"]}
    buoyed = sc["buoyed_weight"]
    lines = ["/* generated by hammerbit.fmu.native_string from the string and hammerbit.model.fmu_description */"]
    lines += [f"#define HS_VR_{_c_ident(n)} {vr}u" for n, vr in sorted(vrs.items())]
    lines += [f"#define HS_START_{n} {float(v)!r}" if n not in ("extrapolation", "top_condition")
              else f"#define HS_START_{n} {int(v)}" for n, v in starts.items()]
    lines += [f"#define HS_BUILD_{n} {float(v)!r}" for n, v in bv.items()]
    lines += [f"#define HS_BUOYED_WEIGHT {float(buoyed)!r}",
              f"#define HS_INTERFACE_STIFFNESS {float(sc['interface_stiffness'])!r}",
              f"#define HS_INTERFACE_DAMPING {float(sc['interface_damping'])!r}",
              f"#define HS_STRING_LENGTH {float(info['length_m'])!r}",
              f"#define HS_STRING_STATES {int(sc['string_states'])}",
              f"#define HS_HAS_AUTO {int('auto' in build.arrays['forms'])}",
              f"#define HS_AUTO_REFUSED {_c_str(str(info.get('auto_driller_refused')))}",
              f"#define HS_INPUT_LIMIT {float(INPUT_LIMIT)!r}",
              f"#define HS_MAX_FEED {float(MAX_FEED)!r}",
              f"#define HS_MAX_GAIN {float(MAX_GAIN)!r}",
              f"#define HS_TIME_TOLERANCE {float(TIME_TOLERANCE)!r}",
              f"#define HS_STATE_TIME_LIMIT {float(RANGES['fmu.time'].hi)!r}",
              f"#define HS_WOB_RANGE_TEXT {_c_str(f'[0, {buoyed:.6g}] N (the buoyed weight)')}",
              f"#define HS_POSITION_RANGE_TEXT {_c_str(f'[-{INPUT_LIMIT:g}, {INPUT_LIMIT:g}] m')}",
              f"#define HS_FEED_RANGE_TEXT {_c_str(f'[-{MAX_FEED:.4g}, {MAX_FEED:.4g}] m/s (1000 m/h)')}",
              f"#define HS_BUILT_STEP_MATCH {float(BUILT_STEP_MATCH)!r}",
              f"#define HS_STEP_CACHE {int(STEP_CACHE)}",
              f"#define HS_PADE_WORK {int(PADE_WORK)}",
              f"#define HS_DATA_FILE {_c_str(DATA_FILE)}",
              f"#define HS_DATA_MAGIC {_c_str(_DATA_MAGIC.decode('ascii'))}",
              f"#define HS_N_COEFFS {N_COEFFS}",
              f"#define HS_N_ROWS {len(OUTPUT_ROWS)}"]
    lines += [f"#define HS_ROW_{_c_ident(r).upper()} {i}" for i, r in enumerate(OUTPUT_ROWS)] + [""]
    return "\n".join(lines)


def native_string_description(xml: bytes) -> bytes:
    """The Python flavour's model description for the native binaries: no execution tool, FMU
    states, any communication step."""
    root = ET.fromstring(xml)
    root.set("generationTool", NATIVE_STRING_TOOL)
    cs = root.find("CoSimulation")
    cs.attrib.pop("needsExecutionTool", None)
    cs.set("canGetAndSetFMUstate", "true")
    cs.set("canSerializeFMUstate", "true")
    cs.set("canHandleVariableCommunicationStepSize", "true")
    # fmi2SetRealInputDerivatives: the hammer's motion over a step as their polynomial
    cs.set("canInterpolateInputs", "true")
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def build_native_string_fmu(string_arg, out=None, *, steps=None, build=None, log=print, fmi_version=2,
                            **kw) -> Path:
    """Build the native ``Drillstring.fmu`` of ``string_arg`` (TOML path or example name).

    ``steps``: the communication step sizes [s] it carries (default :data:`DEFAULT_STEPS`);
    ``fmi_version``: 2, or 3 for an FMI 3.0 FMU (:mod:`hammerbit.fmu.fmi3_description`);
    ``kw`` go to :func:`~hammerbit.fmu.build_string.string_build`."""
    from hammerbit.fmu.fmi3_description import FMI3_PLATFORMS, fmi3_header, fmi3_model_description
    from hammerbit.fmu.native_build import FMI3_DEFINES, FMI3_SOURCES
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version = {fmi_version!r} is out of range: allowed 2 or 3")
    from hammerbit.fmu.compile_cache import cache_enabled
    cache_enabled()                       # a bad HAMMERBIT_BUILD_CACHE is refused before any work
    from hammerbit.fmu.build_string import MODEL_NAME, build_string_fmu, string_build, string_fmu_path
    from hammerbit.fmu.c_description import write_description_header
    from hammerbit.fmu.native import generate_header, read_model_description
    from hammerbit.fmu.native_build import link_platforms, platform_compilers, select_platforms
    from hammerbit.fmu.native_kernels import build_objects
    from hammerbit.fmu.reference_results import slave_results
    from hammerbit.model.string_model import INFO_FILE
    from hammerbit.fmu.table_check import check_description
    from hammerbit.model.fmu_description import STRING_VARIABLES
    from hammerbit.model.string_slave import Drillstring
    steps = tuple(float(h) for h in (DEFAULT_STEPS if steps is None else steps))
    for h in steps:
        if not (0.0 < h < float("inf")):
            raise ValueError(f"--step = {h!r} is out of range: allowed a finite step size > 0 s")
    build = string_build(string_arg, **kw) if build is None else build
    out = string_fmu_path(out)
    # the Python flavour in a directory of its own: the link's directory (-I) holds only what the
    # link reads, since the compile cache keys on every file in it
    with tempfile.TemporaryDirectory(prefix="hammerbit_native_string_") as tmp, \
            tempfile.TemporaryDirectory(prefix="hammerbit_string_python_") as python_tmp:
        tmp, python_dir = Path(tmp), Path(python_tmp)
        py_fmu = build_string_fmu(string_arg, python_dir / f"{MODEL_NAME}.fmu", build=build)
        with zipfile.ZipFile(py_fmu) as zf:
            md = native_string_description(zf.read("modelDescription.xml"))
            info = json.loads(zf.read(f"resources/{INFO_FILE}"))
            zf.extractall(python_dir / "unzipped", [n for n in zf.namelist() if n.startswith("resources/")])
        # the reference results (FMI-LS-REF) from the library's slave on the Python flavour's resources
        reference = slave_results(Drillstring, MODEL_NAME, md, python_dir / "unzipped" / "resources")
        info["steps"] = list(steps)
        write_tables(tmp / DATA_FILE, string_tables(build, steps))
        spec = read_model_description(md)
        (tmp / "hb_model.h").write_text(generate_header(spec, wrapper_file="", python_modules=()))
        write_description_header(tmp)
        (tmp / "hs_string.h").write_text(string_header(build, steps))
        md3, sources, defines = None, STRING_SOURCES, ()
        if fmi_version == 3:
            md3 = fmi3_model_description(md, (), STRING_VARIABLES)
            (tmp / "hb_fmi3.h").write_text(fmi3_header(md3, 0))
            sources, defines = STRING_SOURCES + FMI3_SOURCES, FMI3_DEFINES
        check_description(md if md3 is None else md3, STRING_VARIABLES, out.name)
        compilers = platform_compilers(select_platforms(log, fmi_version), fmi3=fmi_version == 3)
        build_objects(tmp, list(compilers), kernels="string")
        built = link_platforms(compilers, tmp, tmp / "bin", spec.model_identifier, sources, defines)
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", md if md3 is None else md3)
            for plat, path in sorted(built.items()):
                zf.write(path, f"binaries/{plat if md3 is None else FMI3_PLATFORMS[plat]}/{path.name}")
            zf.write(tmp / DATA_FILE, f"resources/{DATA_FILE}")
            # the description (hammerbit cosim --ssp reads it, and the side from DATA_FILE)
            zf.writestr(f"resources/{INFO_FILE}", json.dumps(info, indent=1))
            for name, blob in reference.files().items():
                zf.writestr(name, blob)
        tmp_out.replace(out)
    return out
