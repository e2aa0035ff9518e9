"""The serialised FMU state of the HammerBitRock FMU: its format tag and the bytes it is saved as."""
from __future__ import annotations

import json
import threading

__all__ = ["STATE_FORMAT", "state_to_bytes", "state_from_bytes", "pop_deserialize_status",
           "pop_deserialize_reason"]

#: Format tag of a saved FMU state (checked when a state is restored).
STATE_FORMAT = "hammerbit-fmu-state/2"

#: FMI 2.0 status codes of a deserialisation (OK, Error)
FMI_OK, FMI_ERROR = 0, 3

# status of the last fmi2DeSerializeFMUstate of this thread (a class-level call in pythonfmu:
# the instance it is made for reads it through last_status right after the call)
_DESERIALIZED = threading.local()


def pop_deserialize_status():
    """The status of this thread's last :func:`state_from_bytes` not read yet, or None."""
    return _DESERIALIZED.__dict__.pop("status", None)


def pop_deserialize_reason():
    """Why this thread's last :func:`state_from_bytes` refused its bytes (not read yet), or None."""
    return _DESERIALIZED.__dict__.pop("reason", None)


def state_to_bytes(state) -> bytes:
    """The FMU state as bytes (fmi2SerializeFMUstate): JSON."""
    s = dict(state)
    if "stepper" in s:
        s["stepper"] = [float(v) for v in s["stepper"]]
    return json.dumps(s).encode("utf-8")


def state_from_bytes(data: bytes, check=None):
    """The FMU state of :func:`state_to_bytes` (fmi2DeSerializeFMUstate); an invalid one, with the
    reason, if the bytes are not such a state or ``check(state)`` says why it cannot be restored
    (the status and the reason are kept for :func:`pop_deserialize_status` and
    :func:`pop_deserialize_reason`)."""
    try:
        s = json.loads(bytes(data).decode("utf-8"))
        if not isinstance(s, dict) or s.get("format") != STATE_FORMAT:
            raise ValueError(f"not a {STATE_FORMAT} state")
        why = check(s) if check is not None else None
        if why:
            raise ValueError(why)
        if "inputs" in s:
            s["inputs"] = tuple(s["inputs"])
    except ValueError as e:   # JSON and UTF-8 errors are ValueErrors
        _DESERIALIZED.status = FMI_ERROR
        _DESERIALIZED.reason = f"cannot deserialise the FMU state: {e}"
        return {"format": "invalid", "reason": _DESERIALIZED.reason}
    except Exception as e:  # noqa: BLE001 -- bytes from outside: any failure to read them is a refusal
        # (a huge JSON integer overflows a float, deep nesting recurses, a field of the wrong type)
        _DESERIALIZED.status = FMI_ERROR
        _DESERIALIZED.reason = f"cannot deserialise the FMU state: {type(e).__name__}: {e}"
        return {"format": "invalid", "reason": _DESERIALIZED.reason}
    _DESERIALIZED.status = FMI_OK
    return s
