"""DrillingSystem.fmu in a host's hands: its binary loads on glibc 2.17, and no state crashes or hangs it.

The same checks as the other FMUs' (tests/test_glibc_baseline.py reads the version references
with ``objdump -p``; tests/test_fmu_fuzz.py feeds byte-flipped, field-corrupted and random states
to a host process with a watchdog), on the third FMU of the issue.
"""
from __future__ import annotations

import zipfile

import pytest

pytest.importorskip("fmpy")

from test_fmu_fuzz import _assert_exercised, fuzz_states  # noqa: E402
from test_glibc_baseline import too_new, version_references  # noqa: E402

from hammerbit.cosim.config import CosimConfig, default_hammer  # noqa: E402
from hammerbit.drillstring import load_string  # noqa: E402
from hammerbit.drillstring.top import TopCondition  # noqa: E402


@pytest.fixture(scope="module")
def system_fmu(tmp_path_factory):
    from hammerbit.fmu.build_system import build_system_fmu
    field = load_string("field-2200m")
    cfg = CosimConfig(stop=2.0, step=0.01, rig=default_hammer(field), top=TopCondition.parse("auto-driller"))
    return build_system_fmu(field, cfg, tmp_path_factory.mktemp("safety") / "DS.fmu", log=lambda m: None)


def test_the_binary_needs_no_more_than_glibc_2_17(system_fmu, tmp_path):
    with zipfile.ZipFile(system_fmu) as zf:
        names = [n for n in zf.namelist() if n.startswith("binaries/linux64/") and n.endswith(".so")]
        assert names, "no linux64 binary"
        zf.extractall(tmp_path, names)
    for name in names:
        refs = version_references(tmp_path / name)
        assert refs.get("libc.so.6"), f"{name}: no version references read (objdump's format?)"
        assert too_new(refs) == [], f"{name} needs more than glibc 2.17"


#: a hang is a state that computes for more than this (to this + 1) seconds of CPU: CPU time, not
#: wall time, so that a loaded host (a load of 11 on 2 cores stretches a 0.13 s state to a second of
#: wall time) is not taken for a hang, and a real one (states of a hammer 1e12 x0 into the bit
#: computed 20 s before the state checks refused them) is caught at any load
CPU_BUDGET = 1
#: the wall-clock watchdog beside it catches a state that blocks without computing
WATCHDOG = 60.0


def test_fuzzed_states_never_crash_or_hang_the_host(system_fmu, tmp_path):
    """A few hundred states, a third field-corrupted: 0 crashes, 0 hangs over a second of CPU."""
    counts = fuzz_states(system_fmu, tmp_path, seed=11, count=300, watchdog=WATCHDOG, timeout=900.0,
                         cpu_budget=CPU_BUDGET)
    _assert_exercised(counts, "built_system_fmu")


@pytest.mark.slow
def test_ten_thousand_fuzzed_states_never_crash_or_hang_over_a_second(system_fmu, tmp_path):
    """10,002 states (13 s of CPU at load 1): 0 crashes, 0 hangs over a second of CPU, nor over
    WATCHDOG seconds of wall time."""
    counts = fuzz_states(system_fmu, tmp_path, seed=12345, count=10_002, watchdog=WATCHDOG, timeout=3600.0,
                         cpu_budget=CPU_BUDGET)
    _assert_exercised(counts, "built_system_fmu")
