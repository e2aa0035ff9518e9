"""Native hosts the FMU tests drive: ecos from the ecospy wheel, and the C host built for Linux or
cross-built for Windows and run under wine.  Each helper skips the calling test, saying why,
when its host is not available here."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import fmpy
import pytest
from cached_compile import compile_c

from hammerbit.fmu.native import find_compiler
from hammerbit.fmu.native_build import MINGW_CC

#: the C host of the FMU tests (one source for Linux and Windows)
HOST_SOURCE = Path(__file__).resolve().parent / "fmu_native_host.c"
#: fmpy's copy of the FMI 2.0 headers, which the host includes
FMI_HEADERS = Path(fmpy.__file__).parent / "c-code"


#: the BLAS library's configuration, kept in a clean environment: OpenBLAS picks its kernels by
#: ``OPENBLAS_CORETYPE`` (else by the CPU), and another kernel gives other bits than the Python host's
BLAS_VARIABLE_PREFIXES = ("OPENBLAS_", "GOTO", "OMP_", "MKL_")


def host_env(**extra) -> dict:
    """A clean environment for a native host that starts Python: HOME (numba cache), PATH, the
    caches' directories and the BLAS configuration only; no PYTHONPATH, no LD_PRELOAD."""
    env = {"HOME": os.environ.get("HOME", "/tmp"), "PATH": "/usr/bin:/bin"}
    for key, value in os.environ.items():
        if key in ("HAMMERBIT_CACHE_DIR", "XDG_CACHE_HOME", "NUMBA_CACHE_DIR") or key.startswith(
                BLAS_VARIABLE_PREFIXES):
            env[key] = value
    env.update(extra)
    return env


def linux_host(tmp: Path) -> Path:
    """The C host built for Linux into ``tmp`` with the system C compiler."""
    exe = tmp / "fmu_native_host"
    return compile_c([find_compiler(), "-O1", "-I", str(FMI_HEADERS), "-o", str(exe), str(HOST_SOURCE),
                      "-ldl", "-lpthread"], exe, tmp)


def ecos_or_skip(tmp: Path) -> tuple[Path, Path]:
    """``(ecos executable, directory of libtbb)``: ecos and its library copied into ``tmp`` from the
    ecospy wheel, made executable (the wheel installs it without the execute bit)."""
    try:
        import importlib.metadata as md
        import importlib.util
        spec = importlib.util.find_spec("ecospy")
        tbb = [Path(str(f.locate())).resolve() for f in md.files("tbb") or ()
               if f.name.startswith("libtbb.so.")]
    except Exception as e:  # noqa: BLE001 - any packaging problem means: not available here
        pytest.skip(f"ecospy/tbb not usable: {e!r}")
    if spec is None or not tbb:
        pytest.skip("ecospy or tbb is not installed")
    binaries = Path(spec.origin).parent / "binaries"
    for name in ("ecos", "libecosc.so"):
        if not (binaries / name).exists():
            pytest.skip(f"ecospy ships no {name}")
        shutil.copy(binaries / name, tmp / name)
    (tmp / "ecos").chmod(0o755)
    return tmp / "ecos", tbb[0].parent


def windows_host_or_skip(dll: Path, tmp: Path) -> tuple[str, Path]:
    """``(wine, host .exe)``: the C host cross-built with mingw-w64 into ``tmp``, to run ``dll``."""
    wine = shutil.which("wine") or shutil.which("wine64") or next(
        (w for w in ("/usr/lib/wine/wine64",) if os.access(w, os.X_OK)), None)   # Debian's wine64 alone
    if not shutil.which(MINGW_CC) or not dll.exists():
        pytest.skip(f"no {MINGW_CC} (Debian: gcc-mingw-w64-x86-64): no win64 binary or host")
    if not wine:
        pytest.skip("no wine (Debian: wine64) to run the Windows host")
    exe = tmp / "fmu_native_host.exe"
    compile_c([MINGW_CC, "-O1", "-I", str(FMI_HEADERS), "-o", str(exe), str(HOST_SOURCE), "-static", "-lpthread"],
              exe, tmp)
    return wine, exe
