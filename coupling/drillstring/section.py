"""A uniform section of the drillstring: length, diameters, material, element count."""
from __future__ import annotations

import math
from dataclasses import dataclass

from .validation import DEFAULT_DENSITY, DEFAULT_YOUNGS_MODULUS, DrillStringError, check_int, check_number

__all__ = ["Section"]


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
        check_number(w, "length", self.length, 0.0, 20000.0, lo_open=True, unit="m")
        check_number(w, "od", self.od, 0.0, 2.0, lo_open=True, unit="m")
        check_number(w, "id", self.id, 0.0, float(self.od), hi_open=True, unit="m (id < od)")
        check_number(w, "youngs_modulus", self.youngs_modulus, 1e9, 1e12, unit="Pa")
        check_number(w, "density", self.density, 500.0, 25000.0, unit="kg/m3")
        body = self.density * self.area
        if self.linear_mass is not None:
            check_number(w, "linear_mass", self.linear_mass, 0.5 * body, 20.0 * body,
                          unit=f"kg/m (0.5 to 20 x body mass {body:.4g} kg/m)")
        if self.elements is not None and self.max_element_length is not None:
            raise DrillStringError(w, "elements", self.elements,
                                   "give either 'elements' or 'max_element_length', not both")
        if self.elements is not None:
            object.__setattr__(self, "elements", check_int(w, "elements", self.elements, 1, 100000))
        if self.max_element_length is not None:
            check_number(w, "max_element_length", self.max_element_length, 0.0, 20000.0,
                          lo_open=True, unit="m")
        check_number(w, "viscous_damping", self.viscous_damping, 0.0, 1e9, unit="N s/m^2")

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
