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
