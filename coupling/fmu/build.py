"""Build ``HammerBitRock.fmu``, the FMI 2.0 co-simulation FMU of the hammer-bit-rock model.

Works from any install of hammerbit (the runtime the FMU carries is the
installed package :mod:`hammerbit.model`).  The steps:

1. **Stage** the runtime as the package ``hammerbit_fmu_runtime_<hash>`` and
   the pythonfmu entry module ``hammerbit_fmu_slave_<hash>``, where ``<hash>``
   is the hash of the runtime sources: builds of different code run side by
   side in one Python process; builds of the same code share one import (the
   start values of a build travel in ``resources/start_values.json``).
2. **Compile the kernels once** in a subprocess for numba's portable CPU
   target (``NUMBA_CPU_NAME=generic``, no extra features) into the package's
   ``_compiled/`` directory; a new process must then load them with nothing
   compiled (that subprocess itself if it compiled nothing, else a second one).
   The compiled code is kept in ``<user cache>/fmu-build/`` so a rebuild of the
   same code takes seconds.
3. **pythonfmu** writes the FMU; the build then edits ``modelDescription.xml``
   (outputs declare ``dependencies=""``: no direct feedthrough) and sets its
   GUID to a fingerprint of it and the runtime (:mod:`hammerbit.fmu.guid`).
4. **Native front** (when :mod:`hammerbit.fmu.native` is installed): pythonfmu's
   binary is renamed ``<id>_python.so`` and the front, compiled with the
   system C compiler through the compile cache (:mod:`hammerbit.fmu.compile_cache`),
   becomes ``binaries/linux64/<id>.so``.

From Python::

    from hammerbit.fmu.build import build_fmu
    path = build_fmu("dist/HammerBitRock.fmu", start_values={"hammer_mass": 30.0})

From the shell: ``hammerbit fmu build [--out PATH] [--set NAME=VALUE ...]``.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import textwrap
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Optional
from xml.etree import ElementTree as ET

from hammerbit.fmu.compile_cache import cache_enabled
from hammerbit.fmu.guid import content_guid, replace_guid

__all__ = ["MODEL_NAME", "RUNTIME_PREFIX", "ENTRY_PREFIX", "RUNTIMES", "BuildOptions", "FMUBuildError",
           "UnknownVariableError", "build_fmu", "add_native_front", "runtime_dir", "runtime_files", "build_hash",
           "check_start_values", "default_output"]

MODEL_NAME = "HammerBitRock"
RUNTIME_PREFIX = "hammerbit_fmu_runtime"   # + "_<hash>": the runtime package inside the FMU
ENTRY_PREFIX = "hammerbit_fmu_slave"       # + "_<hash>": pythonfmu's slave module (resources/<name>.py)
WRAPPER_SUFFIX = "_python"                 # pythonfmu's binary beside the native front
_HASH_LEN = 12
#: the runtime flavours of the FMU (BuildOptions.runtime); the first is the default
RUNTIMES = ("pythonfmu", "native")


class FMUBuildError(RuntimeError):
    """The FMU could not be built (the message says which step failed and why)."""


class UnknownVariableError(ValueError):
    """A start value names no parameter or input of the FMU."""

    def __init__(self, name: str, known):
        self.name = name
        super().__init__(f"{name!r} is not a parameter or input of {MODEL_NAME}; known: "
                         f"{', '.join(sorted(known))}")


@dataclass(frozen=True)
class BuildOptions:
    """Options of :func:`build_fmu` (keyword-only).

    Attributes
    ----------
    start_values : mapping
        ``{variable: value}``: start values of FMU parameters and inputs
        (SI units, FMU variable names) replacing the lab preset's.
    portable_cache : bool
        Ship the kernels compiled for the portable CPU target (instant start).
        False: the FMU compiles them on its first use on a machine.
    native_front : bool
        Put the native front library (:mod:`hammerbit.fmu.native`) in front
        of pythonfmu's binary when that package is installed.
    python : str
        Python executable that compiles the kernels (default: this one; it must
        be the Python the FMU will run in, same minor version and numba).
    runtime : {"pythonfmu", "native"}
        ``pythonfmu``: the model runs in Python inside the host (the default).
        ``native``: the binaries hold the compiled kernels and need no Python
        (:mod:`hammerbit.fmu.native_build`; ``portable_cache`` and
        ``native_front`` do not apply).
    fmi_version : {2, 3}
        The FMI version of the FMU (3: native runtime only; :mod:`hammerbit.fmu.fmi3_description`).
    """

    start_values: Mapping[str, float] = field(default_factory=dict)
    portable_cache: bool = True
    native_front: bool = True
    python: str = sys.executable
    runtime: str = "pythonfmu"
    fmi_version: int = 2


def runtime_dir() -> Path:
    """Directory of the installed runtime package (:mod:`hammerbit.model`)."""
    from hammerbit import model
    return Path(model.__file__).resolve().parent


#: modules the HammerBitRock FMU's runtime cannot do without
HAMMER_RUNTIME_MODULES = ("__init__.py", "slave.py", "stepping.py", "kernel_driver.py", "params.py",
                          "numba_cache.py", "build_info.py")


def runtime_files(needed=HAMMER_RUNTIME_MODULES) -> list:
    """The runtime sources an FMU carries: every module of :mod:`hammerbit.model` (the build
    refuses a runtime package that lacks one of ``needed``)."""
    files = sorted(runtime_dir().glob("*.py"))
    names = {p.name for p in files}
    for required in needed:
        if required not in names:
            raise FMUBuildError(f"the runtime package {runtime_dir()} lacks {required}")
    return files


def build_hash(files=None) -> str:
    """Hash of the runtime sources (names and contents): names the FMU's Python modules."""
    h = hashlib.sha256()
    for f in sorted(files or runtime_files(), key=lambda p: p.name):
        if f.name == "build_info.py":
            continue                      # rewritten by the build itself
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:_HASH_LEN]


def default_output() -> Path:
    """``dist/HammerBitRock.fmu`` in the current directory."""
    return Path("dist") / f"{MODEL_NAME}.fmu"


def check_start_values(values: Mapping[str, float]) -> dict:
    """Validated start values ``{name: value}`` (UnknownVariableError / ParameterError name what was typed)."""
    from hammerbit.model.fmu_variables import INPUTS, input_range, start_values
    from hammerbit.model.slave import HammerBitRock
    from hammerbit.model.validation import check_range
    known = start_values()
    for name in values:
        if name not in known:
            raise UnknownVariableError(name, known)
    vals = start_values(values)
    rig, _ = HammerBitRock._validate({k: v for k, v in vals.items() if k not in ("preload", "harmonic_force")})
    for name in (v.name for v in INPUTS):   # bounded by the static friction threshold of these parameters
        check_range(name, vals[name], input_range(name, rig.scales.friction_force))
    return {name: vals[name] for name in values}


# ---------------------------------------------------------------------------
# generated sources
# ---------------------------------------------------------------------------
_ENTRY_SOURCE = '''"""Entry module of the {model} FMU (runtime build {hash}), imported by pythonfmu from resources/.

The model lives in the package ``{pkg}`` (a copy of hammerbit.model).
"""
import ctypes as _ctypes

# pythonfmu 0.7.0's native findClass() runs this file's code again in this
# module's globals on every fmi2Instantiate and then releases one reference to
# that dict which it never owned.  One extra reference per execution balances it.
_ctypes.pythonapi.Py_IncRef.argtypes = [_ctypes.py_object]
_ctypes.pythonapi.Py_IncRef.restype = None
_ctypes.pythonapi.Py_IncRef(globals())

from {pkg} import numba_cache_place as _place  # noqa: E402

_place.select_shipped_target()  # before numba is imported: the shipped kernels' CPU target
from {pkg}.slave import {model}  # noqa: E402,F401
'''

_BUILD_INFO = '''"""Identity of this FMU build (written by hammerbit fmu build)."""

#: Hash of the runtime sources of this build.
BUILD_HASH = {hash!r}

#: File in the FMU's resources directory with {{variable name: start value}} of the build.
START_VALUES_FILE = "start_values.json"
'''

# run in a subprocess with the portable CPU target: every kernel the FMU uses, on the paths
# a run takes (no impact, impact); prints the numba cache hits/misses
_EXERCISE = textwrap.dedent('''
    import importlib, json, sys
    sys.path.insert(0, sys.argv[1])
    pkg = sys.argv[2]
    nc = importlib.import_module(pkg + ".numba_cache")
    S = importlib.import_module(pkg + ".slave")

    def run(impact):
        s = S.HammerBitRock(instance_name="compile")
        vr = {v.name: k for k, v in s.vars.items()}
        s.setup_experiment(0.0)
        if impact:
            s.set_boolean([vr["impact_enabled"]], [True])
            s.set_real([vr["amplitude"]], [0.06 * s._F0])
        s.exit_initialization_mode()
        assert s.last_status in (0, 1), s.log_queue[-1].msg
        reals = [k for k, v in s.vars.items() if type(v).__name__ in ("Real", "RealVar")]
        for k in range(400):
            assert s.do_step(k * 5e-3, 5e-3), s.log_queue[-1].msg
            s.get_real(reals)
        return s.get_integer([vr["impact_count"]])[0]

    impacts = run(False), run(True)
    hits, misses = nc.kernel_cache_counts()
    print(json.dumps({"decision": nc.DECISION, "hits": hits, "misses": misses, "impacts": impacts}))
''')


def _exercise(python: str, staging: Path, pkg: str) -> dict:
    from hammerbit.model.numba_target import PORTABLE_ENV
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", **PORTABLE_ENV)
    env.pop("PYTHONPATH", None)
    r = subprocess.run([python, "-c", _EXERCISE, str(staging), pkg], capture_output=True, text=True,
                       env=env, timeout=1800)
    if r.returncode != 0:
        raise FMUBuildError(f"compiling the kernels for the FMU failed (exit {r.returncode}):\n"
                            f"{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def _portable_cache(pkg_dir: Path, python: str) -> dict:
    """Compile the kernels for the portable target into ``pkg_dir/_compiled``; check they load."""
    from hammerbit.model.numba_cache_place import MANIFEST, user_cache_root
    keep = Path(user_cache_root()) / "fmu-build" / pkg_dir.name
    try:
        keep.mkdir(parents=True, exist_ok=True)
        compiled = keep
    except OSError:
        compiled = pkg_dir.parent / "_compiled_build"      # no writable cache: compile every build
        compiled.mkdir()
    manifest = _python_manifest(python)
    (compiled / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    target = pkg_dir / "_compiled"
    target.symlink_to(compiled, target_is_directory=True)
    first = _exercise(python, pkg_dir.parent, pkg_dir.name)
    if not first["decision"]["shipped"]:
        raise FMUBuildError(f"the build's Python did not use the portable target: {first['decision']}")
    # a first run that compiled nothing was already a new process loading every kernel from the
    # cache: the check would repeat it
    check = first if not first["misses"] else _exercise(python, pkg_dir.parent, pkg_dir.name)
    if check["misses"]:
        raise FMUBuildError(f"the compiled kernels do not load in a new process ({check['misses']} "
                            f"compiled again); numba cache in {compiled}")
    target.unlink()
    shutil.copytree(compiled, target, ignore=shutil.ignore_patterns("*.tmp.*", "__pycache__"))
    return {"compiled_now": first["misses"], "loaded": check["hits"], "manifest": manifest}


def _python_manifest(python: str) -> dict:
    if Path(python).resolve() == Path(sys.executable).resolve():
        from importlib.metadata import version
        return {"numba": version("numba"), "python": "%d.%d" % sys.version_info[:2],
                "machine": platform.machine(), "cpu_name": "generic"}
    code = ("import json, platform, sys; from importlib.metadata import version; "
            "print(json.dumps({'numba': version('numba'), 'python': '%d.%d' % sys.version_info[:2], "
            "'machine': platform.machine(), 'cpu_name': 'generic'}))")
    r = subprocess.run([python, "-c", code], capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        raise FMUBuildError(f"{python} cannot report its numba version: {r.stderr[-1000:]}")
    return json.loads(r.stdout)


# ---------------------------------------------------------------------------
# model description and native front
# ---------------------------------------------------------------------------
def _edit_model_description(xml: bytes) -> bytes:
    """Outputs declare ``dependencies=""`` (no direct feedthrough from the inputs)."""
    root = ET.fromstring(xml)
    outputs = root.find("ModelStructure/Outputs")
    if outputs is None:
        raise FMUBuildError("modelDescription.xml has no <ModelStructure><Outputs>")
    for unknown in outputs.findall("Unknown"):
        unknown.set("dependencies", "")
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def pythonfmu_builder():
    """pythonfmu's ``FmuBuilder``, from a pythonfmu package that carries its binaries.

    A pythonfmu FMU run in this process (fmpy in a Python host) imports the copy of pythonfmu
    that pythonfmu's builder packs into the FMU's resources: it stays in ``sys.modules`` once the
    FMU is freed, and its resources directory stays on ``sys.path`` (while that directory exists,
    an import finds the copy again).  That copy has no binaries, so a build through it would write
    an FMU without any.  Such a copy is forgotten, and the package imported past every path entry
    that holds one."""
    import sys
    loaded = [sys.modules.get(name) for name in ("pythonfmu", "pythonfmu.builder")]
    if any(m is not None and not _has_binaries(Path(m.__file__).parent) for m in loaded):
        for name in [n for n in sys.modules if n == "pythonfmu" or n.startswith("pythonfmu.")]:
            del sys.modules[name]
    kept = list(sys.path)
    sys.path[:] = [p for p in kept if not _shadows(Path(p or ".") / "pythonfmu")]
    try:
        from pythonfmu import FmuBuilder
    finally:
        sys.path[:] = kept
    return FmuBuilder


def _has_binaries(package: Path) -> bool:
    """The pythonfmu package directory ``package`` carries pythonfmu's binaries (an FMU's copy does
    not, nor does one whose directory is gone)."""
    return (package / "resources" / "binaries").is_dir()


def _shadows(package: Path) -> bool:
    """``package`` (``<sys.path entry>/pythonfmu``) is a copy an import would find first."""
    return (package / "__init__.py").is_file() and not _has_binaries(package)


def _native_front():
    """``hammerbit.fmu.native.build_front``, or None if that package is not installed."""
    try:
        from hammerbit.fmu.native import build_front
    except ModuleNotFoundError as e:
        if e.name not in ("hammerbit.fmu.native", "hammerbit"):
            raise
        return None
    return build_front


def add_native_front(files: dict, md_xml: str, model_identifier: str, work: Path) -> Optional[str]:
    """Replace pythonfmu's binary in ``files`` (the FMU's contents by name) by the native front,
    pythonfmu's renamed ``<id>_python.so`` beside it; the wrapper's name, or None without the front."""
    build_front = _native_front()
    if build_front is None:
        return None
    binary = f"binaries/linux64/{model_identifier}.so"
    if binary not in files:
        raise FMUBuildError(f"pythonfmu wrote no {binary}")
    wrapper = model_identifier + WRAPPER_SUFFIX
    out_dir = work / "front"
    out_dir.mkdir()
    front = Path(build_front(md_xml, out_dir, model_identifier=model_identifier, wrapper_name=wrapper))
    files[f"binaries/linux64/{wrapper}.so"] = files.pop(binary)
    files[binary] = front.read_bytes()
    return wrapper


# ---------------------------------------------------------------------------
# the build
# ---------------------------------------------------------------------------
def forget_staged_modules(staging: Path, names) -> None:
    """Undo what pythonfmu's builder left in this process (sys.path entry, imported modules)."""
    for name in list(sys.modules):
        if any(name == n or name.startswith(n + ".") for n in names):
            del sys.modules[name]
    for entry in list(sys.path):
        try:
            if Path(entry).resolve() == staging.resolve():
                sys.path.remove(entry)
        except (OSError, ValueError):
            continue


def build_fmu(out=None, *, options: BuildOptions = BuildOptions(), **kw) -> Path:
    """Build ``HammerBitRock.fmu`` and return its path.

    Parameters
    ----------
    out : path, optional
        The ``.fmu`` file to write, or a directory to write ``HammerBitRock.fmu``
        into (default ``dist/HammerBitRock.fmu``).
    options : BuildOptions
        Start values, portable cache, native front (keyword arguments of the
        same names override single fields).

    Raises
    ------
    UnknownVariableError, ParameterError
        A start value names no variable or is out of range.
    FMUBuildError
        A build step failed (no C compiler for the native front, kernels that
        do not compile, ...).
    """
    FmuBuilder = pythonfmu_builder()
    cache_enabled()                       # a bad HAMMERBIT_BUILD_CACHE is refused before any work
    if kw:
        from dataclasses import replace
        options = replace(options, **kw)
    out = Path(out) if out is not None else default_output()
    if out.suffix != ".fmu":
        out = out / f"{MODEL_NAME}.fmu"
    out = out.resolve()
    if options.runtime not in RUNTIMES:
        raise FMUBuildError(f"runtime {options.runtime!r} is not one of {', '.join(RUNTIMES)}")
    if options.fmi_version not in (2, 3) or (options.fmi_version == 3 and options.runtime != "native"):
        raise FMUBuildError(f"fmi_version = {options.fmi_version!r} is not allowed: 2, or 3 with the "
                            f"native runtime")
    out.parent.mkdir(parents=True, exist_ok=True)
    start = check_start_values(dict(options.start_values))
    if options.runtime == "native":
        return _build_native(out, options, start)

    files = runtime_files()
    tag = build_hash(files)
    pkg_name, entry_name = f"{RUNTIME_PREFIX}_{tag}", f"{ENTRY_PREFIX}_{tag}"
    import hammerbit.model.kernel_driver  # noqa: F401  (numba is imported here before the staged package)
    with tempfile.TemporaryDirectory(prefix="hammerbit_fmu_build_") as tmp:
        work = Path(tmp)
        staging = work / "stage"
        pkg = staging / pkg_name
        pkg.mkdir(parents=True)
        for f in files:
            if f.name != "build_info.py":
                shutil.copy2(f, pkg / f.name)
        (pkg / "build_info.py").write_text(_BUILD_INFO.format(hash=tag))
        (staging / "start_values.json").write_text(json.dumps(start, indent=1, sort_keys=True) + "\n")
        script = staging / f"{entry_name}.py"
        script.write_text(_ENTRY_SOURCE.format(model=MODEL_NAME, hash=tag, pkg=pkg_name))
        if options.portable_cache:
            _portable_cache(pkg, options.python)
        forget_staged_modules(staging, (entry_name, pkg_name))
        try:
            raw = FmuBuilder.build_FMU(
                script, dest=work / f"{MODEL_NAME}.fmu",
                project_files=[pkg, staging / "start_values.json"],
                canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                canHandleVariableCommunicationStepSize=True,
            )
        finally:
            forget_staged_modules(staging, (entry_name, pkg_name))
        with zipfile.ZipFile(raw) as zf:
            contents = {n: zf.read(n) for n in zf.namelist() if not n.endswith("/")}
        md = _edit_model_description(contents["modelDescription.xml"])
        md = replace_guid(md, content_guid(md, tag))
        contents["modelDescription.xml"] = md
        from hammerbit.fmu.table_check import check_description
        from hammerbit.model.fmu_description import HAMMER_VARIABLES
        check_description(md, HAMMER_VARIABLES, out.name)
        model_identifier = ET.fromstring(md).find("CoSimulation").get("modelIdentifier")
        if options.native_front:
            add_native_front(contents, md.decode("utf-8"), model_identifier, work)
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            for name in sorted(contents):
                zf.writestr(name, contents[name])
        os.replace(tmp_out, out)
    _check_contents(out, pkg_name, entry_name)
    return out


def _build_native(out: Path, options: BuildOptions, start: dict) -> Path:
    """The native flavour: the model description of a Python build, native binaries."""
    from dataclasses import replace

    from hammerbit.fmu.native_build import NativeBuildError, assemble_native_fmu
    with tempfile.TemporaryDirectory(prefix="hammerbit_fmu_md_") as tmp:
        python_fmu = build_fmu(Path(tmp) / f"{MODEL_NAME}.fmu",
                               options=replace(options, runtime="pythonfmu", portable_cache=False,
                                               native_front=False, fmi_version=2))
        try:
            return assemble_native_fmu(python_fmu, out, start, fmi_version=options.fmi_version,
                                       log=lambda msg: print(msg, file=sys.stderr))
        except NativeBuildError as e:
            raise FMUBuildError(f"the native runtime: {e}") from None


def _check_contents(fmu: Path, pkg_name: str, entry_name: str) -> None:
    """The FMU carries the runtime and nothing of the library's other modules or the tests."""
    with zipfile.ZipFile(fmu) as zf:
        names = zf.namelist()
    expected = {f"resources/{pkg_name}/{f.name}" for f in runtime_files()}
    expected.add(f"resources/{entry_name}.py")
    missing = expected - set(names)
    if missing:
        raise FMUBuildError(f"{fmu}: missing {sorted(missing)}")
    stray = [n for n in names if "coupling" in n or "/tests/" in n or n.endswith(".pyc")]
    if stray:
        raise FMUBuildError(f"{fmu}: unexpected files {stray}")
