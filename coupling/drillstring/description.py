"""The string description: sections, end conditions, the TOML schema and the mesh sizes.

A string is a chain of uniform sections listed top to bottom.  Depth ``z`` is
0 at the top node and grows downward; displacements are positive downward.

Mesh
    Elements are sized by **equal travel time** ``h/c`` across sections: every
    element of the string takes about the same time ``tau`` for an axial wave
    to cross it, so neighbouring elements see the same ``k h = omega tau`` and
    the mixed mass keeps its fourth-order accuracy through section junctions.
    ``tau`` comes from the string's ``max_element_length`` (the longest element
    of the fastest section, default 10 m) or, in :func:`~hammerbit.drillstring.modes`
    and the check, from a target accuracy (see :meth:`DrillString.for_accuracy`).

The bit mass
    A mass written into the default bottom (``bottom = "free:MASS"`` or
    ``"spring:K:C:MASS"``) is the bit's lumped mass.  Every bottom condition
    that states no mass of its own (``on_bottom``, ``off_bottom``, a ``hammer``
    interface, a ``--bottom`` given on the command line) carries it too; see
    :meth:`DrillString.resolve_bottom`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

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

_DATA_DIR = Path(__file__).resolve().parent.parent / "data"


# --------------------------------------------------------------------------
# errors and validation helpers
# --------------------------------------------------------------------------
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


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _check_number(where: str, key: str, value: Any, lo: float | None, hi: float | None,
                  *, lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``float(value)`` or raise :class:`DrillStringError` with the range."""
    lo_s = "" if lo is None else f"{lo:g} {'<' if lo_open else '<='} "
    hi_s = "" if hi is None else f" {'<' if hi_open else '<='} {hi:g}"
    allowed = f"allowed range {lo_s}{key}{hi_s}{(' ' + unit) if unit else ''}"
    if not _is_number(value) or not math.isfinite(float(value)):
        raise DrillStringError(where, key, value, f"must be a finite number; {allowed}")
    x = float(value)
    bad = (lo is not None and (x <= lo if lo_open else x < lo)) or \
          (hi is not None and (x >= hi if hi_open else x > hi))
    if bad:
        raise DrillStringError(where, key, value, allowed)
    return x


def _check_int(where: str, key: str, value: Any, lo: int, hi: int) -> int:
    allowed = f"allowed range {lo} <= {key} <= {hi} (integer)"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if _is_number(value) and float(value).is_integer():
            value = int(value)
        else:
            raise DrillStringError(where, key, value, f"must be an integer; {allowed}")
    if not lo <= int(value) <= hi:
        raise DrillStringError(where, key, value, allowed)
    return int(value)


# --------------------------------------------------------------------------
# description dataclasses
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """One uniform section of the string (drill pipe, heavy-weight, collars ...)."""

    name: str
    """Label used in messages, tables and plots."""
    length: float
    """Section length [m]; 0 < length <= 20000."""
    od: float
    """Outer diameter [m]; 0 < od <= 2."""
    id: float
    """Inner diameter [m]; 0 <= id < od (0 for a solid bar)."""
    youngs_modulus: float = DEFAULT_YOUNGS_MODULUS
    """Young's modulus E [Pa]; 1e9 <= E <= 1e12.  Default 2.07e11 (steel)."""
    density: float = DEFAULT_DENSITY
    """Density of the tube material [kg/m^3]; 500 <= rho <= 25000.  Default 7850.
    Also sets the displaced volume ``linear_mass / density`` used for buoyancy."""
    linear_mass: float | None = None
    """Mass per unit length m' [kg/m] including tool joints and upsets (mass
    only, the stiffness stays ``E*A`` of the tube body); default
    ``density * area``.  Allowed 0.5 to 20 times the body mass per length."""
    elements: int | None = None
    """Number of elements of the section (1..100000); exclusive with
    ``max_element_length``."""
    max_element_length: float | None = None
    """Maximum element length [m] (> 0); the count is ``ceil(length/max)``."""
    viscous_damping: float = 0.0
    """External viscous damping per unit length c' [N s/m^2], i.e. drag force
    per metre of string per m/s of axial velocity; >= 0, default 0."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise DrillStringError("section", "name", self.name, "must be a non-empty string")
        w = f"section '{self.name}'"
        _check_number(w, "length", self.length, 0.0, 20000.0, lo_open=True, unit="m")
        _check_number(w, "od", self.od, 0.0, 2.0, lo_open=True, unit="m")
        _check_number(w, "id", self.id, 0.0, float(self.od), hi_open=True, unit="m (id < od)")
        _check_number(w, "youngs_modulus", self.youngs_modulus, 1e9, 1e12, unit="Pa")
        _check_number(w, "density", self.density, 500.0, 25000.0, unit="kg/m3")
        body = self.density * self.area
        if self.linear_mass is not None:
            _check_number(w, "linear_mass", self.linear_mass, 0.5 * body, 20.0 * body,
                          unit=f"kg/m (0.5 to 20 x body mass {body:.4g} kg/m)")
        if self.elements is not None and self.max_element_length is not None:
            raise DrillStringError(w, "elements", self.elements,
                                   "give either 'elements' or 'max_element_length', not both")
        if self.elements is not None:
            object.__setattr__(self, "elements", _check_int(w, "elements", self.elements, 1, 100000))
        if self.max_element_length is not None:
            _check_number(w, "max_element_length", self.max_element_length, 0.0, 20000.0,
                          lo_open=True, unit="m")
        _check_number(w, "viscous_damping", self.viscous_damping, 0.0, 1e9, unit="N s/m^2")

    # derived properties -------------------------------------------------
    @property
    def area(self) -> float:
        """Steel cross-section area ``pi/4 (od^2 - id^2)`` [m^2]."""
        return math.pi / 4.0 * (self.od ** 2 - self.id ** 2)

    @property
    def mass_per_length(self) -> float:
        """Linear mass m' [kg/m] (``linear_mass`` or ``density * area``)."""
        return float(self.linear_mass) if self.linear_mass is not None else self.density * self.area

    @property
    def axial_stiffness(self) -> float:
        """Axial rigidity ``E A`` [N]."""
        return self.youngs_modulus * self.area

    @property
    def wave_speed(self) -> float:
        """Axial wave speed ``c = sqrt(EA/m')`` [m/s]."""
        return math.sqrt(self.axial_stiffness / self.mass_per_length)

    @property
    def impedance(self) -> float:
        """Characteristic axial impedance ``Z = sqrt(EA m')`` [N s/m]."""
        return math.sqrt(self.axial_stiffness * self.mass_per_length)

    def buoyancy_factor(self, mud_density: float) -> float:
        """``1 - rho_mud/rho`` [-]."""
        return 1.0 - mud_density / self.density


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
        k = _check_number(w, "stiffness", self.stiffness, 0.0, 1e15, unit="N/m")
        c = _check_number(w, "damping", self.damping, 0.0, 1e12, unit="N s/m")
        m = _check_number(w, "mass", self.mass, 0.0, 1e7, unit="kg")
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


def _check_end(b: Boundary, end: str) -> Boundary:
    if end == "top" and b.kind == "hammer":
        raise DrillStringError("boundary top", "kind", b.kind, "allowed values at the top: fixed, free, spring")
    return b


@dataclass(frozen=True)
class Mesh:
    """Element arrays of a discretised string (all SI, shapes noted)."""

    z: np.ndarray
    """Node depths (n_nodes,) [m], 0 at the top node."""
    h: np.ndarray
    """Element lengths (n_el,) [m]."""
    section_index: np.ndarray
    """Index of the section of each element (n_el,)."""
    ea: np.ndarray
    """Axial rigidity per element (n_el,) [N]."""
    m: np.ndarray
    """Linear mass per element (n_el,) [kg/m]."""
    cv: np.ndarray
    """Viscous damping per unit length per element (n_el,) [N s/m^2]."""
    q: np.ndarray
    """Buoyed weight per unit length per element (n_el,) [N/m]."""

    @property
    def n_nodes(self) -> int:
        return int(self.z.size)

    @property
    def n_elements(self) -> int:
        return int(self.h.size)


@dataclass(frozen=True)
class DrillString:
    """A vertical drillstring: sections top to bottom plus defaults.

    The boundary fields are defaults used when a function is called without
    explicit ``top``/``bottom`` (``modes``) or ``on_bottom``/``off_bottom``
    (the avoidance check).
    """

    sections: tuple[Section, ...]
    """Sections, top to bottom."""
    name: str = "drillstring"
    """Label."""
    description: str = ""
    """Free text."""
    modal_damping_ratio: float = 0.0
    """Damping ratio zeta [-] (0 <= zeta < 1): the frequency response and the
    check use the hysteretic loss factor ``2 zeta`` (mesh-independent); the
    state space of the co-simulation gives every mode the ratio zeta."""
    mud_density: float = 0.0
    """Mud density [kg/m^3] for buoyancy; 0 = none (in air)."""
    max_element_length: float = DEFAULT_MAX_ELEMENT_LENGTH
    """Longest element [m] of the fastest section for sections without a mesh
    spec; the others get the same travel time ``h/c``."""
    top: Boundary = Boundary("fixed")
    """Default top boundary (hook)."""
    bottom: Boundary = Boundary("free")
    """Default bottom boundary for :func:`modes`."""
    on_bottom: Boundary = Boundary("fixed")
    """Bottom boundary with the bit on bottom (avoidance check)."""
    off_bottom: Boundary = Boundary("free")
    """Bottom boundary with the bit off bottom (avoidance check)."""

    def __post_init__(self) -> None:
        secs = tuple(self.sections)
        if not secs:
            raise DrillStringError(f"string '{self.name}'", "section", [], "at least one [[section]] is required")
        for s in secs:
            if not isinstance(s, Section):
                raise DrillStringError(f"string '{self.name}'", "section", s, "must be Section objects")
        object.__setattr__(self, "sections", secs)
        w = f"string '{self.name}'"
        _check_number(w, "modal_damping_ratio", self.modal_damping_ratio, 0.0, 1.0, hi_open=True)
        _check_number(w, "mud_density", self.mud_density, 0.0, 3000.0, unit="kg/m3")
        for s in secs:
            if self.mud_density >= s.density:
                raise DrillStringError(f"{w}, section '{s.name}'", "mud_density", self.mud_density,
                                       f"must be < section density {s.density:g} kg/m3")
        _check_number(w, "max_element_length", self.max_element_length, 0.0, 20000.0, lo_open=True, unit="m")
        for end in ("top", "bottom", "on_bottom", "off_bottom"):
            b = parse_boundary(getattr(self, end), where=f"{w}, boundary {end}")
            object.__setattr__(self, end, _check_end(b, "top" if end == "top" else "bottom"))

    # construction helpers ----------------------------------------------
    @classmethod
    def uniform(cls, length: float, od: float, id: float, *, name: str = "uniform",
                elements: int | None = None, **section_kw: Any) -> "DrillString":
        """A one-section string (``section_kw`` go to :class:`Section`)."""
        sec = Section(name, length, od, id, elements=elements, **section_kw)
        return cls((sec,), name=name)

    def replace(self, **changes: Any) -> "DrillString":
        """``dataclasses.replace`` shortcut."""
        return dataclasses.replace(self, **changes)

    def with_elements(self, elements: Sequence[int] | int) -> "DrillString":
        """Copy with explicit element counts per section (int = same for all)."""
        if isinstance(elements, (int, np.integer)):
            elements = [int(elements)] * len(self.sections)
        if len(elements) != len(self.sections):
            raise ValueError("one element count per section is required")
        secs = tuple(dataclasses.replace(s, elements=int(n), max_element_length=None)
                     for s, n in zip(self.sections, elements))
        return self.replace(sections=secs)

    def for_accuracy(self, f_max: float, rtol: float = DEFAULT_RTOL, mass: str = DEFAULT_MASS, *,
                     min_per_section: int = 2) -> "DrillString":
        """Copy meshed by equal travel time so that the dispersion error at
        ``f_max`` [Hz] is below ``rtol`` (never coarser than this string's mesh).

        The travel time per element is ``tau = theta / (2 pi f_max)`` with
        ``theta`` from ``(k h)^4/480 = rtol`` (mixed mass) or ``(k h)^2/24 =
        rtol`` (lumped, consistent); every section gets ``ceil(l / (c tau))``
        elements, at least ``min_per_section``.
        """
        tau = _theta_max(rtol, mass) / (2.0 * math.pi * float(f_max))
        return self.with_travel_time(tau, min_per_section=min_per_section)

    def with_travel_time(self, tau: float, *, min_per_section: int = 1) -> "DrillString":
        """Copy with ``ceil(l/(c tau))`` elements per section (never fewer than now)."""
        counts = [max(n, min_per_section, int(math.ceil(s.length / (s.wave_speed * tau) - 1e-9)))
                  for s, n in zip(self.sections, self.elements_per_section)]
        return self.with_elements(counts)

    def refined(self, f_max: float, rel_tol: float = 1e-3, mass: str = DEFAULT_MASS) -> "DrillString":
        """Older name of :meth:`for_accuracy` (``min_per_section = 1``)."""
        return self.for_accuracy(f_max, rel_tol, mass, min_per_section=1)

    @property
    def travel_times(self) -> np.ndarray:
        """Travel time ``h/c`` of the elements of each section (n_sections,) [s]."""
        return np.array([s.length / n / s.wave_speed for s, n in zip(self.sections, self.elements_per_section)])

    @property
    def bit_mass(self) -> float:
        """Lumped mass at the bit [kg]: the mass of the default ``bottom``."""
        return float(self.bottom.mass) if self.bottom.kind in ("free", "spring") else 0.0

    def resolve_bottom(self, bottom: "Boundary | str | None" = None, *, where: str = "bottom") -> Boundary:
        """The bottom condition with the bit mass applied.

        ``None`` is the default ``bottom``.  A ``free`` or ``spring`` bottom that
        states no mass gets :attr:`bit_mass`; a ``hammer`` interface keeps its
        kind (the bit mass is added to the bit node in the assembly); a
        ``fixed`` bit does not move.
        """
        b = _check_end(parse_boundary(self.bottom if bottom is None else bottom, where=where), "bottom")
        if b.kind in ("free", "spring") and b.mass == 0.0 and self.bit_mass > 0.0:
            b = dataclasses.replace(b, mass=self.bit_mass)
        return b

    # derived ---------------------------------------------------------------
    @property
    def length(self) -> float:
        """Total length [m]."""
        return float(sum(s.length for s in self.sections))

    @property
    def mass(self) -> float:
        """Total mass [kg] (without boundary masses)."""
        return float(sum(s.mass_per_length * s.length for s in self.sections))

    @property
    def buoyed_weight(self) -> float:
        """Buoyed weight of the sections [N]."""
        return float(sum(s.mass_per_length * s.length * G * s.buoyancy_factor(self.mud_density)
                         for s in self.sections))

    @property
    def elements_per_section(self) -> tuple[int, ...]:
        """Element count of each section: explicit ``elements``, the section's
        ``max_element_length``, or equal travel time ``tau = max_element_length
        / max(c)`` of the string (the fastest section gets elements of at most
        ``max_element_length``, every other section the same ``h/c``)."""
        tau = self.max_element_length / max(s.wave_speed for s in self.sections)
        out = []
        for s in self.sections:
            if s.elements is not None:
                out.append(int(s.elements))
            elif s.max_element_length is not None:
                out.append(max(1, int(math.ceil(s.length / s.max_element_length - 1e-12))))
            else:
                out.append(max(1, int(math.ceil(s.length / (s.wave_speed * tau) - 1e-9))))
        return tuple(out)

    @property
    def n_elements(self) -> int:
        return int(sum(self.elements_per_section))

    def mesh(self) -> Mesh:
        """Element arrays (vectorised, one entry per element)."""
        counts = np.asarray(self.elements_per_section)
        idx = np.repeat(np.arange(len(self.sections)), counts)
        h_sec = np.array([s.length for s in self.sections]) / counts
        h = h_sec[idx]
        ea = np.array([s.axial_stiffness for s in self.sections])[idx]
        m = np.array([s.mass_per_length for s in self.sections])[idx]
        cv = np.array([s.viscous_damping for s in self.sections])[idx]
        bf = np.array([s.buoyancy_factor(self.mud_density) for s in self.sections])[idx]
        z = np.concatenate(([0.0], np.cumsum(h)))
        return Mesh(z=z, h=h, section_index=idx, ea=ea, m=m, cv=cv, q=m * G * bf)

    def to_dict(self) -> dict:
        """Plain-data description (TOML/JSON friendly)."""
        return {
            "name": self.name,
            "description": self.description,
            "modal_damping_ratio": self.modal_damping_ratio,
            "mud_density": self.mud_density,
            "max_element_length": self.max_element_length,
            "boundaries": {e: getattr(self, e).spec() for e in ("top", "bottom", "on_bottom", "off_bottom")},
            "section": [{k: v for k, v in dataclasses.asdict(s).items() if v is not None}
                        for s in self.sections],
        }


def _theta_max(rel_tol: float, mass: str) -> float:
    _check_mass(mass)
    if mass == "mixed":
        return (480.0 * rel_tol) ** 0.25
    return math.sqrt(24.0 * rel_tol)


def dispersion_error(kh: "float | np.ndarray", mass: str = DEFAULT_MASS) -> "float | np.ndarray":
    """Exact relative frequency error ``f_h/f - 1`` of an infinite uniform
    chain for a wave with ``kh`` radians per element.

    ``lumped``: ``2 sin(kh/2)/kh - 1``; ``consistent``:
    ``sqrt(6(1-cos kh)/(2+cos kh))/kh - 1``; ``mixed``:
    ``sqrt(12(1-cos kh)/(5+cos kh))/kh - 1``.
    """
    _check_mass(mass)
    x = np.asarray(kh, dtype=float)
    if mass == "lumped":
        r = 2.0 * np.sin(x / 2.0) / x
    elif mass == "consistent":
        r = np.sqrt(6.0 * (1.0 - np.cos(x)) / (2.0 + np.cos(x))) / x
    else:
        r = np.sqrt(12.0 * (1.0 - np.cos(x)) / (5.0 + np.cos(x))) / x
    return r - 1.0


def _check_mass(mass: str) -> None:
    if mass not in MASS_SCHEMES:
        raise ValueError(f"mass = {mass!r}: allowed values {', '.join(MASS_SCHEMES)}")


# --------------------------------------------------------------------------
# TOML loading
# --------------------------------------------------------------------------
_TOP_KEYS = {"name", "description", "modal_damping_ratio", "mud_density", "max_element_length",
             "section", "boundaries"}
_SECTION_REQUIRED = ("name", "length", "od", "id")
_SECTION_OPTIONAL = ("youngs_modulus", "density", "linear_mass", "elements", "max_element_length",
                     "viscous_damping")
_BOUNDARY_KEYS = ("top", "bottom", "on_bottom", "off_bottom")


def string_from_dict(data: Mapping[str, Any], *, source: str = "<dict>") -> DrillString:
    """Build a :class:`DrillString` from the TOML data model.

    Raises
    ------
    DrillStringError
        Naming ``source``, the section (number and name), key, value and the
        allowed range.
    """
    if not isinstance(data, Mapping):
        raise DrillStringError(source, None, data, "top level must be a table")
    for key in data:
        if key not in _TOP_KEYS:
            raise DrillStringError(source, key, data[key],
                                   f"unknown top-level key; allowed keys {', '.join(sorted(_TOP_KEYS))}")
    raw_secs = data.get("section")
    if not isinstance(raw_secs, list) or not raw_secs:
        raise DrillStringError(source, "section", raw_secs, "at least one [[section]] table is required")
    sections = []
    for i, raw in enumerate(raw_secs, start=1):
        label = raw.get("name", "?") if isinstance(raw, Mapping) else "?"
        where = f"{source}: section #{i} '{label}'"
        if not isinstance(raw, Mapping):
            raise DrillStringError(where, None, raw, "each [[section]] must be a table")
        for key in raw:
            if key not in _SECTION_REQUIRED + _SECTION_OPTIONAL:
                raise DrillStringError(where, key, raw[key], "unknown key; allowed keys "
                                       + ", ".join(_SECTION_REQUIRED + _SECTION_OPTIONAL))
        for key in _SECTION_REQUIRED:
            if key not in raw:
                raise DrillStringError(where, key, None, "missing required key")
        try:
            sections.append(Section(**dict(raw)))
        except DrillStringError as err:
            raise DrillStringError(where, err.key, err.value, err.allowed) from None
    kw: dict[str, Any] = {k: data[k] for k in ("name", "description", "modal_damping_ratio",
                                               "mud_density", "max_element_length")
                          if k in data}
    kw.setdefault("name", Path(source).stem if source.endswith(".toml") else "drillstring")
    bnd = data.get("boundaries", {})
    if not isinstance(bnd, Mapping):
        raise DrillStringError(source, "boundaries", bnd, "must be a table")
    for key, val in bnd.items():
        if key not in _BOUNDARY_KEYS:
            raise DrillStringError(f"{source}: [boundaries]", key, val,
                                   "unknown key; allowed keys " + ", ".join(_BOUNDARY_KEYS))
        kw[key] = parse_boundary(val, where=f"{source}: [boundaries] {key}")
    try:
        return DrillString(tuple(sections), **kw)
    except DrillStringError as err:
        raise err.with_prefix(source) from None


def loads_string(text: str, *, source: str = "<string>") -> DrillString:
    """Parse TOML text (see :func:`string_from_dict`)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise DrillStringError(source, None, None, f"TOML syntax error: {err}") from None
    return string_from_dict(data, source=source)


def example_names() -> list[str]:
    """Names of the built-in example strings (``coupling/data/*.toml``)."""
    return sorted(p.stem for p in _DATA_DIR.glob("*.toml"))


def example_path(name: str) -> Path:
    """Path of a built-in example, e.g. ``field-2200m`` or ``lab``."""
    p = _DATA_DIR / f"{name}.toml"
    if not p.is_file():
        raise DrillStringError("example", "name", name, f"allowed values {', '.join(example_names())}")
    return p


def load_string(path_or_name: "str | Path") -> DrillString:
    """Load a string from a TOML file path or a built-in example name."""
    p = Path(path_or_name)
    if not p.is_file():
        if isinstance(path_or_name, str) and p.suffix == "" and path_or_name in example_names():
            p = example_path(path_or_name)
        else:
            raise DrillStringError(str(path_or_name), None, None,
                                   "no such file and not a built-in example; examples: "
                                   + ", ".join(example_names()))
    return loads_string(p.read_text(encoding="utf-8"), source=p.name)




def resolve_ends(string: DrillString, top: "Boundary | str | None" = None,
                 bottom: "Boundary | str | None" = None) -> tuple[Boundary, Boundary]:
    """``(top, bottom)`` as used by every computation: defaults from the
    string, the bit mass applied to the bottom (:meth:`DrillString.resolve_bottom`)."""
    t = _check_end(parse_boundary(string.top if top is None else top, where="top"), "top")
    return t, string.resolve_bottom(bottom)
