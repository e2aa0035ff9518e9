"""The pythonfmu Drillstring.fmu behind the native front, as HammerBitRock's pythonfmu flavour.

pythonfmu's own binary expects the host to be Python (in a native host it fails with
``undefined symbol: _Py_NoneStruct``); the front loads Python into a native host.  The oracle
is the same FMU with pythonfmu's binary alone, run in fmpy (a Python host).
"""
from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from fmu_slave import Slave
from native_hosts import host_env, linux_host

pytest.importorskip("fmpy")

ID = "Drillstring"
OUT = ("interface_force", "held_force", "hook_load")
STEPS, H = 200, 1e-3
AMP, FREQ = 5e-5, 25.0      # the hammer's parabola about its rest position [m], [Hz] (as the host)


def _drive(t: float, rest: float) -> list:
    """The C host's drive=... inputs at t, computed as the host computes them."""
    u = FREQ * t
    s = u - float(int(u))
    return [rest + 4.0 * AMP * s * (1.0 - s), 4.0 * AMP * FREQ * (1.0 - 2.0 * s)]


@pytest.fixture(scope="module")
def dirs(built_string_fmu, tmp_path_factory):
    """(the FMU as built, extracted; the same with pythonfmu's binary alone under the FMU's name)."""
    front, plain = tmp_path_factory.mktemp("front"), tmp_path_factory.mktemp("plain")
    for d in (front, plain):
        with zipfile.ZipFile(built_string_fmu) as zf:
            zf.extractall(d)
    bindir = plain / "binaries" / "linux64"
    (bindir / f"{ID}_python.so").replace(bindir / f"{ID}.so")
    return front, plain


def test_the_fmu_carries_the_front_and_pythonfmus_binary_beside_it(built_string_fmu):
    with zipfile.ZipFile(built_string_fmu) as zf:
        names = set(zf.namelist())
    assert {f"binaries/linux64/{ID}.so", f"binaries/linux64/{ID}_python.so"} <= names


def _oracle(plain: Path) -> list:
    s = Slave(plain)
    rest = s.get("hammer_position_at_rest")[0]
    vx, vv = s.vr["hammer_position"], s.vr["hammer_velocity"]
    for i in range(STEPS):
        s.fmu.setReal([vx, vv], _drive(i * H, rest))
        s.step(H)
    values = s.get(*OUT)
    s.close()
    return values


def test_a_native_c_host_runs_it_like_fmpy(dirs, tmp_path):
    front, plain = dirs
    import sysconfig
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip(f"{sys.executable} has no shared libpython, which a native host needs")
    from fmpy import read_model_description
    md = read_model_description(str(front / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    rest = json.loads((front / "resources" / "string_info.json").read_text())["hammer_position_at_rest"]
    host = linux_host(tmp_path)
    env = host_env(HAMMERBIT_PYTHON=sys.executable)
    proc = subprocess.run([str(host), str(front / "binaries" / "linux64" / f"{ID}.so"),
                           (front / "resources").as_uri(), md.guid, f"steps={STEPS}", f"h={H!r}",
                           "out=" + ",".join(str(vr[n]) for n in OUT),
                           f"drive={vr['hammer_position']}:{vr['hammer_velocity']}:{rest!r}:{AMP!r}:{FREQ!r}"],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "_Py_NoneStruct" not in proc.stdout + proc.stderr
    got = [float(line.split()[1]) for line in proc.stdout.splitlines() if line.startswith("value ")]
    assert got == _oracle(plain)
