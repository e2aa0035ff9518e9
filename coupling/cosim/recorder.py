"""The recorder of a co-simulation run: the recorded series, ``time`` first."""
from __future__ import annotations

import numpy as np

from hammerbit.cosim.config import CosimConfig, record_dtype
from hammerbit.cosim.exchange import EXCHANGE_OUT_FORCE
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

    def add(self, t, h, r_step, defect, wob_diff) -> None:
        if self.j == len(self.data):
            self.data = np.concatenate([self.data, np.zeros_like(self.data)])
        lane = self.lane
        out = lane.out
        row = self.data[self.j]
        row[0] = t
        cols = self.cols
        for i, k in cols["out"]:
            row[i] = out[k]
        if cols["arg"]:
            args = (h, r_step, defect, wob_diff)     # wob_diff: the difference now, the factor at the end
            for i, k in cols["arg"]:
                row[i] = args[k]
        for i, n in cols["lane"]:
            row[i] = lane.sc[EXCHANGE_OUT_FORCE] if n == "interface_force" else lane.F_held
        if self.need_flags:
            fl = flags_of(lane.hammer)
            for i, k in cols["flag"]:
                row[i] = fl[k]
        if self.need_string:
            so = lane.string.outputs()
            for i, k in cols["str"]:
                row[i] = so[k]
        self.j += 1

    def result(self) -> np.ndarray:
        return np.ascontiguousarray(self.data[:self.j]).view(self.dtype).reshape(self.j)
