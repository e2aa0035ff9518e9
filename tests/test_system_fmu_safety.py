"""DrillingSystem.fmu in a host's hands: its binary loads on glibc 2.17, and no state crashes or hangs it.

The same checks as the other FMUs' (tests/test_glibc_baseline.py reads the version references
with ``objdump -p``; tests/test_fmu_fuzz.py feeds byte-flipped, field-corrupted and random states
to a host process with a watchdog), on the third FMU of the issue.
"""
from __future__ import annotations

import struct
import zipfile

import pytest

pytest.importorskip("fmpy")

from test_fmu_fuzz import CPU_BUDGET, WATCHDOG, _assert_exercised, fuzz_states  # noqa: E402
from test_glibc_baseline import too_new, version_references  # noqa: E402

from hammerbit.cosim.config import CosimConfig, default_hammer  # noqa: E402
from hammerbit.drillstring import load_string  # noqa: E402
from hammerbit.drillstring.top import TopCondition  # noqa: E402


def _config():
    field = load_string("field-2200m")
    return field, CosimConfig(stop=2.0, step=0.01, rig=default_hammer(field), top=TopCondition.parse("auto-driller"))


@pytest.fixture(scope="module")
def system_fmu(built_field_system_fmu):
    """field-2200m under the auto-driller, 2 s at H = 10 ms (the session's shared build)."""
    return built_field_system_fmu


@pytest.fixture(scope="module")
def system_fmu_data():
    """The data the build of :func:`system_fmu` compiles in (computed once: the string's modal
    system takes seconds)."""
    from hammerbit.fmu.build_system import system_data
    return system_data(*_config())


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
    """A few hundred states, a third field-corrupted: 0 crashes, 0 hangs over a second of CPU."""
    counts = fuzz_states(system_fmu, tmp_path, seed=11, count=300, watchdog=WATCHDOG, timeout=900.0,
                         cpu_budget=CPU_BUDGET)
    _assert_exercised(counts, "built_system_fmu")


def test_a_few_fuzzed_states_never_crash_or_hang_the_host(system_fmu, tmp_path):
    """Sixty states, a third field-corrupted, each kind refused at times: 0 crashes, 0 hangs (the
    fast set's sample; the slow set asks 300 and 10,002)."""
    counts = fuzz_states(system_fmu, tmp_path, seed=11, count=60, watchdog=WATCHDOG, timeout=900.0,
                         cpu_budget=CPU_BUDGET)
    _assert_exercised(counts, "built_system_fmu")


@pytest.mark.slow
def test_ten_thousand_fuzzed_states_never_crash_or_hang_over_a_second(system_fmu, tmp_path):
    """10,002 states (13 s of CPU at load 1): 0 crashes, 0 hangs over a second of CPU, nor over
    WATCHDOG seconds of wall time."""
    counts = fuzz_states(system_fmu, tmp_path, seed=12345, count=10_002, watchdog=WATCHDOG, timeout=3600.0,
                         cpu_budget=CPU_BUDGET)
    _assert_exercised(counts, "built_system_fmu")



def _word_offsets(data: bytes, value: float) -> list:
    """The offsets of the 8-byte words of ``data`` that hold ``value`` exactly."""
    word = struct.pack("<d", value)
    return [o for o in range(0, len(data) - 7, 8) if data[o:o + 8] == word]


@pytest.mark.parametrize("field,value,reason", [
    ("hammer_position", 1e12, "beyond the physical range"),     # stepped 20 s before the state checks
    ("hammer_position", 101.0, "from the bit, beyond"),        # a hammer 100 x0 inside the bit
    ("rtol", 1e-300, "tolerance is out of range"),              # a step that never ends
    ("rtol", 2e-4, "not those of one tolerance"),               # the shadow no longer 32x tighter
    ("eta", 1e12, "not its applied inputs'"),                   # a billion solver steps a period
])
def test_a_state_out_of_its_physical_range_is_refused(system_fmu, system_fmu_data, field, value, reason):
    """The fields whose corruption made the solver step for tens of seconds (found by setting each
    solver-state word to each adversarial value), each refused when the state is deserialised,
    naming why.  A field is found by the value the build gives it in the state right after
    initialisation (the hammer's start position in both runs, the main run's rtol, the forcing's
    nondimensional frequency), so the test does not restate the C layout."""
    from fmpy.fmi1 import FMICallException
    from test_system_fmu import Slave

    from hammerbit.fmu.build_system import RTOL_PER_TOLERANCE
    from hammerbit.model.fmu_description import TWO_PI
    data = system_fmu_data
    start = {"hammer_position": float(data["y0"][0]), "rtol": 1e-3 * RTOL_PER_TOLERANCE,
             "eta": TWO_PI * data["frequency"] / data["Om"]}[field]
    log = []
    s = Slave(system_fmu, logger=log)
    try:
        state = s.fmu.getFMUstate()
        valid = bytes(s.fmu.serializeFMUstate(state))
        offsets = _word_offsets(valid, start)
        assert len(offsets) == {"hammer_position": 2}.get(field, 1), f"{field} held at {offsets}"
        bad = bytearray(valid)
        for o in offsets:
            bad[o:o + 8] = struct.pack("<d", value)
        s.fmu.freeFMUstate(s.fmu.deSerializeFMUstate(valid))          # the valid one is accepted
        with pytest.raises(FMICallException):
            s.fmu.deSerializeFMUstate(bytes(bad))
        assert reason in log[-1], log[-1]
        s.fmu.setFMUstate(state)           # out of the error state (FMI 2.0.4), to terminate
        s.fmu.freeFMUstate(state)
    finally:
        s.close()
