"""The glibc baseline of the Linux binaries: glibc 2.17 (manylinux2014).

Every native ``.so`` the project builds (the native front of the pythonfmu flavours, the native
flavours' binaries) may need no symbol version above GLIBC_2.17, and none of libstdc++
(GLIBCXX, CXXABI) or GLIBC_ABI_*.  The versions are read with ``objdump -p`` (the "Version
References" the dynamic loader checks at load time).  pythonfmu's own binary is not ours:
docs/fmu.md must name the glibc version it needs.
"""
from __future__ import annotations

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from cached_compile import compile_c

from hammerbit.fmu.build import WRAPPER_SUFFIX

BASELINE = (2, 17)
DOCS = Path(__file__).resolve().parents[1] / "docs" / "fmu.md"

pytestmark = pytest.mark.skipif(shutil.which("objdump") is None, reason="no objdump (binutils)")


def version_references(so: Path) -> dict:
    """``{library: [version name, ...]}`` of the "Version References" of ``objdump -p so``."""
    out = subprocess.run(["objdump", "-p", str(so)], capture_output=True, text=True, check=True).stdout
    refs, lib, inside = {}, None, False
    for line in out.splitlines():
        if line.startswith("Version References:"):
            inside = True
            continue
        if inside:
            m = re.match(r"\s+required from (\S+):", line)
            if m:
                lib = m.group(1)
                refs[lib] = []
            elif re.match(r"\s+0x[0-9a-f]+ 0x[0-9a-f]+ \d+ (\S+)", line):
                refs[lib].append(line.split()[-1])
            elif line.strip():
                break
    return refs


def too_new(refs: dict) -> list:
    """The version names of ``refs`` above the baseline (or of libstdc++ / GLIBC_ABI)."""
    bad = []
    for lib, names in refs.items():
        for name in names:
            m = re.fullmatch(r"GLIBC_(\d+)\.(\d+)(?:\.\d+)?", name)
            if m is None or tuple(map(int, m.groups())) > BASELINE:
                bad.append(f"{lib}: {name}")
    return bad


def _shared_objects(fmu: Path, tmp: Path) -> list:
    with zipfile.ZipFile(fmu) as zf:
        names = [n for n in zf.namelist() if n.startswith("binaries/linux64/") and n.endswith(".so")]
        zf.extractall(tmp, names)
    return [tmp / n for n in names]


def test_too_new_names_each_kind_of_version_above_the_baseline():
    refs = {"libm.so.6": ["GLIBC_2.2.5", "GLIBC_2.29"], "libstdc++.so.6": ["GLIBCXX_3.4"],
            "libc.so.6": ["GLIBC_2.17", "GLIBC_ABI_DT_RELR"]}
    assert too_new(refs) == ["libm.so.6: GLIBC_2.29", "libstdc++.so.6: GLIBCXX_3.4",
                             "libc.so.6: GLIBC_ABI_DT_RELR"]


def test_the_shim_binds_the_oldest_math_versions_and_keeps_the_results(tmp_path):
    """A library calling exp, log and pow, linked as link_binary links: without the shim it binds
    glibc's newest versions (2.29 on glibc >= 2.29, which this oracle needs), with it GLIBC_2.2.5,
    and it computes the same numbers as Python's math (the same implementation on this machine)."""
    import ctypes
    import math

    from hammerbit.fmu.native import find_compiler
    from hammerbit.fmu.native_build import GLIBC_COMPAT_SOURCE, GLIBC_WRAPPED
    src = tmp_path / "k.c"
    src.write_text("#include <math.h>\n"
                   "double k(double x) { return exp(x) + 3.0 * log(x) + 5.0 * pow(x, 1.25); }\n")
    cc = find_compiler()
    plain, shimmed = tmp_path / "plain.so", tmp_path / "shimmed.so"
    compile_c([cc, "-O2", "-fPIC", "-shared", "-o", str(plain), str(src), "-lm"], plain, tmp_path)
    compile_c([cc, "-O2", "-fPIC", "-shared", "-o", str(shimmed), str(src), str(GLIBC_COMPAT_SOURCE),
               "-Wl," + ",".join(f"--wrap={n}" for n in GLIBC_WRAPPED), "-lm"], shimmed, tmp_path)
    if not too_new(version_references(plain)):
        pytest.skip("this machine's glibc is older than 2.29: exp binds no new version to avoid")
    assert too_new(version_references(shimmed)) == []
    k = ctypes.CDLL(str(shimmed)).k
    k.restype, k.argtypes = ctypes.c_double, [ctypes.c_double]
    for x in (0.1, 1.0, 2.5, 700.0):
        assert k(x) == math.exp(x) + 3.0 * math.log(x) + 5.0 * math.pow(x, 1.25)


@pytest.mark.parametrize("built", ["built_fmu", "built_native_fmu", "built_string_fmu",
                                   "built_native_string_fmu"], indirect=True)
def test_no_binary_of_ours_needs_more_than_glibc_2_17(built, tmp_path):
    fmu = built
    ours = [so for so in _shared_objects(fmu, tmp_path) if not so.stem.endswith(WRAPPER_SUFFIX)]
    assert ours, f"{fmu.name} has no linux64 binary of ours"
    for so in ours:
        refs = version_references(so)
        assert refs.get("libc.so.6"), f"{so.name}: no version references read (objdump's format?)"
        assert too_new(refs) == [], f"{fmu.name}: {so.name} needs more than glibc 2.17"


def test_docs_name_what_pythonfmus_own_binary_needs(built_fmu, tmp_path):
    """pythonfmu's binary is rebuilt by nobody here: docs/fmu.md names its newest glibc version."""
    wrapper = [so for so in _shared_objects(built_fmu, tmp_path) if so.stem.endswith(WRAPPER_SUFFIX)]
    assert len(wrapper) == 1
    glibc = [tuple(map(int, n[len("GLIBC_"):].split(".")[:2])) for names in version_references(wrapper[0]).values()
             for n in names if re.fullmatch(r"GLIBC_[\d.]+", n)]
    newest = "%d.%d" % max(glibc)
    assert f"glibc {newest}" in DOCS.read_text(), f"docs/fmu.md does not say pythonfmu's binary needs glibc {newest}"
