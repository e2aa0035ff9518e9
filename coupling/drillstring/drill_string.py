"""The drillstring: a chain of uniform sections listed top to bottom, with its ends.

Depth ``z`` is 0 at the top node and grows downward; displacements are
positive downward.

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
from typing import Any, Sequence

import numpy as np

from .validation import (DEFAULT_MASS, DEFAULT_MAX_ELEMENT_LENGTH, DEFAULT_RTOL, DrillStringError, G,
                         check_number)
from .section import Section
from .boundary import Boundary, check_end, parse_boundary
from .mesh import Mesh, theta_max

__all__ = ["DrillString", "resolve_ends"]


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
        check_number(w, "modal_damping_ratio", self.modal_damping_ratio, 0.0, 1.0, hi_open=True)
        check_number(w, "mud_density", self.mud_density, 0.0, 3000.0, unit="kg/m3")
        for s in secs:
            if self.mud_density >= s.density:
                raise DrillStringError(f"{w}, section '{s.name}'", "mud_density", self.mud_density,
                                       f"must be < section density {s.density:g} kg/m3")
        check_number(w, "max_element_length", self.max_element_length, 0.0, 20000.0, lo_open=True, unit="m")
        for end in ("top", "bottom", "on_bottom", "off_bottom"):
            b = parse_boundary(getattr(self, end), where=f"{w}, boundary {end}")
            object.__setattr__(self, end, check_end(b, "top" if end == "top" else "bottom"))

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
        tau = theta_max(rtol, mass) / (2.0 * math.pi * float(f_max))
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
        b = check_end(parse_boundary(self.bottom if bottom is None else bottom, where=where), "bottom")
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


def resolve_ends(string: DrillString, top: "Boundary | str | None" = None,
                 bottom: "Boundary | str | None" = None) -> tuple[Boundary, Boundary]:
    """``(top, bottom)`` as used by every computation: defaults from the
    string, the bit mass applied to the bottom (:meth:`DrillString.resolve_bottom`)."""
    t = check_end(parse_boundary(string.top if top is None else top, where="top"), "top")
    return t, string.resolve_bottom(bottom)
