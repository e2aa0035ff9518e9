#!/usr/bin/env python
"""Build ``dist/HammerBitRock.fmu``: the FMI 2.0 co-simulation FMU of the hammer-bit-rock model.

Usage::

    python build_fmu.py [--dest DIR]

The FMU carries only the model runtime, ``fmu_src/*.py``, staged as the
package ``hammerbit_fmu_runtime`` in ``resources/`` next to the pythonfmu
entry module ``hammerbit_fmu_slave.py``.  Those two names are fixed: the numba
cache (``fmu_src/_numba_cache.py``) keys compiled kernels on the module file
name and the source's content hash, so every extraction of the same FMU (and
every FMU built from the same sources) finds the kernels compiled by the first
load on the machine.

From Python::

    from build_fmu import build_fmu
    path = build_fmu("some/dir")      # -> some/dir/HammerBitRock.fmu
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parent
FMU_SRC = REPO / "fmu_src"
RUNTIME_PACKAGE = "hammerbit_fmu_runtime"   # package name of fmu_src inside the FMU (stable!)
ENTRY_MODULE = "hammerbit_fmu_slave"        # pythonfmu's slave module (resources/<name>.py)
MODEL_NAME = "HammerBitRock"

_STAGE_MARKER = (f"# -- staged into the {MODEL_NAME} FMU as package {RUNTIME_PACKAGE} "
                 f"by build_fmu.py --\n").encode()

_ENTRY_SOURCE = f'''"""Entry module of the {MODEL_NAME} FMU, imported by pythonfmu from resources/.

The model lives in the package ``{RUNTIME_PACKAGE}`` (a copy of hammerbit's fmu_src/).
"""
import ctypes as _ctypes

# pythonfmu 0.7.0's native findClass() runs this file's code again in this
# module's globals on every fmi2Instantiate and then releases one reference to
# that dict which it never owned.  Without this extra reference the dict is
# freed after the first instance and the next fmi2Instantiate in the process
# (or interpreter shutdown) crashes the host.  One reference per execution
# balances it exactly; with a fixed pythonfmu it only keeps the dict alive.
_ctypes.pythonapi.Py_IncRef.argtypes = [_ctypes.py_object]
_ctypes.pythonapi.Py_IncRef.restype = None
_ctypes.pythonapi.Py_IncRef(globals())

from {RUNTIME_PACKAGE}.slave import {MODEL_NAME}  # noqa: E402,F401
'''


def runtime_files() -> list[Path]:
    """The runtime sources the FMU carries: every module of fmu_src/."""
    files = sorted(p for p in FMU_SRC.glob("*.py"))
    names = {p.name for p in files}
    for required in ("__init__.py", "slave.py", "stepping.py", "kernels.py", "params.py"):
        if required not in names:
            raise FileNotFoundError(f"fmu_src/{required} is missing")
    return files


def _forget_staged_modules(staging: Path) -> None:
    """Undo what pythonfmu's builder left in this process (sys.path entry, imported modules)."""
    for name in list(sys.modules):
        if name == ENTRY_MODULE or name == RUNTIME_PACKAGE or name.startswith(RUNTIME_PACKAGE + "."):
            del sys.modules[name]
    for entry in list(sys.path):
        try:
            if Path(entry).resolve() == staging.resolve():
                sys.path.remove(entry)
        except (OSError, ValueError):
            pass


def build_fmu(dest="dist") -> Path:
    """Build ``HammerBitRock.fmu`` into the directory ``dest`` and return its path."""
    from pythonfmu import FmuBuilder

    dest = Path(dest).resolve()
    dest.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix="hammerbit_fmu_build_"))
    try:
        pkg = staging / RUNTIME_PACKAGE
        pkg.mkdir()
        for f in runtime_files():
            # The marker line gives the staged kernels their own content hash, hence their own
            # numba cache directory: cache entries record the module name they were compiled
            # under (hammerbit.model.kernels vs hammerbit_fmu_runtime.kernels) and must not be
            # shared between the two.  Appended at the end, so line numbers do not change.
            (pkg / f.name).write_bytes(f.read_bytes().rstrip(b"\n") + b"\n" + _STAGE_MARKER)
        script = staging / f"{ENTRY_MODULE}.py"
        script.write_text(_ENTRY_SOURCE)
        _forget_staged_modules(staging)
        try:
            out = FmuBuilder.build_FMU(
                script, dest=dest / f"{MODEL_NAME}.fmu", project_files=[pkg],
                canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                canHandleVariableCommunicationStepSize=True,
            )
        finally:
            _forget_staged_modules(staging)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    out = Path(out)
    _check_contents(out)
    return out


def _check_contents(fmu: Path) -> None:
    """The FMU must carry the runtime and nothing of coupling/ or the tests."""
    with zipfile.ZipFile(fmu) as zf:
        names = zf.namelist()
    expected = {f"resources/{RUNTIME_PACKAGE}/{f.name}" for f in runtime_files()}
    missing = expected - set(names)
    if missing:
        raise RuntimeError(f"{fmu}: missing {sorted(missing)}")
    stray = [n for n in names if "coupling" in n or "/tests/" in n or n.endswith(".pyc")]
    if stray:
        raise RuntimeError(f"{fmu}: unexpected files {stray}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dest", default=str(REPO / "dist"), help="output directory (default: dist/)")
    args = ap.parse_args(argv)
    path = build_fmu(args.dest)
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
