"""Native front of a pythonfmu co-simulation FMU: its C sources and their build.

``binaries/linux64/<modelIdentifier>.so`` of the FMU is the front (``front.c``);
pythonfmu's export library is shipped next to it as ``<wrapper_name>.so`` and
opened by the front once Python is in the process (see ``README.md`` in this
directory for what the front does and why).

The front is compiled per FMU: :func:`build_front` reads the model description
(GUID, model identifier, variables, log categories, the value reference of the
slave's ``last_status`` variable), writes the header ``hb_model.h`` for
``front.c`` and runs the system C compiler (``$CC``, else ``cc``, ``gcc`` or ``clang`` on PATH)::

    from hammerbit.fmu.native import build_front
    so = build_front(Path("modelDescription.xml").read_text(), fmu_dir / "binaries" / "linux64",
                     wrapper_name="HammerBitRock_python")
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from hammerbit.fmu.compile_cache import cache_enabled, compile_output

__all__ = ["FrontBuildError", "FrontSpec", "Variable", "STATUS_VARIABLE", "PYTHON_MODULES",
           "SOURCE_DIR", "FRONT_SOURCES", "SOURCES", "c_string", "read_model_description", "generate_header",
           "find_compiler", "build_front"]

#: directory of the C sources (package data)
SOURCE_DIR = Path(__file__).resolve().parent
#: the FMI 2.0 front's C sources (front.h says what each holds), for every flavour
FRONT_SOURCES = ("front.c", "front_core.c", "front_state.c", "front_inquiry.c", "front_me.c",
                 "resource_uri.c")
SOURCES = tuple(SOURCE_DIR / f for f in (*FRONT_SOURCES, "python_embed.c", "pythonfmu_wrapper.c"))

#: name of the slave's Integer variable holding the FMI status its last call should have returned
STATUS_VARIABLE = "last_status"

#: modules the Python found by the front must import (checked before the slave is created)
PYTHON_MODULES = ("numpy", "numba")

# instance states of front.c in which fmi2Set* may write a variable (bit masks)
_ST_INSTANTIATED, _ST_INIT, _ST_STEP = 1, 2, 4
_TYPES = ("Real", "Integer", "Boolean", "String")
#: value references below this get a direct index in the front's tables (4 x this many shorts at
#: most); a model description with larger ones is searched by bisection instead
VR_INDEX_LIMIT = 4096


class FrontBuildError(RuntimeError):
    """The native front cannot be built (no compiler, unusable model description, compile error)."""


@dataclass(frozen=True)
class Variable:
    """One scalar variable of the model description, as the front checks it."""

    name: str
    type: str                 #: Real, Integer, Boolean or String
    value_reference: int
    causality: str
    variability: str
    initial: str | None       #: as written, or the FMI 2.0 default when absent (None for inputs)

    @property
    def set_mask(self) -> int:
        """States in which fmi2Set* may write it (FMI 2.0.4, section 3.2.3 / 4.2.4)."""
        if self.variability == "constant":
            return 0
        if self.causality == "input":
            return _ST_INSTANTIATED | _ST_INIT | _ST_STEP
        if self.causality == "parameter":
            base = _ST_INSTANTIATED | _ST_INIT
            return base | _ST_STEP if self.variability == "tunable" else base
        if self.initial in ("exact", "approx"):
            return _ST_INSTANTIATED | _ST_INIT
        return 0


@dataclass(frozen=True)
class FrontSpec:
    """What the front compiles in from ``modelDescription.xml``."""

    guid: str
    model_identifier: str
    variables: tuple[Variable, ...]
    log_categories: tuple[str, ...]
    status_vr: int | None     #: value reference of ``last_status`` (None: the slave has none)
    model_exchange: bool = False   #: the description has <ModelExchange> (the native flavour)
    can_get_set_state: bool = False   #: <CoSimulation canGetAndSetFMUstate="true">
    can_serialize_state: bool = False   #: <CoSimulation canSerializeFMUstate="true">


def _default_initial(causality: str, variability: str) -> str | None:
    if causality in ("input", "independent"):
        return None
    if causality == "parameter" or variability == "constant":
        return "exact"
    return "calculated"


def read_model_description(xml) -> FrontSpec:
    """Parse a model description given as XML text (``str``/``bytes``) or a file path."""
    if isinstance(xml, os.PathLike):
        xml = Path(xml).read_bytes()
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as e:
        raise FrontBuildError(f"the model description is not valid XML: {e}") from None
    if root.tag != "fmiModelDescription" or root.get("fmiVersion") != "2.0":
        raise FrontBuildError("not an FMI 2.0 model description (fmiModelDescription fmiVersion='2.0')")
    guid = root.get("guid")
    cs = root.find("CoSimulation")
    if not guid or cs is None or not cs.get("modelIdentifier"):
        raise FrontBuildError("the model description has no guid or no CoSimulation modelIdentifier")
    variables = []
    for sv in root.iter("ScalarVariable"):
        kind = next((c for c in sv if c.tag in _TYPES), None)
        if kind is None:
            raise FrontBuildError(f"variable {sv.get('name')!r} has no supported type element")
        causality = sv.get("causality", "local")
        variability = sv.get("variability", "continuous")
        variables.append(Variable(
            name=sv.get("name"), type=kind.tag, value_reference=int(sv.get("valueReference")),
            causality=causality, variability=variability,
            initial=sv.get("initial") or _default_initial(causality, variability)))
    seen = set()
    for v in variables:
        key = (v.type, v.value_reference)
        if key in seen:
            raise FrontBuildError(f"two {v.type} variables share the value reference {v.value_reference}")
        seen.add(key)
    status = [v for v in variables if v.name == STATUS_VARIABLE]
    if status and status[0].type != "Integer":
        raise FrontBuildError(f"{STATUS_VARIABLE!r} must be an Integer variable, not {status[0].type}")
    cats = tuple(c.get("name") for c in root.iter("Category") if c.get("name"))
    return FrontSpec(guid=guid, model_identifier=cs.get("modelIdentifier"), variables=tuple(variables),
                     log_categories=cats, status_vr=status[0].value_reference if status else None,
                     model_exchange=root.find("ModelExchange") is not None,
                     can_get_set_state=cs.get("canGetAndSetFMUstate") == "true",
                     can_serialize_state=cs.get("canSerializeFMUstate") == "true")


def c_string(s: str) -> str:
    """``s`` as a C string literal (UTF-8 bytes, non-printable ones as octal escapes)."""
    out = []
    for b in s.encode("utf-8"):
        c = chr(b)
        if c in '"\\':
            out.append("\\" + c)
        elif 32 <= b < 127 and c != "?":
            out.append(c)
        else:
            out.append(f"\\{b:03o}")
    return '"' + "".join(out) + '"'


def _vr_index(order) -> list:
    """``HB_VAR_INDEX[type][vr]``: the row of each variable in ``HB_VARS`` (-1: none), so that the
    front finds a value reference at once; with ``HB_VR_INDEX_LEN`` 0 (value references beyond
    :data:`VR_INDEX_LIMIT`) the front searches ``HB_VARS`` instead."""
    top = max((v.value_reference for v in order), default=0)
    if top >= VR_INDEX_LIMIT:
        return ["#define HB_VR_INDEX_LEN 0u"]
    index = [[-1] * (top + 1) for _ in _TYPES]
    for row, v in enumerate(order):
        index[_TYPES.index(v.type)][v.value_reference] = row
    return [f"#define HB_VR_INDEX_LEN {top + 1}u",
            f"static const short HB_VAR_INDEX[{len(_TYPES)}][HB_VR_INDEX_LEN] = {{",
            *(f"    {{{', '.join(map(str, r))}}}," for r in index), "};"]


def generate_header(spec: FrontSpec, *, wrapper_file: str, python_modules=PYTHON_MODULES) -> str:
    """Text of ``hb_model.h``: the model's tables for front.c (included there only)."""
    from hammerbit.model.validation import RANGES
    order = sorted(spec.variables, key=lambda v: (_TYPES.index(v.type), v.value_reference))
    types = {"Real": "HB_REAL", "Integer": "HB_INTEGER", "Boolean": "HB_BOOLEAN", "String": "HB_STRING"}
    rows = [f"    {{{types[v.type]}, {v.value_reference}u, {v.set_mask}, {c_string(v.name)}, "
            f"{c_string(v.causality + ', ' + v.variability)}}}," for v in order]
    cats = ", ".join(c_string(c) for c in spec.log_categories) or "NULL"
    lines = [
        "/* generated by hammerbit.fmu.native.build_front from modelDescription.xml */",
        f"#define HB_GUID {c_string(spec.guid)}",
        f"#define HB_MODEL_IDENTIFIER {c_string(spec.model_identifier)}",
        f"#define HB_WRAPPER_FILE {c_string(wrapper_file)}",
        f"#define HB_HAS_STATUS_VR {0 if spec.status_vr is None else 1}",
        f"#define HB_STATUS_VR {0 if spec.status_vr is None else spec.status_vr}u",
        f"#define HB_HAS_ME {int(spec.model_exchange)}",
        f"#define HB_CAN_GET_SET_STATE {int(spec.can_get_set_state)}",
        f"#define HB_CAN_SERIALIZE_STATE {int(spec.can_serialize_state)}",
        f"#define HB_TIME_LIMIT {RANGES['fmu.time'].hi!r}",
        f"#define HB_PYTHON_MODULES {c_string(' '.join(python_modules))}",
        f"#define HB_NVARS {len(order)}u",
        f"static const hb_var HB_VARS[{max(len(order), 1)}] = {{",
        *(rows or ["    {0, 0u, 0, \"\", \"\"},"]),
        "};",
        *_vr_index(order),
        f"#define HB_NCATEGORIES {len(spec.log_categories)}u",
        f"static const char *const HB_CATEGORIES[{max(len(spec.log_categories), 1)}] = {{{cats}}};",
        "",
    ]
    return "\n".join(lines)


def find_compiler() -> str:
    """The C compiler: ``$CC``, else ``cc``, ``gcc`` or ``clang`` on PATH."""
    env = os.environ.get("CC")
    candidates = [env] if env else ["cc", "gcc", "clang"]
    for c in candidates:
        path = shutil.which(c)
        if path:
            return path
    raise FrontBuildError(
        "building the FMU's native front needs a C compiler, and none was found "
        f"({'CC=' + env if env else 'cc, gcc and clang are not on PATH'}); install one "
        "(e.g. apt-get install gcc) or set CC")


def build_front(model_description_xml, out_dir, *, model_identifier: str | None = None,
                wrapper_name: str | None = None, python_modules=PYTHON_MODULES,
                cc: str | None = None) -> Path:
    """Compile the native front for a model description; return the path of ``<id>.so``.

    ``model_description_xml`` is the XML text (or a path).  ``model_identifier``
    defaults to the model description's; ``wrapper_name`` (without ``.so``) is
    the name pythonfmu's library is shipped under next to the front, by
    default ``<model_identifier>_python``.  Raises :class:`FrontBuildError`.
    """
    if not sys.platform.startswith("linux"):
        raise FrontBuildError(f"the native front is built for Linux only (this is {sys.platform})")
    spec = read_model_description(model_description_xml)
    ident = model_identifier or spec.model_identifier
    if ident != spec.model_identifier:
        raise FrontBuildError(f"model_identifier {ident!r} differs from the model description's "
                              f"{spec.model_identifier!r}")
    wrapper = (wrapper_name or f"{ident}_python")
    if not wrapper.endswith(".so"):
        wrapper += ".so"
    if wrapper == f"{ident}.so":
        raise FrontBuildError(f"wrapper_name {wrapper_name!r} would overwrite the front itself")
    cache_enabled()                       # a bad HAMMERBIT_BUILD_CACHE fails before any work
    compiler = cc or find_compiler()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / f"{ident}.so"
    with tempfile.TemporaryDirectory(prefix="hammerbit_front_") as tmp:
        (Path(tmp) / "hb_model.h").write_text(generate_header(spec, wrapper_file=wrapper,
                                                              python_modules=python_modules))
        (Path(tmp) / "hb_python.h").write_text(
            f"#define HB_WRAPPER_FILE {c_string(wrapper)}\n"
            f"#define HB_PYTHON_MODULES {c_string(' '.join(python_modules))}\n")
        target = Path(tmp) / out.name
        # the temporary directory's name must not reach the binary: the compile cache keys on
        # its contents, not on its name
        cmd = [compiler, "-std=gnu11", "-O2", "-fPIC", "-shared", "-fvisibility=hidden",
               "-Wall", "-Wextra", "-Wno-unused-parameter", f"-ffile-prefix-map={tmp}=.", "-I", tmp,
               "-I", str(SOURCE_DIR), "-o", str(target), *(str(f) for f in SOURCES),
               "-Wl,-z,nodelete", "-Wl,-Bsymbolic", "-Wl,--no-as-needed", "-l:libdl.so.2", "-lpthread"]
        compile_output(cmd, target, scratch=(tmp,), what="compiling the native front", error=FrontBuildError)
        shutil.copyfile(target, out)
    return out
