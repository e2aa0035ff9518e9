"""Lumped axial model of a vertical drillstring.

The string is a chain of uniform sections listed top to bottom.  Each section
is cut into two-node bar elements; the axial displacement ``u`` of every node
is positive **downward** and measured from the unstrained configuration with
the top node at the hook.  Depth ``z`` is 0 at the top node and grows
downward, so the last node is the bit.

Matrices (all tridiagonal because the string is a chain)

* stiffness ``K``: ``EA/h * [[1, -1], [-1, 1]]`` per element;
* mass ``M`` per element, ``m' h`` times
  ``lumped = [[1/2, 0], [0, 1/2]]`` (half masses at the element ends),
  ``consistent = [[1/3, 1/6], [1/6, 1/3]]`` or
  ``mixed = (lumped + consistent)/2 = [[5/12, 1/12], [1/12, 5/12]]``.
  Lumped and consistent masses make frequency errors of order ``(kh)^2``
  (opposite signs), the mixed mass cancels them and is fourth order,
  ``f_h/f = 1 - (kh)^4/480 + ...`` with ``k = 2 pi f / c``.  **Mixed mass is the
  default** everywhere in this module.
* viscous damping ``C`` per unit length (``viscous_damping`` of a section,
  [N s/m^2]), distributed with the same pattern as the mass, plus the
  dashpots of the boundaries, plus, optionally, a modal damping ratio
  ``zeta`` for every mode (``C_modal = M Phi diag(2 zeta omega) Phi^T M``).

Gravity ``g = 9.81 m/s^2`` acts on the buoyed weight per length
``q = m' g (1 - rho_mud / rho)`` (buoyancy-factor method: effective tension,
pressure-area and ballooning terms neglected).  ``mud_density = 0`` (the
default) means no buoyancy.

Main entry points
-----------------
:func:`load_string` (file or built-in example name), :func:`modes`,
:func:`exact_frequencies` (continuous transfer-matrix solution),
:func:`static_equilibrium`, :func:`state_space`, :func:`assemble`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.linalg as sla

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = [
    "G",
    "DEFAULT_MASS",
    "MASS_SCHEMES",
    "DrillStringError",
    "Section",
    "Boundary",
    "DrillString",
    "Mesh",
    "Assembly",
    "Modes",
    "StaticState",
    "StateSpace",
    "parse_boundary",
    "load_string",
    "loads_string",
    "string_from_dict",
    "example_names",
    "example_path",
    "assemble",
    "modes",
    "exact_frequencies",
    "static_equilibrium",
    "static_compliance",
    "state_space",
    "dispersion_error",
]

#: Gravitational acceleration [m/s^2].
G = 9.81
#: Default Young's modulus of steel [Pa].
DEFAULT_YOUNGS_MODULUS = 2.07e11
#: Default density of steel [kg/m^3].
DEFAULT_DENSITY = 7850.0
#: Default maximum element length [m] when a section gives neither
#: ``elements`` nor ``max_element_length``.
DEFAULT_MAX_ELEMENT_LENGTH = 10.0
#: Minimum number of elements of a section meshed with the default length.
DEFAULT_MIN_ELEMENTS = 10
#: Mass-matrix schemes.
MASS_SCHEMES = ("lumped", "consistent", "mixed")
#: Default mass-matrix scheme (fourth-order accurate).
DEFAULT_MASS = "mixed"

_DATA_DIR = Path(__file__).resolve().parent / "data"


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
    """Damping ratio zeta [-] given to every mode (0 <= zeta < 1)."""
    mud_density: float = 0.0
    """Mud density [kg/m^3] for buoyancy; 0 = none (in air)."""
    max_element_length: float = DEFAULT_MAX_ELEMENT_LENGTH
    """Default maximum element length [m] for sections without a mesh spec."""
    min_elements: int = DEFAULT_MIN_ELEMENTS
    """Minimum elements of a section meshed with the default length."""
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
        object.__setattr__(self, "min_elements", _check_int(w, "min_elements", self.min_elements, 1, 100000))
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

    def refined(self, f_max: float, rel_tol: float = 1e-3, mass: str = DEFAULT_MASS) -> "DrillString":
        """Copy meshed finely enough that the dispersion error at ``f_max`` [Hz]
        is below ``rel_tol`` for the given mass scheme (never coarser).

        Uses ``|df/f| = (kh)^2/24`` (lumped, consistent) and ``(kh)^4/480``
        (mixed) with ``k = 2 pi f_max / c`` of each section.
        """
        theta = _theta_max(rel_tol, mass)
        counts = []
        for s, n in zip(self.sections, self.elements_per_section):
            h_max = theta * s.wave_speed / (2.0 * math.pi * f_max)
            counts.append(max(n, int(math.ceil(s.length / h_max))))
        return self.with_elements(counts)

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
        """Element count of each section (explicit, per-section max length, or
        the string default ``max_element_length`` with ``min_elements``)."""
        out = []
        for s in self.sections:
            if s.elements is not None:
                out.append(int(s.elements))
            elif s.max_element_length is not None:
                out.append(max(1, int(math.ceil(s.length / s.max_element_length - 1e-12))))
            else:
                out.append(max(self.min_elements,
                               int(math.ceil(s.length / self.max_element_length - 1e-12))))
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
            "min_elements": self.min_elements,
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
             "min_elements", "section", "boundaries"}
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
                                               "mud_density", "max_element_length", "min_elements")
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


# --------------------------------------------------------------------------
# assembly
# --------------------------------------------------------------------------
def _element_pattern(mass: str) -> tuple[float, float]:
    """(diagonal, off-diagonal) factors of the element mass ``m' h``."""
    _check_mass(mass)
    return {"lumped": (0.5, 0.0), "consistent": (1.0 / 3.0, 1.0 / 6.0),
            "mixed": (5.0 / 12.0, 1.0 / 12.0)}[mass]


def _chain(diag_el: np.ndarray) -> np.ndarray:
    """Node diagonal from per-element end contributions (n_el,) -> (n_el+1,)."""
    out = np.zeros(diag_el.size + 1)
    out[:-1] += diag_el
    out[1:] += diag_el
    return out


@dataclass(frozen=True)
class Assembly:
    """Tridiagonal matrices of a string with its boundaries.

    Arrays named ``*_full`` run over all nodes; the retained degrees of
    freedom (DOFs) are nodes ``start .. stop-1`` (fixed ends removed).  The
    reduced tridiagonals ``(diagonal, off-diagonal)`` are returned by
    :meth:`tridiagonal`; dense matrices by :attr:`K`, :attr:`M`, :attr:`C`.
    Boundary springs, dashpots and masses are included at non-fixed ends.
    """

    string: DrillString
    top: Boundary
    bottom: Boundary
    mass: str
    mesh: Mesh
    kd_full: np.ndarray
    """Stiffness diagonal (n_nodes,) [N/m]."""
    ke_full: np.ndarray
    """Stiffness off-diagonal (n_nodes-1,) [N/m]."""
    md_full: np.ndarray
    """Mass diagonal (n_nodes,) [kg]."""
    me_full: np.ndarray
    """Mass off-diagonal (n_nodes-1,) [kg]."""
    cd_full: np.ndarray
    """Viscous damping diagonal (n_nodes,) [N s/m]."""
    ce_full: np.ndarray
    """Viscous damping off-diagonal (n_nodes-1,) [N s/m]."""
    start: int
    stop: int

    @property
    def n_nodes(self) -> int:
        return self.mesh.n_nodes

    @property
    def nodes(self) -> np.ndarray:
        """Node index of each DOF (n_dof,)."""
        return np.arange(self.start, self.stop)

    @property
    def n_dof(self) -> int:
        return self.stop - self.start

    @property
    def bottom_dof(self) -> int | None:
        """DOF index of the bit node (None when the bottom is fixed)."""
        return None if self.bottom.is_fixed else self.n_dof - 1

    @property
    def modal_damping_ratio(self) -> float:
        return self.string.modal_damping_ratio

    def tridiagonal(self, which: str) -> tuple[np.ndarray, np.ndarray]:
        """Reduced ``(diagonal (n_dof,), off-diagonal (n_dof-1,))`` of
        ``which`` in ``{"K", "M", "C"}`` (C = viscous + boundary dashpots)."""
        d, e = {"K": (self.kd_full, self.ke_full), "M": (self.md_full, self.me_full),
                "C": (self.cd_full, self.ce_full)}[which]
        return d[self.start:self.stop].copy(), e[self.start:self.stop - 1].copy()

    def dense(self, which: str) -> np.ndarray:
        """Dense reduced matrix (n_dof, n_dof)."""
        d, e = self.tridiagonal(which)
        return np.diag(d) + np.diag(e, 1) + np.diag(e, -1)

    def sparse(self, which: str):
        """``scipy.sparse`` CSC form of the reduced matrix."""
        import scipy.sparse as sp
        d, e = self.tridiagonal(which)
        return sp.diags([e, d, e], [-1, 0, 1], format="csc")

    @property
    def K(self) -> np.ndarray:
        """Stiffness (n_dof, n_dof) [N/m]."""
        return self.dense("K")

    @property
    def M(self) -> np.ndarray:
        """Mass (n_dof, n_dof) [kg]."""
        return self.dense("M")

    @property
    def C_viscous(self) -> np.ndarray:
        """Viscous + boundary-dashpot damping (n_dof, n_dof) [N s/m]."""
        return self.dense("C")

    @property
    def has_viscous(self) -> bool:
        d, e = self.tridiagonal("C")
        return bool(np.any(d != 0.0) or np.any(e != 0.0))

    def modal_damping_matrix(self) -> np.ndarray:
        """``M Phi diag(2 zeta omega) Phi^T M`` over all modes (n_dof, n_dof) [N s/m]."""
        zeta = self.modal_damping_ratio
        if zeta == 0.0:
            return np.zeros((self.n_dof, self.n_dof))
        lam, phi = _eigen(self, None, None, all_modes=True)
        mphi = self.M @ phi
        return (mphi * (2.0 * zeta * np.sqrt(lam))) @ mphi.T

    @property
    def C(self) -> np.ndarray:
        """Total damping: viscous + dashpots + modal (n_dof, n_dof) [N s/m]."""
        return self.C_viscous + self.modal_damping_matrix()

    def gravity_load(self) -> np.ndarray:
        """Nodal buoyed weight (n_nodes,) [N] incl. boundary masses
        (bit mass buoyed with the bottom section; top mass in air)."""
        ms = self.mesh
        f = _chain(ms.q * ms.h / 2.0)
        if not self.top.is_fixed:
            f[0] += self.top.mass * G
        if not self.bottom.is_fixed:
            bf = self.string.sections[-1].buoyancy_factor(self.string.mud_density)
            f[-1] += self.bottom.mass * G * bf
        return f


def assemble(string: DrillString, top: "Boundary | str | None" = None,
             bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS) -> Assembly:
    """Assemble K, M and viscous C of ``string`` with the given ends.

    Parameters
    ----------
    string : DrillString
    top, bottom : Boundary or str, optional
        End conditions (default ``string.top`` / ``string.bottom``).  A
        ``hammer`` bottom is free here.
    mass : {"mixed", "lumped", "consistent"}
        Mass-matrix scheme.

    Returns
    -------
    Assembly
    """
    top = _check_end(parse_boundary(string.top if top is None else top, where="top"), "top")
    bottom = _check_end(parse_boundary(string.bottom if bottom is None else bottom, where="bottom"), "bottom")
    ms = string.mesh()
    a, b = _element_pattern(mass)
    kel = ms.ea / ms.h
    mel = ms.m * ms.h
    cel = ms.cv * ms.h
    kd, ke = _chain(kel), -kel
    md, me = _chain(a * mel), b * mel
    cd, ce = _chain(a * cel), b * cel
    for bnd, i in ((top, 0), (bottom, -1)):
        if not bnd.is_fixed:
            kd[i] += bnd.ground_stiffness
            cd[i] += bnd.ground_damping
            md[i] += bnd.mass
    start = 1 if top.is_fixed else 0
    stop = ms.n_nodes - 1 if bottom.is_fixed else ms.n_nodes
    if stop - start < 1:
        raise DrillStringError(f"string '{string.name}'", "elements", string.n_elements,
                               "fixed-fixed needs at least 2 elements")
    return Assembly(string, top, bottom, mass, ms, kd, ke, md, me, cd, ce, start, stop)


# --------------------------------------------------------------------------
# eigenvalues
# --------------------------------------------------------------------------
_SPARSE_MIN_DOF = 100


def _eigen(asm: Assembly, f_max: float | None, count: int | None, *,
           all_modes: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Lowest eigenpairs ``(omega^2 (n,), Phi (n_dof, n))`` with ``Phi^T M Phi = I``.

    Only eigenvalues ``omega <= 2 pi f_max`` and/or the ``count`` lowest are
    computed (both given: both limits apply).  Lumped mass: mass-scaled
    symmetric tridiagonal, ``eigh_tridiagonal`` with ``select``.  Consistent
    or mixed mass: shift-invert Lanczos (``eigsh``, sparse LU of the
    tridiagonal pencil, O(n k)) when few modes of a long mesh are wanted,
    otherwise dense ``eigh(K, M, subset_by_...)``.
    """
    kd, ke = asm.tridiagonal("K")
    md, me = asm.tridiagonal("M")
    n = kd.size
    if not all_modes and f_max is None and count is None:
        count = 10
    hi = None if f_max is None else (2.0 * math.pi * f_max) ** 2
    if count is not None:
        count = min(int(count), n)
    scale = float(np.max(kd / np.maximum(md, 1e-300)))
    lo = -1e-8 * scale  # below a (numerically) zero rigid-body eigenvalue
    if all_modes:
        sel: dict[str, Any] = {}
    elif hi is not None:
        sel = {"subset_by_value": (lo, hi)}
    else:
        sel = {"subset_by_index": (0, count - 1)}
    if asm.mass == "lumped":
        s = 1.0 / np.sqrt(md)
        d, e = kd * s * s, ke * s[:-1] * s[1:]
        if "subset_by_value" in sel:
            lam, psi = sla.eigh_tridiagonal(d, e, select="v", select_range=sel["subset_by_value"])
        elif "subset_by_index" in sel:
            lam, psi = sla.eigh_tridiagonal(d, e, select="i", select_range=sel["subset_by_index"])
        else:
            lam, psi = sla.eigh_tridiagonal(d, e)
        phi = psi * s[:, None]
    else:
        k_est = None
        if not all_modes:
            k_est = count if hi is None else \
                int(2.0 * f_max * sum(x.length / x.wave_speed for x in asm.string.sections)) + 4
            if count is not None:
                k_est = min(k_est, count)
        if k_est is not None and n > _SPARSE_MIN_DOF and k_est < n // 4:
            lam, phi = _eigen_sparse(asm, hi, count, k_est)
        else:
            lam, phi = sla.eigh(asm.K, asm.M, **sel)
    if count is not None and lam.size > count:
        lam, phi = lam[:count], phi[:, :count]
    lam = np.where(lam < 0.0, 0.0, lam)
    if lam.size and _has_rigid_mode(asm.top, asm.bottom):
        lam[0] = 0.0  # exact zero instead of round-off (~eps * max eigenvalue)
    # deterministic sign: bit (last DOF) displacement >= 0, else largest entry > 0
    ref = phi[-1].copy()
    weak = np.abs(ref) < 1e-9 * np.max(np.abs(phi), axis=0, initial=0.0)
    ref[weak] = phi[np.argmax(np.abs(phi), axis=0), np.arange(phi.shape[1])][weak]
    phi = phi * np.where(ref < 0.0, -1.0, 1.0)
    return lam, phi


def _has_rigid_mode(top: Boundary, bottom: Boundary) -> bool:
    """Both ends unrestrained (no fixed end, no ground spring)."""
    return (not top.is_fixed and top.ground_stiffness == 0.0
            and not bottom.is_fixed and bottom.ground_stiffness == 0.0)


def _eigen_sparse(asm: Assembly, hi: float | None, count: int | None, k0: int):
    """Shift-invert Lanczos about ``sigma = -1 rad^2/s^2`` (``K + M`` is
    positive definite even with a rigid-body mode); ``k`` grows until the
    largest eigenvalue found passes ``hi``.  Falls back to dense when more
    than a quarter of the spectrum is needed."""
    import scipy.sparse.linalg as spla
    K, M = asm.sparse("K"), asm.sparse("M")
    n = asm.n_dof
    k = max(1, k0)
    while True:
        if k >= n // 4:
            sel = {"subset_by_value": (-1.0, hi)} if hi is not None else {"subset_by_index": (0, count - 1)}
            return sla.eigh(asm.K, asm.M, **sel)
        lam, phi = spla.eigsh(K, k=k, M=M, sigma=-1.0, which="LM")
        order = np.argsort(lam)
        lam, phi = lam[order], phi[:, order]
        if hi is None or lam[-1] > hi:
            break
        k *= 2
    if hi is not None:
        keep = lam <= hi
        lam, phi = lam[keep], phi[:, keep]
    return lam, phi


@dataclass(frozen=True)
class Modes:
    """Undamped axial modes of a string with given ends."""

    frequencies_hz: np.ndarray
    """Natural frequencies (n,) [Hz], ascending; rigid-body modes are 0."""
    shapes: np.ndarray
    """Mass-normalised shapes on all nodes (n_nodes, n) [1/sqrt(kg)];
    zero at fixed ends; sign chosen so the bit displacement is >= 0."""
    z: np.ndarray
    """Node depths (n_nodes,) [m]."""
    top: Boundary
    bottom: Boundary
    mass: str
    n_elements: int

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies (n,) [rad/s]."""
        return 2.0 * math.pi * self.frequencies_hz

    def __len__(self) -> int:
        return int(self.frequencies_hz.size)

    def to_dict(self, shapes: bool = False) -> dict:
        d = {"frequencies_hz": [float(f) for f in self.frequencies_hz],
             "top": self.top.spec(), "bottom": self.bottom.spec(), "mass": self.mass,
             "elements": self.n_elements}
        if shapes:
            d["depth_m"] = self.z.tolist()
            d["shapes"] = self.shapes.T.tolist()
        return d


def modes(string: DrillString, top: "Boundary | str | None" = None,
          bottom: "Boundary | str | None" = None, f_max: float | None = None,
          count: int | None = None, *, mass: str = DEFAULT_MASS) -> Modes:
    """Lowest axial natural frequencies and mode shapes.

    Only the requested part of the spectrum is computed (``eigh_tridiagonal``
    after mass scaling for lumped mass, ``eigh(subset_by_...)`` for
    consistent/mixed, shift-invert Lanczos when few modes of a long mesh are wanted).

    Parameters
    ----------
    string : DrillString
    top, bottom : Boundary or str, optional
        Ends (default ``string.top``/``string.bottom``); ``hammer`` = free.
    f_max : float, optional
        Keep modes with frequency <= f_max [Hz].
    count : int, optional
        Keep at most the ``count`` lowest modes (default 10 if ``f_max`` is
        not given either).
    mass : {"mixed", "lumped", "consistent"}

    Returns
    -------
    Modes
    """
    asm = assemble(string, top, bottom, mass=mass)
    lam, phi = _eigen(asm, f_max, count)
    shapes = np.zeros((asm.n_nodes, lam.size))
    shapes[asm.start:asm.stop] = phi
    return Modes(np.sqrt(lam) / (2.0 * math.pi), shapes, asm.mesh.z, asm.top, asm.bottom, mass,
                 string.n_elements)


# --------------------------------------------------------------------------
# exact (continuous) solution by transfer matrices
# --------------------------------------------------------------------------
def _characteristic(string: DrillString, top: Boundary, bottom: Boundary,
                    omega: np.ndarray) -> np.ndarray:
    """Frequency function g(omega) whose roots are the exact natural frequencies.

    State ``s = [u, N]`` (displacement, tension ``N = EA u'``) is carried
    down each uniform section by ``[[cos kl, sin kl/(Z w)], [-Z w sin kl, cos kl]]``
    (``k = w/c``, ``Z w = EA k``).  Top: fixed ``s0=[0, 1]``, otherwise
    ``s0 = [1, k_t - m_t w^2]``.  Bottom: fixed ``r=[1, 0]``, otherwise
    ``r = [k_b - m_b w^2, 1]``; ``g = r . T(w) s0``.  Dashpots are ignored.
    """
    w = np.asarray(omega, dtype=float)
    if top.is_fixed:
        u, n = np.zeros_like(w), np.ones_like(w)
    else:
        u, n = np.ones_like(w), top.ground_stiffness - top.mass * w ** 2
    for s in string.sections:
        a = w * s.length / s.wave_speed
        zw = s.impedance * w
        ca, sa = np.cos(a), np.sin(a)
        with np.errstate(divide="ignore", invalid="ignore"):
            sz = np.where(zw > 0, sa / np.where(zw > 0, zw, 1.0), s.length / s.axial_stiffness)
        u, n = ca * u + sz * n, -zw * sa * u + ca * n
    if bottom.is_fixed:
        return u
    return (bottom.ground_stiffness - bottom.mass * w ** 2) * u + n


def exact_frequencies(string: DrillString, top: "Boundary | str | None" = None,
                      bottom: "Boundary | str | None" = None, count: int = 4,
                      *, f_max: float | None = None, points_per_mode: int = 256) -> np.ndarray:
    """Natural frequencies [Hz] of the continuous piecewise-uniform bar.

    Roots of :func:`_characteristic` are bracketed on a grid of
    ``points_per_mode`` points per mean mode spacing ``1/(2 sum l/c)`` and
    polished with ``brentq``.  A rigid-body mode (both ends free, no
    springs) is returned as 0.  Boundary dashpots are ignored.

    Returns
    -------
    ndarray (count,) or all roots <= f_max.
    """
    from scipy.optimize import brentq
    top = _check_end(parse_boundary(string.top if top is None else top), "top")
    bottom = _check_end(parse_boundary(string.bottom if bottom is None else bottom), "bottom")
    rigid = _has_rigid_mode(top, bottom)
    roots: list[float] = [0.0] if rigid else []
    spacing = 1.0 / (2.0 * sum(s.length / s.wave_speed for s in string.sections))  # Hz
    step = 2.0 * math.pi * spacing / points_per_mode
    w0 = 1e-9 * step
    target = math.inf if f_max is None else 2.0 * math.pi * f_max
    need = math.inf if f_max is not None else count

    def g(w: float) -> float:
        return float(_characteristic(string, top, bottom, np.array([w]))[0])

    while len(roots) < need:
        grid = w0 + step * np.arange(points_per_mode * 8 + 1)
        val = _characteristic(string, top, bottom, grid)
        for i in np.nonzero(np.sign(val[:-1]) * np.sign(val[1:]) < 0)[0]:
            roots.append(brentq(g, grid[i], grid[i + 1], xtol=1e-13 * grid[i + 1], rtol=1e-15,
                                maxiter=200))
        if grid[-1] > target:
            break
        w0 = grid[-1]
    out = np.array(roots) / (2.0 * math.pi)
    if f_max is not None:
        return out[out <= f_max]
    return out[:count]


# --------------------------------------------------------------------------
# statics
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class StaticState:
    """Static equilibrium of the string hanging from the hook."""

    z: np.ndarray
    """Node depths (n_nodes,) [m]."""
    displacement: np.ndarray
    """Downward node displacement from the unstrained string (n_nodes,) [m]."""
    tension_nodes: np.ndarray
    """Effective tension at the nodes (n_nodes,) [N] (exact; < 0 = compression)."""
    tension_elements: np.ndarray
    """Effective tension ``EA du/dz`` per element (n_el,) [N] (= exact value at
    the element mid-point)."""
    hook_load: float
    """Force at the hook = buoyed weight - weight on bit [N]."""
    wob: float
    """Weight on bit [N] (force of the rock on the bit, upward)."""
    buoyed_weight: float
    """Buoyed weight of the string incl. bit-end mass [N]."""
    neutral_point_depth: float | None
    """Depth of zero effective tension [m] (None when the whole string is in tension)."""

    @property
    def bit_displacement(self) -> float:
        """Static displacement of the bit node [m]."""
        return float(self.displacement[-1])


def static_equilibrium(string: DrillString, wob: float | None = None, hook_load: float | None = None,
                       *, top: "Boundary | str | None" = None, mud_density: float | None = None,
                       bottom_mass: float = 0.0) -> StaticState:
    """Static stretch of the string hung from the hook with a weight on bit.

    The top is the hook (default ``string.top``, normally fixed; a spring top
    stretches by ``hook_load/k``).  The bit carries the upward force ``wob``.
    Give ``wob`` *or* ``hook_load`` (``hook_load = W_buoyed - wob``); neither
    means off bottom (``wob = 0``).  Nodal displacements are exact for
    piecewise-uniform sections (linear elements, consistent nodal loads).

    Parameters
    ----------
    string : DrillString
    wob : float, optional
        Weight on bit [N], 0 <= wob <= buoyed weight.
    hook_load : float, optional
        Hook load [N].
    top : Boundary or str, optional
        Hook boundary (``fixed`` or ``spring``).
    mud_density : float, optional
        Override ``string.mud_density`` [kg/m^3].
    bottom_mass : float
        Lumped mass at the bit [kg] (weight included, buoyed).

    Returns
    -------
    StaticState
    """
    if mud_density is not None:
        string = string.replace(mud_density=mud_density)
    topb = _check_end(parse_boundary(string.top if top is None else top), "top")
    if topb.kind == "free" or (topb.kind == "spring" and topb.stiffness == 0.0):
        raise ValueError("static equilibrium needs a hook: top must be 'fixed' or 'spring'")
    asm = assemble(string, topb, Boundary.free(bottom_mass), mass="lumped")
    f = asm.gravity_load()
    weight = float(f.sum() - (topb.mass * G if not topb.is_fixed else 0.0))
    if wob is not None and hook_load is not None:
        raise ValueError("give wob or hook_load, not both")
    if hook_load is not None:
        wob = weight - float(hook_load)
    wob = 0.0 if wob is None else float(wob)
    if not -1e-9 * weight <= wob <= weight * (1 + 1e-12):
        raise ValueError(f"wob = {wob:.6g} N: allowed range 0 <= wob <= buoyed weight {weight:.6g} N")
    f = f.copy()
    f[-1] -= wob
    kd, ke = asm.tridiagonal("K")
    ab = np.zeros((2, kd.size))
    ab[0, 1:], ab[1] = ke, kd
    u = np.zeros(asm.n_nodes)
    u[asm.start:asm.stop] = sla.solveh_banded(ab, f[asm.start:asm.stop])
    ms = asm.mesh
    t_el = ms.ea * np.diff(u) / ms.h
    below = np.concatenate((np.cumsum((ms.q * ms.h)[::-1])[::-1], [0.0]))
    bf_bit = string.sections[-1].buoyancy_factor(string.mud_density)
    t_nodes = below + bottom_mass * G * bf_bit - wob
    neutral = None
    if t_nodes[-1] < 0.0:
        i = int(np.argmax(t_nodes <= 0.0))
        if i == 0:
            neutral = 0.0
        else:
            t0, t1 = t_nodes[i - 1], t_nodes[i]
            neutral = float(ms.z[i - 1] + (ms.z[i] - ms.z[i - 1]) * t0 / (t0 - t1))
    return StaticState(ms.z, u, t_nodes, t_el, weight - wob, wob, weight, neutral)


def static_compliance(string: DrillString, top: "Boundary | str | None" = None,
                      bottom: "Boundary | str | None" = None) -> float:
    """Static driving-point compliance at the bit [m/N].

    The hook spring (if any) and the elements act in series, the bottom
    spring in parallel: ``1 / (1/(1/k_t + sum h/EA) + k_b)``.  Returns inf
    with a rigid-body mode and 0 with a fixed bit.
    """
    topb = _check_end(parse_boundary(string.top if top is None else top), "top")
    botb = _check_end(parse_boundary(string.bottom if bottom is None else bottom), "bottom")
    if botb.is_fixed:
        return 0.0
    ms = string.mesh()
    if topb.is_fixed:
        flex = float(np.sum(ms.h / ms.ea))
    elif topb.ground_stiffness > 0.0:
        flex = float(np.sum(ms.h / ms.ea)) + 1.0 / topb.ground_stiffness
    else:
        flex = math.inf
    stiff = (0.0 if math.isinf(flex) else 1.0 / flex) + botb.ground_stiffness
    return math.inf if stiff == 0.0 else 1.0 / stiff


# --------------------------------------------------------------------------
# state-space export for the co-simulation
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class StateSpace:
    """Linear first-order model of the string for co-simulation.

    ``dx/dt = A x + B u + d``,  ``y = C x + D u + y_offset`` with the scalar input
    ``u`` = axial force applied to the bottom (bit) node [N], **positive
    downward**; the rock or hammer pushing up on the string is negative.

    Nodal form: ``x = [u_1..u_n, v_1..v_n]`` (displacements [m] and
    velocities [m/s] of the DOFs, downward, from the unstrained string).
    Modal form (``f_max`` given): ``x = [q, dq/dt]`` are *deviations from the
    static equilibrium* of the full model, DOF displacements
    ``static_displacement[nodes] + basis @ q`` (``x0 = 0``; ``y_offset``
    holds the equilibrium outputs), so the truncation is exact at rest.
    Outputs ``y`` (see ``output_names``): bit displacement [m], bit velocity
    [m/s], effective tension in the top element [N], all absolute.

    ``x0`` is the static equilibrium with ``u = u0 = -wob`` (it satisfies
    ``A x0 + B u0 + d = 0``).  A bottom ``spring`` is unloaded at ``x0``
    (its preload is folded into ``d``), so the WOB always enters via ``u``.
    For ``bottom = hammer`` the interface force is
    ``u = k_i (x_h - y[0]) + c_i (v_h - y[1])`` with ``k_i, c_i`` from
    :attr:`interface`.
    """

    A: np.ndarray
    """State matrix (n_x, n_x)."""
    B: np.ndarray
    """Input matrix (n_x, 1) [per N]."""
    C: np.ndarray
    """Output matrix (3, n_x)."""
    D: np.ndarray
    """Feed-through (3, 1), zero."""
    d: np.ndarray
    """Constant term from gravity and bottom-spring preload (n_x,)."""
    x0: np.ndarray | None
    """Static equilibrium state (n_x,); None with a free top (no hook, no equilibrium)."""
    u0: float
    """Input at equilibrium, ``-wob`` [N]."""
    mass_matrix: np.ndarray
    """Second-order mass in the state coordinates (n_q, n_q) [kg] (identity if modal)."""
    stiffness_matrix: np.ndarray
    """Second-order stiffness (n_q, n_q) [N/m] (``diag(omega^2)`` if modal)."""
    damping_matrix: np.ndarray
    """Second-order damping (n_q, n_q) [N s/m] (``Phi^T C Phi`` if modal)."""
    load_vector: np.ndarray
    """Constant generalized force (n_q,) [N]: gravity + spring preload
    (nodal); ``basis^T b * wob`` (modal, balances ``u0``)."""
    input_vector: np.ndarray
    """Generalized force per unit input (n_q,) [-]."""
    basis: np.ndarray | None
    """Mode shapes on the DOFs (n_dof, n_modes) for the modal form, else None."""
    nodes: np.ndarray
    """Node index of each DOF (n_dof,)."""
    z: np.ndarray
    """Node depths (n_nodes,) [m]."""
    bottom_node: int
    """Node index of the bit (n_nodes - 1)."""
    bottom_dof: int
    """DOF index of the bit node."""
    top: Boundary
    bottom: Boundary
    wob: float
    """Weight on bit at equilibrium [N]."""
    hook_load: float
    """Hook load at equilibrium [N]."""
    static_displacement: np.ndarray
    """Equilibrium displacement of all nodes (n_nodes,) [m] (full model)."""
    residual_compliance: float
    """Static bit compliance missing from a modal truncation [m/N] (0 nodal)."""
    max_frequency_hz: float
    """Highest natural frequency represented [Hz] (step-size guide)."""
    y_offset: np.ndarray
    """Constant output offset (3,): zero for the nodal form; the equilibrium
    outputs for the modal form (whose states are deviations)."""
    output_names: tuple[str, ...] = ("bit_displacement", "bit_velocity", "top_element_tension")

    @property
    def interface(self) -> Boundary:
        """Bottom boundary; for ``hammer`` it carries the interface k [N/m], c [N s/m]."""
        return self.bottom

    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    def rhs(self, x: np.ndarray, u: float) -> np.ndarray:
        """``dx/dt`` (n_x,) for state ``x`` and bottom force ``u`` [N]."""
        return self.A @ x + self.B[:, 0] * u + self.d

    def output(self, x: np.ndarray, u: float = 0.0) -> np.ndarray:
        """Outputs (3,): bit displacement [m], bit velocity [m/s], top tension [N]."""
        return self.C @ x + self.D[:, 0] * u + self.y_offset


def state_space(string: DrillString, top: "Boundary | str | None" = None,
                bottom: "Boundary | str | None" = None, *, mass: str = DEFAULT_MASS,
                wob: float | None = None, hook_load: float | None = None,
                mud_density: float | None = None, f_max: float | None = None) -> StateSpace:
    """First-order linear model with a force input at the bit.

    Parameters
    ----------
    string : DrillString
    top : Boundary or str, optional
        Hook (default ``string.top``).
    bottom : Boundary or str, optional
        Default ``string.bottom``.  ``hammer:K:C`` for the co-simulation
        (bottom node free, interface data kept in
        :attr:`StateSpace.interface`), ``free`` or ``spring``.  ``fixed`` is
        refused (there would be no bit DOF to drive).
    mass : {"mixed", "lumped", "consistent"}
        Lumped mass gives a diagonal M and the lowest top frequency.
    wob, hook_load : float, optional
        Weight on bit or hook load [N] of the equilibrium (default wob = 0).
    mud_density : float, optional
        Override ``string.mud_density`` [kg/m^3].
    f_max : float, optional
        Modal truncation: keep the modes <= f_max [Hz].

    Returns
    -------
    StateSpace
    """
    if mud_density is not None:
        string = string.replace(mud_density=mud_density)
    asm = assemble(string, top, bottom, mass=mass)
    if asm.bottom.is_fixed:
        raise ValueError("state_space needs a moving bit: bottom must be hammer, free or spring")
    n = asm.n_dof
    b_dof = n - 1
    K, M = asm.K, asm.M
    Cv = asm.C_viscous
    lam_all = None
    if asm.modal_damping_ratio > 0.0:
        lam_all, phi_all = _eigen(asm, None, None, all_modes=True)
        mphi = M @ phi_all
        Cfull = Cv + (mphi * (2.0 * asm.modal_damping_ratio * np.sqrt(lam_all))) @ mphi.T
    else:
        Cfull = Cv
    fg_full = asm.gravity_load()
    fg = fg_full[asm.start:asm.stop].copy()
    bvec = np.zeros(n)
    bvec[b_dof] = 1.0
    # equilibrium: bottom spring unloaded, WOB through the input
    rigid = asm.top.kind == "free"
    weight = float(fg_full.sum() - (asm.top.mass * G if not asm.top.is_fixed else 0.0))
    if wob is not None and hook_load is not None:
        raise ValueError("give wob or hook_load, not both")
    wob_v = weight - float(hook_load) if hook_load is not None else float(wob or 0.0)
    if not -1e-9 * weight <= wob_v <= weight * (1 + 1e-12):
        raise ValueError(f"wob = {wob_v:.6g} N: allowed range 0 <= wob <= buoyed weight {weight:.6g} N")
    x_eq_full = np.zeros(asm.n_nodes)
    load = fg.copy()
    if not rigid:
        Kstat = K.copy()
        Kstat[b_dof, b_dof] -= asm.bottom.ground_stiffness
        x_eq = np.linalg.solve(Kstat, fg - wob_v * bvec)
        x_eq_full[asm.start:asm.stop] = x_eq
        load[b_dof] += asm.bottom.ground_stiffness * x_eq[b_dof]
    # top-element tension row on the DOFs
    trow = np.zeros(n)
    k0 = asm.mesh.ea[0] / asm.mesh.h[0]
    trow[1 - asm.start] += k0
    if asm.start == 0:
        trow[0] -= k0
    if f_max is None:
        L = sla.cho_factor(M)
        Minv_K = sla.cho_solve(L, K)
        Minv_C = sla.cho_solve(L, Cfull)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv_K, -Minv_C]])
        B = np.concatenate((np.zeros(n), sla.cho_solve(L, bvec)))[:, None]
        d = np.concatenate((np.zeros(n), sla.cho_solve(L, load)))
        C = np.zeros((3, 2 * n))
        C[0, b_dof] = 1.0
        C[1, n + b_dof] = 1.0
        C[2, :n] = trow
        x0 = None if rigid else np.concatenate((x_eq, np.zeros(n)))
        lam_top = lam_all[-1] if lam_all is not None else sla.eigh(K, M, eigvals_only=True,
                                                                     subset_by_index=(n - 1, n - 1))[0]
        return StateSpace(A, B, C, np.zeros((3, 1)), d, x0, -wob_v, M, K, Cfull, load, bvec, None,
                          asm.nodes, asm.mesh.z, asm.n_nodes - 1, b_dof, asm.top, asm.bottom, wob_v,
                          weight - wob_v, x_eq_full, 0.0, math.sqrt(lam_top) / (2 * math.pi), np.zeros(3))
    lam, phi = _eigen(asm, f_max, None)
    m = lam.size
    if m == 0:
        raise ValueError(f"no mode below f_max = {f_max} Hz")
    # modal coordinates measure the deviation from the full-model equilibrium:
    # x = x_eq + Phi q, so the truncated model is exact at rest.
    Cm = phi.T @ Cv @ phi + np.diag(2.0 * asm.modal_damping_ratio * np.sqrt(lam))
    A = np.block([[np.zeros((m, m)), np.eye(m)], [-np.diag(lam), -Cm]])
    gen_b = phi.T @ bvec
    gen_load = gen_b * wob_v
    B = np.concatenate((np.zeros(m), gen_b))[:, None]
    d = np.concatenate((np.zeros(m), gen_load))
    C = np.zeros((3, 2 * m))
    C[0, :m] = phi[b_dof]
    C[1, m:] = phi[b_dof]
    C[2, :m] = trow @ phi
    x0 = None if rigid else np.zeros(2 * m)
    y_off = np.zeros(3)
    if not rigid:
        y_off = np.array([x_eq[b_dof], 0.0, trow @ x_eq])
    has_rigid = rigid or bool(np.any(lam == 0.0))
    comp = static_compliance(string, asm.top, asm.bottom)
    resid = comp - float(np.sum(phi[b_dof] ** 2 / lam)) if not has_rigid else math.nan
    return StateSpace(A, B, C, np.zeros((3, 1)), d, x0, -wob_v, np.eye(m), np.diag(lam), Cm, gen_load,
                      gen_b, phi, asm.nodes, asm.mesh.z, asm.n_nodes - 1, b_dof, asm.top, asm.bottom,
                      wob_v, weight - wob_v, x_eq_full, resid, math.sqrt(lam[-1]) / (2 * math.pi), y_off)
