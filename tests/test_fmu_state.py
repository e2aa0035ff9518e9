"""The serialised FMU state (fmi2SerializeFMUstate / fmi2DeSerializeFMUstate) in process: round trip,
and corrupt or foreign bytes refused with fmi2Error."""
from __future__ import annotations

import json

import numpy as np

from hammerbit.model.fmu_state import STATE_FORMAT, pop_deserialize_status, state_from_bytes, state_to_bytes

FMI_OK, FMI_ERROR = 0, 3


def _state():
    return {"format": STATE_FORMAT, "stepper": np.array([0.25, -1.5, 3.0]), "inputs": (1.0, 2.0),
            "t": 0.5, "params": {"hammer_mass": 25.3}}


def test_round_trip_keeps_every_value_and_reports_ok():
    s = state_from_bytes(state_to_bytes(_state()))
    assert pop_deserialize_status() == FMI_OK
    assert s["format"] == STATE_FORMAT and s["stepper"] == [0.25, -1.5, 3.0]
    assert s["inputs"] == (1.0, 2.0) and s["t"] == 0.5 and s["params"] == {"hammer_mass": 25.3}
    assert pop_deserialize_status() is None          # read once


def test_corrupt_bytes_give_an_invalid_state_and_error():
    s = state_from_bytes(b"\xff\x00 not json")
    assert pop_deserialize_status() == FMI_ERROR
    assert s["format"] == "invalid" and "cannot deserialise" in s["reason"]


def test_a_state_of_another_format_is_refused():
    other = dict(_state(), format="hammerbit-fmu-state/1", stepper=[0.0])
    s = state_from_bytes(json.dumps(other).encode())
    assert pop_deserialize_status() == FMI_ERROR
    assert s["format"] == "invalid" and STATE_FORMAT in s["reason"]


# ---------------------------------------------------------------------------
# field checks of a deserialised state, both flavours of HammerBitRock.fmu
# ---------------------------------------------------------------------------
import struct  # noqa: E402
import zipfile  # noqa: E402

import pytest  # noqa: E402

from hammerbit.model import kernel_layouts as K  # noqa: E402

#: the front's header before the model's body (magic, GUID, instance state, pad, two times)
FRONT_HEADER = 96
N_Y = 4                      # x1..x4: the FMU's stepper state starts with them


@pytest.fixture(scope="module")
def stepped_states(built_fmu, built_native_fmu, tmp_path_factory):
    """``{flavour: (an instance, its serialised state after 60 steps of 1 ms)}``; the two flavours
    compute the same integer state (the native one is the library's kernels compiled)."""
    from fmu_slave import Slave
    out = {}
    for flavour, fmu in (("pythonfmu", built_fmu), ("native", built_native_fmu)):
        d = tmp_path_factory.mktemp(flavour)
        with zipfile.ZipFile(fmu) as zf:
            zf.extractall(d)
        s = Slave(d, logging=True)
        for _ in range(60):
            s.step()
        st = s.fmu.getFMUstate()
        out[flavour] = (s, bytes(s.fmu.serializeFMUstate(st)))
        s.fmu.freeFMUstate(st)
    yield out
    for s, _ in out.values():
        s.fmu.freeInstance()


def _ist_of_json(data: bytes) -> list:
    doc = json.loads(data[FRONT_HEADER:])
    return [int(v) for v in doc["stepper"][N_Y:N_Y + K.N_ISTATE]]


def _with_ist_entry(flavour: str, data: bytes, ist: list, i: int, value: int) -> bytes:
    """The state with integer-state entry ``i`` set to ``value``, otherwise well formed."""
    if flavour == "pythonfmu":
        doc = json.loads(data[FRONT_HEADER:])
        doc["stepper"][N_Y + i] = float(value)
        return data[:FRONT_HEADER] + json.dumps(doc).encode()
    # the native body holds the integer state as int64s, equal to the pythonfmu flavour's
    pattern = struct.pack(f"<{len(ist)}q", *ist)
    at = data.find(pattern, FRONT_HEADER)
    assert at > 0 and data.find(pattern, at + 1) < 0, "the integer state is not found once in the native state"
    b = bytearray(data)
    struct.pack_into("<q", b, at + 8 * i, value)
    return bytes(b)


def _deserialize_status(s, data: bytes) -> tuple:
    """The status of fmi2DeSerializeFMUstate of ``data`` on the instance ``s``, the errors it logged."""
    from fmpy.fmi1 import FMICallException
    n = len(s.errors())
    try:
        state = s.fmu.deSerializeFMUstate(data)
        s.fmu.freeFMUstate(state)
        status = FMI_OK
    except FMICallException as e:
        status = e.status
    return status, s.errors()[n:]


@pytest.mark.parametrize("flavour", ["pythonfmu", "native"])
@pytest.mark.parametrize("entry, value", [(K.I_SAMP_NEXT, -1), (K.I_POIN_NEXT, -1), (K.I_NLOG, 1),
                                          (K.I_SAMP_NEXT, 1), (K.I_STICK, 2), (K.I_CONTACT, -1),
                                          (K.I_BOUNCE, 2), (K.I_COUNT0 + K.EV_IMPACT, -1),
                                          (K.I_COUNT0 + K.EV_SLIP_START, 2 ** 31), (K.I_WIN, -2)])
def test_a_state_with_an_integer_entry_out_of_its_range_is_refused(stepped_states, flavour, entry, value):
    """The FMU records nothing, so its record buffers are empty: any record index but 0 would make
    the next step write outside them (a negative sample index segfaulted).  Modes outside their
    enums, negative counts, a count beyond the 32-bit Integer output: refused as well."""
    ist = _ist_of_json(stepped_states["pythonfmu"][1])
    d, data = stepped_states[flavour]
    assert _deserialize_status(d, _with_ist_entry(flavour, data, ist, entry, ist[entry]))[0] == FMI_OK
    status, errors = _deserialize_status(d, _with_ist_entry(flavour, data, ist, entry, value))
    assert status == FMI_ERROR and errors, (entry, value)


@pytest.mark.parametrize("field, value", [("t", 2e9), ("t_start", -6.2e144), ("t", 0.5),
                                          ("stepper_p_eta", 7.0), ("stepper_tau", 1e12),
                                          ("stepper_h", -1.0), ("stepper_x1", 1e13)])
def test_a_pythonfmu_state_inconsistent_with_its_parameters_or_clock_is_refused(stepped_states, field, value):
    """Times outside +-1e9 s, a communication time the kernel's clock does not match, a kernel
    parameter its parameters in use do not give, a step proposal <= 0, a position beyond the state
    range: each refused by the field checks (the bytes are well formed)."""
    d, data = stepped_states["pythonfmu"]
    doc = json.loads(data[FRONT_HEADER:])
    n_f0 = N_Y + K.N_ISTATE
    where = {"stepper_p_eta": n_f0 + K.N_FSTATE + K.P_ETA, "stepper_tau": n_f0 + K.F_T,
             "stepper_h": n_f0 + K.F_H, "stepper_x1": 0}
    if field in where:
        doc["stepper"][where[field]] = value
    else:
        doc[field] = value
    status, errors = _deserialize_status(d, data[:FRONT_HEADER] + json.dumps(doc).encode())
    assert status == FMI_ERROR and errors, field


@pytest.mark.parametrize("flavour", ["pythonfmu", "native"])
def test_a_contact_mode_without_an_impact_device_is_refused(stepped_states, flavour):
    """The mode in range but not fitting the positions: the default FMU has no impact device (an
    infinite gap), so contact marked in its state gives an infinite contact force (an accepted
    fuzzed state of the native flavour read contact_force = -inf)."""
    ist = _ist_of_json(stepped_states["pythonfmu"][1])
    assert ist[K.I_CONTACT] == K.FREE, "the stepped state is not free: the test would be vacuous"
    d, data = stepped_states[flavour]
    status, errors = _deserialize_status(d, _with_ist_entry(flavour, data, ist, K.I_CONTACT, K.CONTACT))
    assert status == FMI_ERROR and errors
