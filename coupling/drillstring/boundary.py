"""The end conditions of the drillstring (fixed, free, spring, hammer) and their text form."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Mapping

from .validation import DrillStringError, check_number

__all__ = ["Boundary", "parse_boundary", "check_end"]

_BOUNDARY_KINDS = ("fixed", "free", "spring", "hammer")


@dataclass(frozen=True)
class Boundary:
    """End condition of the string.

    ``kind`` is one of

    * ``"fixed"`` -- the end node does not move (a rigid hook at the top, a
      rigid rock at the bit);
    * ``"free"`` -- no force, optionally carrying a lumped ``mass``;
    * ``"spring"`` -- a spring ``stiffness`` and dashpot ``damping`` to the
      ground (derrick/drill line at the top; bit-rock contact at the bit),
      optionally with a lumped ``mass`` on the end node;
    * ``"hammer"`` (bottom only) -- the bottom node is left **free** in this
      module; the co-simulation attaches the hammer body to it through a
      spring-dashpot with this ``stiffness`` and ``damping``: the force on the
      string's bottom node is ``stiffness*(x_h - x_b) + damping*(v_h - v_b)``
      (positive downward), applied through the input of :func:`state_space`.
    """

    kind: str = "free"
    """``"fixed"``, ``"free"``, ``"spring"`` or ``"hammer"``."""
    stiffness: float = 0.0
    """Spring stiffness to ground (spring) or interface stiffness (hammer) [N/m]."""
    damping: float = 0.0
    """Dashpot to ground (spring) or interface damping (hammer) [N s/m]."""
    mass: float = 0.0
    """Lumped mass on the end node [kg] (free or spring ends only)."""

    def __post_init__(self) -> None:
        w = "boundary"
        if self.kind not in _BOUNDARY_KINDS:
            raise DrillStringError(w, "kind", self.kind, f"allowed values {', '.join(_BOUNDARY_KINDS)}")
        w = f"boundary '{self.kind}'"
        k = check_number(w, "stiffness", self.stiffness, 0.0, 1e15, unit="N/m")
        c = check_number(w, "damping", self.damping, 0.0, 1e12, unit="N s/m")
        m = check_number(w, "mass", self.mass, 0.0, 1e7, unit="kg")
        if self.kind == "fixed" and (k or c or m):
            raise DrillStringError(w, "stiffness/damping/mass", (k, c, m),
                                   "a fixed end takes no stiffness, damping or mass")
        if self.kind == "free" and (k or c):
            raise DrillStringError(w, "stiffness/damping", (k, c),
                                   "a free end takes no stiffness or damping (use kind 'spring')")
        if self.kind in ("spring", "hammer") and k <= 0.0:
            raise DrillStringError(w, "stiffness", self.stiffness, "allowed range 0 < stiffness <= 1e15 N/m")
        if self.kind == "hammer" and m:
            raise DrillStringError(w, "mass", self.mass, "the hammer mass belongs to the hammer model; must be 0")

    @classmethod
    def fixed(cls) -> "Boundary":
        """A fixed end."""
        return cls("fixed")

    @classmethod
    def free(cls, mass: float = 0.0) -> "Boundary":
        """A free end, optionally with a lumped ``mass`` [kg]."""
        return cls("free", mass=mass)

    @classmethod
    def spring(cls, stiffness: float, damping: float = 0.0, mass: float = 0.0) -> "Boundary":
        """Spring [N/m] and dashpot [N s/m] to ground, optional end ``mass`` [kg]."""
        return cls("spring", stiffness, damping, mass)

    @classmethod
    def hammer(cls, stiffness: float, damping: float = 0.0) -> "Boundary":
        """Bottom node free; hammer attached through this interface spring-dashpot."""
        return cls("hammer", stiffness, damping)

    @property
    def is_fixed(self) -> bool:
        return self.kind == "fixed"

    @property
    def ground_stiffness(self) -> float:
        """Stiffness to ground that enters ``K`` [N/m] (0 for hammer/free/fixed)."""
        return self.stiffness if self.kind == "spring" else 0.0

    @property
    def ground_damping(self) -> float:
        """Dashpot to ground that enters ``C`` [N s/m]."""
        return self.damping if self.kind == "spring" else 0.0

    def spec(self) -> str:
        """Compact text form accepted by :func:`parse_boundary`."""
        if self.kind == "fixed":
            return "fixed"
        if self.kind == "free":
            return "free" if not self.mass else f"free:{self.mass:g}"
        if self.kind == "hammer":
            return f"hammer:{self.stiffness:g}:{self.damping:g}"
        s = f"spring:{self.stiffness:g}"
        if self.damping or self.mass:
            s += f":{self.damping:g}"
        if self.mass:
            s += f":{self.mass:g}"
        return s

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def parse_boundary(spec: "Boundary | str | Mapping[str, Any]", *, where: str = "boundary") -> Boundary:
    """Build a :class:`Boundary` from a text spec, a mapping or a Boundary.

    Text forms: ``fixed``, ``free``, ``free:MASS``, ``mass:MASS``,
    ``spring:K``, ``spring:K:C``, ``spring:K:C:MASS``, ``hammer:K``,
    ``hammer:K:C`` with K [N/m], C [N s/m], MASS [kg].  Mappings take the keys
    ``kind``, ``stiffness``, ``damping``, ``mass``.
    """
    if isinstance(spec, Boundary):
        return spec
    try:
        if isinstance(spec, Mapping):
            bad = set(spec) - {"kind", "stiffness", "damping", "mass"}
            if bad:
                key = sorted(bad)[0]
                raise DrillStringError(where, key, spec[key],
                                       "unknown key; allowed keys kind, stiffness, damping, mass")
            return Boundary(**dict(spec))
        if not isinstance(spec, str):
            raise DrillStringError(where, None, spec, f"cannot read boundary {spec!r}")
        parts = [p.strip() for p in spec.strip().split(":")]
        kind = parts[0].lower()
        try:
            nums = [float(p) for p in parts[1:]]
        except ValueError:
            raise DrillStringError(where, "spec", spec,
                                   "numbers after ':' must parse as floats, e.g. spring:1e8:2e4") from None
        nmax = {"fixed": 0, "free": 1, "mass": 1, "spring": 3, "hammer": 2}.get(kind)
        if nmax is None:
            raise DrillStringError(where, "kind", kind,
                                   "allowed values fixed, free[:M], mass:M, spring:K[:C[:M]], hammer:K[:C]")
        if len(nums) > nmax or (kind in ("mass", "spring", "hammer") and not nums):
            raise DrillStringError(where, "spec", spec,
                                   "allowed forms fixed, free[:M], mass:M, spring:K[:C[:M]], hammer:K[:C]")
        if kind == "fixed":
            return Boundary.fixed()
        if kind in ("free", "mass"):
            return Boundary.free(nums[0] if nums else 0.0)
        if kind == "spring":
            return Boundary.spring(*nums)
        return Boundary.hammer(*nums)
    except DrillStringError as err:
        if err.where.startswith(where):
            raise
        raise err.with_prefix(where) from None
    except TypeError as err:  # bad keyword types in mapping
        raise DrillStringError(where, None, spec, str(err)) from None


def check_end(b: Boundary, end: str) -> Boundary:
    if end == "top" and b.kind == "hammer":
        raise DrillStringError("boundary top", "kind", b.kind, "allowed values at the top: fixed, free, spring")
    return b
