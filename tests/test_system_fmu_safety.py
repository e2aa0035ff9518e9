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


@pytest.fixture(scope="module")
def system_fmu(built_field_system_fmu):
    """field-2200m under the auto-driller, 2 s at H = 10 ms (the session's shared build)."""
    return built_field_system_fmu


def test_the_binary_needs_no_more_than_glibc_2_17(system_fmu, tmp_path):
    with zipfile.ZipFile(system_fmu) as zf:
        names = [n for n in zf.namelist() if n.startswith("binaries/linux64/") and n.endswith(".so")]
        assert names, "no linux64 binary"
        zf.extractall(tmp_path, names)
    for name in names:
        refs = version_references(tmp_path / name)
        assert refs.get("libc.so.6"), f"{name}: no version references read (objdump's format?)"
        assert too_new(refs) == [], f"{name} needs more than glibc 2.17"


def test_fuzzed_states_never_crash_or_hang_the_host(system_fmu, tmp_path):
    """A few hundred states, a third field-corrupted: 0 crashes, 0 hangs (the slow set's twin asks
    1 s per state of 10,000)."""
    counts = fuzz_states(system_fmu, tmp_path, seed=11, count=300, watchdog=60.0, timeout=900.0)
    _assert_exercised(counts, "built_system_fmu")


def test_a_few_fuzzed_states_never_crash_or_hang_the_host(system_fmu, tmp_path):
    """Sixty states, a third field-corrupted, each kind refused at times: 0 crashes, 0 hangs (the
    fast set's sample; the slow set asks 300, the soak set 10,000)."""
    counts = fuzz_states(system_fmu, tmp_path, seed=11, count=60, watchdog=60.0, timeout=900.0)
    _assert_exercised(counts, "built_system_fmu")


@pytest.mark.soak
@pytest.mark.slow
def test_ten_thousand_fuzzed_states_never_crash_or_hang_over_a_second(system_fmu, tmp_path):
    counts = fuzz_states(system_fmu, tmp_path, seed=12345, count=10_002, watchdog=1.0, timeout=3600.0)
    _assert_exercised(counts, "built_system_fmu")
