"""The FMI 3.0 native FMU's three binaries run by one plain C host (tests/fmi3_host.c): built for
x86_64-linux, cross-built for aarch64-linux and run under qemu-aarch64, cross-built for Windows
and run under wine.  Oracle: the x86_64-linux run of the same host and steps."""
from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402

from hammerbit.fmu.native import find_compiler  # noqa: E402
from hammerbit.fmu.native_build import AARCH64_CC, MINGW_CC  # noqa: E402
from cached_compile import compile_c  # noqa: E402

HOST_SOURCE = Path(__file__).resolve().parent / "fmi3_host.c"
FMI_HEADERS = Path(fmpy.__file__).parent / "c-code"
OUTS = ("hammer_position", "hammer_velocity", "bit_position", "bit_velocity", "rock_force")
QEMU_SYSROOT = "/usr/aarch64-linux-gnu"
REL = 1e-13


def assert_close(got, want, label):
    """Each output equal to REL relative, against its scale where it is smaller (the lab rig's x0,
    x0 Omega, F0: the velocities pass through zero), as the FMI 2.0 platform tests compare."""
    from hammerbit.model.params import RigParameters
    sc = RigParameters().scales                            # the FMU's default start values
    scales = (sc.length, sc.velocity, sc.length, sc.velocity, sc.friction_force)
    assert len(got) == len(want) == len(OUTS)
    for name, a, b, s in zip(OUTS, got, want, scales):
        assert abs(a - b) <= REL * max(abs(b), s), f"{label}: {name} {a!r} vs {b!r}"


@pytest.fixture(scope="module")
def fmu3_dir(built_native_fmu3, tmp_path_factory):
    d = tmp_path_factory.mktemp("fmi3p_unzipped")
    with zipfile.ZipFile(built_native_fmu3) as zf:
        zf.extractall(d)
    (d / "resources").mkdir(exist_ok=True)
    return d


def _host(cc, out: Path, *extra) -> Path:
    return compile_c([cc, "-O1", "-I", str(FMI_HEADERS), "-o", str(out), str(HOST_SOURCE), *extra], out, out.parent)


def _values(stdout: str) -> list:
    return [float(line.split()[1]) for line in stdout.splitlines() if line.startswith("value ")]


def _run(cmd, env=None):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, f"{cmd[0]} exit {r.returncode}: {r.stdout[-2000:]} {r.stderr[-2000:]}"
    return r.stdout


def _args(d: Path, lib: str, resources: str, steps: int, early: bool):
    md = read_model_description(str(d / "modelDescription.xml"))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    return [lib, resources, md.guid, str(steps), "1e-3", ",".join(str(vrs[n]) for n in OUTS),
            f"early={int(early)}"]


def _linux_run(d, tmp, steps, early):
    exe = _host(find_compiler(), tmp / "fmi3_host", "-ldl")
    return _run([str(exe), *_args(d, str(d / "binaries/x86_64-linux/HammerBitRock.so"),
                                  str(d / "resources") + "/", steps, early)])


@pytest.mark.parametrize("early", [False, True])
@pytest.mark.parametrize("steps", [1000, pytest.param(10000, marks=pytest.mark.slow)])
def test_aarch64_under_qemu_equals_x86_64(fmu3_dir, tmp_path, steps, early):
    qemu = shutil.which("qemu-aarch64")
    so = fmu3_dir / "binaries/aarch64-linux/HammerBitRock.so"
    if not (qemu and shutil.which(AARCH64_CC) and so.exists() and Path(QEMU_SYSROOT).is_dir()):
        pytest.skip(f"needs {AARCH64_CC}, qemu-aarch64 (Debian: qemu-user) and {QEMU_SYSROOT}")
    exe = _host(shutil.which(AARCH64_CC), tmp_path / "fmi3_host_aarch64", "-ldl")
    arm = _run([qemu, "-L", QEMU_SYSROOT, str(exe), *_args(fmu3_dir, str(so), str(fmu3_dir / "resources") + "/",
                                                            steps, early)])
    lin = _linux_run(fmu3_dir, tmp_path, steps, early)
    a, x = _values(arm), _values(lin)
    assert x[2] > 0.0                                      # the lab rig drills
    assert_close(a, x, "aarch64 (qemu) vs x86_64-linux")
    assert arm.split("returns")[1] == lin.split("returns")[1]       # the same early returns


@pytest.mark.parametrize("steps", [1000, pytest.param(10000, marks=pytest.mark.slow)])
def test_windows_dll_under_wine_equals_x86_64_linux(fmu3_dir, tmp_path, steps):
    wine = shutil.which("wine") or shutil.which("wine64")
    dll = fmu3_dir / "binaries/x86_64-windows/HammerBitRock.dll"
    if not (wine and shutil.which(MINGW_CC) and dll.exists()):
        pytest.skip(f"needs {MINGW_CC} and wine")
    exe = _host(shutil.which(MINGW_CC), tmp_path / "fmi3_host.exe", "-static")
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "WINEDEBUG": "-all",
           "WINEPREFIX": os.environ.get("WINEPREFIX", str(Path.home() / ".wine"))}
    win_path = "Z:" + str(dll).replace("/", "\\")
    res = "Z:" + str(fmu3_dir / "resources").replace("/", "\\") + "\\"
    win = _run([wine, str(exe), *_args(fmu3_dir, win_path, res, steps, True)], env=env)
    lin = _linux_run(fmu3_dir, tmp_path, steps, True)
    assert_close(_values(win), _values(lin), "x86_64-windows (wine) vs x86_64-linux")


def test_linux_binaries_need_no_newer_glibc_than_2_17(fmu3_dir):
    """FMI 3.0's Linux platforms as old as the manylinux2014 baseline (glibc 2.17)."""
    objdump = shutil.which("objdump")
    if not objdump:
        pytest.skip("no objdump")
    newest = {}
    # the host's objdump reads an AArch64 binary as plain ELF, without its symbol versions
    readers = {"x86_64-linux": objdump, "aarch64-linux": shutil.which("aarch64-linux-gnu-objdump")}
    for plat, reader in readers.items():
        so = fmu3_dir / "binaries" / plat / "HammerBitRock.so"
        if not so.exists() or reader is None:
            continue
        out = subprocess.run([reader, "-T", str(so)], capture_output=True, text=True).stdout
        vers = {tuple(int(p) for p in v.split("_")[1].split(".")) for v in
                (w.strip("()") for w in out.split()) if v.startswith("GLIBC_") and v[6:7].isdigit()}
        newest[plat] = max(vers)
    assert newest and all(v <= (2, 17) for v in newest.values()), newest
