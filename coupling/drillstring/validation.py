"""The drillstring description's defaults, its input error and the checks of the numbers it is given."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["G", "DEFAULT_YOUNGS_MODULUS", "DEFAULT_DENSITY", "DEFAULT_MAX_ELEMENT_LENGTH", "DEFAULT_RTOL",
           "MASS_SCHEMES", "DEFAULT_MASS", "DrillStringError", "is_number", "check_number", "check_int",
           "check_mass"]

G = 9.81
#: Default Young's modulus of steel [Pa].
DEFAULT_YOUNGS_MODULUS = 2.07e11
#: Default density of steel [kg/m^3].
DEFAULT_DENSITY = 7850.0
#: Default longest element [m] (in the fastest section) when a section gives
#: neither ``elements`` nor ``max_element_length``; the travel time
#: ``tau = max_element_length / max(c)`` then sizes every section.
DEFAULT_MAX_ELEMENT_LENGTH = 10.0
#: Default target relative accuracy of the natural frequencies in range [-].
DEFAULT_RTOL = 1e-5
#: Mass-matrix schemes.
MASS_SCHEMES = ("lumped", "consistent", "mixed")
#: Default mass-matrix scheme (fourth-order accurate).
DEFAULT_MASS = "mixed"


class DrillStringError(ValueError):
    """Invalid drillstring description.

    The message names where the problem is (file, section), the key, the
    offending value and the allowed range; the same pieces are available as
    attributes ``where``, ``key``, ``value`` and ``allowed``.
    """

    def __init__(self, where: str, key: str | None, value: Any, allowed: str):
        self.where = where
        self.key = key
        self.value = value
        self.allowed = allowed
        super().__init__(self._format())

    def _format(self) -> str:
        parts = [self.where] if self.where else []
        if self.key is not None:
            parts.append(f"key '{self.key}' = {self.value!r}")
        parts.append(self.allowed)
        return ": ".join(parts)

    def with_prefix(self, prefix: str) -> "DrillStringError":
        """Return a copy whose location is prefixed (e.g. by the file name)."""
        where = f"{prefix}: {self.where}" if self.where else prefix
        return DrillStringError(where, self.key, self.value, self.allowed)


def is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def check_number(where: str, key: str, value: Any, lo: float | None, hi: float | None,
                  *, lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``float(value)`` or raise :class:`DrillStringError` with the range."""
    lo_s = "" if lo is None else f"{lo:g} {'<' if lo_open else '<='} "
    hi_s = "" if hi is None else f" {'<' if hi_open else '<='} {hi:g}"
    allowed = f"allowed range {lo_s}{key}{hi_s}{(' ' + unit) if unit else ''}"
    if not is_number(value) or not math.isfinite(float(value)):
        raise DrillStringError(where, key, value, f"must be a finite number; {allowed}")
    x = float(value)
    bad = (lo is not None and (x <= lo if lo_open else x < lo)) or \
          (hi is not None and (x >= hi if hi_open else x > hi))
    if bad:
        raise DrillStringError(where, key, value, allowed)
    return x


def check_int(where: str, key: str, value: Any, lo: int, hi: int) -> int:
    allowed = f"allowed range {lo} <= {key} <= {hi} (integer)"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if is_number(value) and float(value).is_integer():
            value = int(value)
        else:
            raise DrillStringError(where, key, value, f"must be an integer; {allowed}")
    if not lo <= int(value) <= hi:
        raise DrillStringError(where, key, value, allowed)
    return int(value)


def check_mass(mass: str) -> None:
    if mass not in MASS_SCHEMES:
        raise ValueError(f"mass = {mass!r}: allowed values {', '.join(MASS_SCHEMES)}")
