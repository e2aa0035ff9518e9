"""The recorder of a co-simulation run: the recorded series, ``time`` first."""
from __future__ import annotations

import numpy as np

from hammerbit.cosim.config import CosimConfig, record_dtype
from hammerbit.cosim.hammer_interface import (OUT_BIT_POSITION, OUT_BIT_VELOCITY, OUT_HAMMER_POSITION,
                                              OUT_HAMMER_VELOCITY, OUT_WOB, flags_of)
from hammerbit.cosim.lane import Lane

__all__ = ["Recorder"]


class Recorder:
    """The recorded series (grows as needed; adaptive runs do not know their length).

    Rows go into a plain float array (one column per variable, ``time`` first), viewed as
    the structured array of :func:`record_dtype` at the end; the string's outputs are read with
    one product per row."""

    #: Variables read from the lane's hammer outputs ``out`` (their index there).
    _OUT = {"wob": OUT_WOB, "hammer_position": OUT_HAMMER_POSITION, "hammer_velocity": OUT_HAMMER_VELOCITY,
            "bit_position": OUT_BIT_POSITION, "bit_velocity": OUT_BIT_VELOCITY}
    #: Variables of :meth:`add`'s arguments (their position after ``t``).
    _ARG = {"step_size": 0, "energy_residual": 1, "force_defect": 2, "wob_error_estimate": 3}
    #: The string's outputs (row of ``StringState.outputs``).
    _STR = {"string_bit_displacement": 0, "string_bit_velocity": 1, "hook_load": 2}

    def __init__(self, c: CosimConfig, capacity: int, lane: Lane):
        self.names = tuple(c.record)
        self.dtype = record_dtype(self.names)
        self.data = np.zeros((max(capacity, 2), 1 + len(self.names)))
        self.j = 0
        self.lane = lane
        self.need_flags = "stick" in self.names or "contact" in self.names
        self.need_string = any(n in self._STR for n in self.names)
        cols = {"out": [], "arg": [], "str": [], "flag": [], "lane": []}
        for i, n in enumerate(self.names, start=1):
            if n in self._OUT:
                cols["out"].append((i, self._OUT[n]))
            elif n in self._ARG:
                cols["arg"].append((i, self._ARG[n]))
            elif n in self._STR:
                cols["str"].append((i, self._STR[n]))
            elif n in ("stick", "contact"):
                cols["flag"].append((i, 0 if n == "stick" else 1))
            else:                                   # interface_force, hammer_force
                cols["lane"].append((i, n))
        self.cols = cols
        # the column lists as tuples, the empty ones None: add() runs every step
        self._out_cols = tuple(cols["out"]) or None
        self._arg_cols = tuple(cols["arg"]) or None
        self._lane_cols = tuple(cols["lane"]) or None
        self._flag_cols = tuple(cols["flag"]) if self.need_flags else None
        self._str_cols = tuple(cols["str"]) if self.need_string else None

    def add(self, t, h, r_step, defect, wob_diff) -> None:
        if self.j == len(self.data):
            self.data = np.concatenate([self.data, np.zeros_like(self.data)])
        lane = self.lane
        row = self.data[self.j]
        row[0] = t
        if self._out_cols is not None:
            out = lane.out
            for i, k in self._out_cols:
                row[i] = out[k]
        if self._arg_cols is not None:
            args = (h, r_step, defect, wob_diff)     # wob_diff: the difference now, the factor at the end
            for i, k in self._arg_cols:
                row[i] = args[k]
        if self._lane_cols is not None:
            for i, n in self._lane_cols:
                row[i] = lane.F if n == "interface_force" else lane.F_held
        if self._flag_cols is not None:
            fl = flags_of(lane.hammer)
            for i, k in self._flag_cols:
                row[i] = fl[k]
        if self._str_cols is not None:
            so = lane.string.outputs(t)
            for i, k in self._str_cols:
                row[i] = so[k]
        self.j += 1

    def result(self) -> np.ndarray:
        return np.ascontiguousarray(self.data[:self.j]).view(self.dtype).reshape(self.j)
