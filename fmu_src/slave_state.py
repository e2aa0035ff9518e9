"""The saved state of the HammerBitRock FMU: fmi2GetFMUstate, fmi2SetFMUstate and their serialisation.

A mixin of :class:`~.slave.HammerBitRock`: the whole hidden state is saved, so
get-step-set-step is bit-identical; a state from outside (deserialised) is
checked field by field before it is used.
"""
from __future__ import annotations

import math

import numpy as np

from . import build_info
from .fmu_state import STATE_FORMAT, state_from_bytes, state_to_bytes
from .fmu_state_checks import kernel_problem, state_problem
from .fmu_variables import FIXED_REALS, INPUT_GROUPS, INPUTS, input_range
from .validation import RANGES
from .validation import ParameterError
from .fmi_status import OK


class SavedState:
    """fmi2GetFMUstate / fmi2SetFMUstate and their bytes."""

    # ------------------------------------------------------------------
    # FMU state
    # ------------------------------------------------------------------
    def _get_fmu_state(self):
        try:
            state = {
                "format": STATE_FORMAT,
                "build": build_info.BUILD_HASH,
                "stepper": self._st.get_state(),
                "committed": dict(self._committed),
                "params": self._param_values(),
                "inputs": (float(self.preload), float(self.harmonic_force)),
                "t": self._t,
                "t_start": self._t_start,
                "ready": self._ready,
                "terminated": self._terminated,
                "error": self._error,
            }
        except Exception as e:  # noqa: BLE001 -- an exception would be fmi2Fatal in pythonfmu
            self._fail(f"fmi2GetFMUstate failed: {type(e).__name__}: {e}")
            return {"format": "invalid", "reason": repr(e)}
        self.last_status = OK
        return state

    def _set_fmu_state(self, state):
        try:
            if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
                reason = state.get("reason") if isinstance(state, dict) else None
                return self._fail(f"fmi2SetFMUstate: not a {STATE_FORMAT} state"
                                  + (f" ({reason})" if reason else "") + "; state unchanged")
            arr = np.asarray(state["stepper"], dtype=np.float64)
            if arr.shape != self._st.get_state().shape or np.any(np.isnan(arr)):
                return self._fail(f"fmi2SetFMUstate: the stepper state (length {arr.shape[0]}) does not "
                                  f"fit or holds NaN; state unchanged")
            committed = state["committed"]
            t_start_old = self._t_start
            self._t_start = float(state["t_start"])
            try:
                if committed != self._committed or self._t_start != t_start_old:
                    self._commit(committed, warm_up=False, keep_state=arr)
                else:
                    self._st.set_state(arr)
                    self._applied_preload = self._applied_force = math.nan
            except Exception:
                self._t_start = t_start_old
                raise
            for name, v in state["params"].items():
                setattr(self, name, v)
            self._dirty = state["params"] != committed
            self._slow = True
            self._stale = False
            self.preload, self.harmonic_force = state["inputs"]
            # the inputs in the kernel's parameters now, so the regime verdict is the state's own
            self._apply_inputs(self._p)
            self._regime_seen = self._regime()
            self._t = float(state["t"])
            self._ready = bool(state["ready"])
            self._terminated = bool(state.get("terminated", False))
            self._error = state["error"]
            self.last_status = OK
        except Exception as e:  # noqa: BLE001 -- an exception would be fmi2Fatal in pythonfmu
            self._fail(f"fmi2SetFMUstate failed: {type(e).__name__}: {e}; state unchanged")

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        return state_to_bytes(state)

    @classmethod
    def _fmu_state_from_bytes(cls, data: bytes):
        return state_from_bytes(data, check=cls._state_body_problem)

    @classmethod
    def _state_body_problem(cls, s: dict):
        """Why a decoded state cannot be restored into this model (None: it can)."""
        why = state_problem(s, cls._STATE_SIZE, FIXED_REALS + ("impact_enabled", "tolerance"),
                            len(INPUTS))
        if why:
            return why
        try:
            rig, _ = cls._validate(s["committed"])
        except ParameterError as e:
            return f"its parameters in use are invalid: {e}"
        for name, v in zip((i.name for i in INPUTS), s["inputs"]):
            rng = input_range(name, rig.scales.friction_force)
            if not rng.contains(v):
                return f"input {name!r} = {v!r} is outside {rng.text()} (1000 F0 of its parameters)"
        # the kernel's arrays as the parameters in use build them (the slave's _commit)
        groups = rig.to_groups()
        if s["t_start"] != 0.0:
            groups = groups.replace(phi=math.fmod(rig.phase + 2.0 * math.pi * rig.frequency * s["t_start"],
                                                  2.0 * math.pi))
        # the inputs enter the kernel divided by F0: their group's bound, and a rounding's margin
        limits = [RANGES[INPUT_GROUPS[name]].hi * (1.0 + 1e-12) for name in ("preload", "harmonic_force")]
        return kernel_problem(s["stepper"], groups.to_kernel(), s["t"], s["t_start"], rig.scales.omega, limits)

