"""Checks of a saved HammerBitRock FMU state before it is restored (fmi2DeSerializeFMUstate).

A serialised state comes from outside the process (a file, another tool), so
every field is checked before the slave uses it: the keys, the types, finite
numbers, the stepper array's length, the ranges of its mode and counter
entries (an out-of-range mode would index past the kernel's tables), the
record indexes (the FMU records nothing: an index other than 0 would write
outside the kernel's empty record buffers), positions and velocities within
the state's ranges, a positive step proposal, and the clock within the FMU's
time range.  :func:`state_problem` says what is wrong, or returns None; what
depends on the parameters in use (the kernel's parameter vector, the clock of
the kernel against the communication time) is the slave's to check
(:func:`kernel_problem`).
"""
from __future__ import annotations

import math

import numpy as np

from . import kernel_layouts as K
from .kernel_layouts import N_P
from .validation import RANGES

__all__ = ["STATE_KEYS", "state_problem", "kernel_problem"]

#: keys of a saved state (besides "format" and "build")
STATE_KEYS = ("stepper", "committed", "params", "inputs", "t", "t_start", "ready", "terminated",
              "error")

#: the largest counter a state may hold: every integer below it is exact in a float64
_MAX_COUNT = 2.0 ** 53
#: the event counters are the FMU's Integer outputs (fmi2Integer: 32 bits)
_EVENT_COUNTS = range(K.I_COUNT0, K.I_COUNT0 + K.N_EVENT_KINDS)
_MAX_EVENT_COUNT = 2.0 ** 31 - 1
#: allowed values of the mode entries of the kernel's integer state
_MODES = {K.I_STICK: (K.STICK, K.SLIP), K.I_CONTACT: (K.FREE, K.CONTACT, K.CLAMPED),
          K.I_BOUNCE: (0, 1)}


#: the forcing-period windows of the storm counters start at -1 (no window yet)
_WINDOWS = (K.I_WIN, K.I_SWIN)
_WINDOW_START = -1
#: indexes into the kernel's record buffers (Poincaré rows, requested samples, event log), which
#: the FMU leaves empty: each must be 0
_RECORD_INDEXES = (K.I_POIN_NEXT, K.I_SAMP_NEXT, K.I_NLOG)
#: the ranges of the nondimensional state x1..x4 (the library's own state ranges)
_Y_RANGES = tuple(RANGES[k] for k in ("state.hammer_position", "state.hammer_velocity",
                                      "state.bit_position", "state.hammer_velocity"))
#: the FMU's clock [s]
TIME_RANGE = RANGES["fmu.time"]
#: the kernel's clock tau = omega (t - t_start) may differ from the communication time's by this
#: much, relative to max(1, |tau|) (the driver ends a step at its end time to the last bits)
_TAU_REL_TOL = 1e-9


def _finite_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _stepper_problem(arr, size: int):
    if not isinstance(arr, list) or len(arr) != size:
        n = len(arr) if isinstance(arr, list) else type(arr).__name__
        return f"the stepper state has {n} entries, this model's has {size}"
    # numbers, none NaN; the kernel's parameters may hold inf (no gap: R = inf)
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and v == v for v in arr):
        return "the stepper state holds a NaN or non-numeric entry"
    n_y = size - K.N_ISTATE - K.N_FSTATE - N_P
    f0 = n_y + K.N_ISTATE
    for i in range(n_y):
        rng = _Y_RANGES[i] if i < len(_Y_RANGES) else RANGES["state.subsystem"]
        if not rng.contains(arr[i]):
            return f"the stepper state's position or velocity entry {i} = {arr[i]!r} is outside {rng.text()}"
    for i in (f0 + K.F_T, f0 + K.F_H):
        if not math.isfinite(arr[i]):
            return f"the stepper state's time or step (entry {i}) is {arr[i]!r}"
    if not arr[f0 + K.F_H] > 0.0:
        return f"the stepper state's step proposal {arr[f0 + K.F_H]!r} is not positive"
    for i, v in enumerate(arr[n_y:f0]):
        lowest = _WINDOW_START if i in _WINDOWS else 0
        if not math.isfinite(v) or v != int(v) or not lowest <= v < _MAX_COUNT:
            return f"integer state entry {i} = {v!r} is not a count in [{lowest}, 2**53)"
        if i in _EVENT_COUNTS and v > _MAX_EVENT_COUNT:
            return f"event counter entry {i} = {v!r} is above 2**31 - 1 (its output is a 32-bit Integer)"
        allowed = _MODES.get(i)
        if allowed is not None and int(v) not in allowed:
            return f"mode entry {i} = {v!r} is not one of {allowed}"
        if i in _RECORD_INDEXES and v != 0:
            return f"record index entry {i} = {v!r} is not 0 (the FMU's record buffers are empty)"
    return None


def kernel_problem(stepper, p_expected, t: float, t_start: float, omega: float, input_limits):
    """Why the stepper array of a state does not fit the parameters in use (None: it does).

    ``p_expected`` is the kernel parameter vector the parameters in use give; its input entries
    (preload ``P_B`` and the extra force ``P_FEXT``, held over a step) need only lie within
    ``input_limits`` (their bounds / F0); ``omega`` the time scale of the kernel's clock."""
    n_p = len(p_expected)
    p = stepper[len(stepper) - n_p:]
    for i, (have, want) in enumerate(zip(p, p_expected)):
        if i in (K.P_B, K.P_FEXT):
            limit = input_limits[0 if i == K.P_B else 1]
            if not abs(have) <= limit:
                return f"the kernel's input entry p[{i}] = {have!r} is outside +-{limit!r}"
        elif have != float(want):
            return f"the kernel's parameter p[{i}] = {have!r} is not {float(want)!r}, what the parameters in use give"
    n_y = len(stepper) - K.N_ISTATE - K.N_FSTATE - n_p
    tau = stepper[n_y + K.N_ISTATE + K.F_T]
    want = (t - t_start) * omega
    if not abs(tau - want) <= _TAU_REL_TOL * max(1.0, abs(want)):
        return f"the kernel's clock tau = {tau!r} is not omega (t - t_start) = {want!r}"
    return _forces_problem(stepper[:4], int(stepper[n_y + K.I_CONTACT]), p)


def _forces_problem(y, contact_mode: int, p):
    """Why the contact mode does not fit the positions (None: it does): in contact, the contact
    law's force must be finite (contact marked without an impact device, whose gap is infinite,
    gives an infinite force)."""
    if contact_mode != K.CONTACT:
        return None
    from . import kernel_forces as KF
    y, p = np.asarray(y, dtype=float), np.asarray(p, dtype=float)
    with np.errstate(all="ignore"):
        force = KF.contact_force(KF.overlap(y, p), y[1] - y[3], p, contact_mode)
    if not math.isfinite(force):
        return f"the contact mode does not fit the positions: the contact force is {force!r}"
    return None


def state_problem(s, size: int, param_names, n_inputs: int):
    """Why the decoded state ``s`` cannot be restored (None: it can).

    ``size`` is the length of the stepper array, ``param_names`` the names in
    ``params``/``committed``, ``n_inputs`` the number of input values.  The
    ranges that depend on the parameters (the committed parameters, the inputs'
    bounds) are the slave's to check.
    """
    missing = [k for k in STATE_KEYS if k not in s]
    if missing:
        return f"fields missing: {', '.join(missing)}"
    why = _stepper_problem(s["stepper"], size)
    if why:
        return why
    for key in ("t", "t_start"):
        if not (_finite_number(s[key]) and TIME_RANGE.contains(s[key])):
            return f"{key} = {s[key]!r} is not a time in {TIME_RANGE.text()}"
    if s["t"] < s["t_start"]:
        return f"t = {s['t']!r} s is before t_start = {s['t_start']!r} s"
    for key in ("params", "committed"):
        d = s[key]
        if not isinstance(d, dict) or set(d) != set(param_names):
            return f"{key} does not name this model's parameters"
        for name, v in d.items():
            ok = isinstance(v, bool) if name == "impact_enabled" else _finite_number(v)
            if not ok:
                return f"{key}[{name!r}] = {v!r} is not a {'Boolean' if name == 'impact_enabled' else 'finite number'}"
    inputs = s["inputs"]
    if not (isinstance(inputs, (list, tuple)) and len(inputs) == n_inputs
            and all(_finite_number(v) for v in inputs)):
        return f"inputs = {inputs!r} is not {n_inputs} finite numbers"
    for key in ("ready", "terminated"):
        if not isinstance(s[key], bool):
            return f"{key} = {s[key]!r} is not a Boolean"
    if s["error"] is not None and not isinstance(s["error"], str):
        return f"error = {s['error']!r} is not a text"
    return None
