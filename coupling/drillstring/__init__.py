"""Axial model of a vertical drillstring.

One concept per module:

* :mod:`.description` -- sections, end conditions, the TOML schema, mesh sizes;
* :mod:`.assembly` -- tridiagonal stiffness, mass and damping;
* :mod:`.eigen` -- selected eigenpairs of a tridiagonal pencil (Sturm bisection);
* :mod:`.modes` -- discrete modes (impedance-corrected, accuracy target) and
  exact modes (transfer matrix);
* :mod:`.damping` -- the damping model of the frequency response (hysteretic
  loss factor, viscous per unit length) and the bit receptance;
* :mod:`.statics` -- the hanging string with a weight on bit;
* :mod:`.state_space` -- the linear model the co-simulation master steps.

Displacements are positive **downward**; depth ``z`` is 0 at the top node.
"""

from .assembly import Assembly, assemble
from .damping import (
    DampingModel,
    bit_dynamic_stiffness,
    bit_receptance,
    exact_dynamic_stiffness,
    exact_receptance,
    reference_impedance,
)
from .description import (
    DEFAULT_MASS,
    DEFAULT_MAX_ELEMENT_LENGTH,
    DEFAULT_RTOL,
    G,
    MASS_SCHEMES,
    Boundary,
    DrillString,
    DrillStringError,
    Mesh,
    Section,
    _check_end,
    _check_number,
    dispersion_error,
    example_names,
    example_path,
    load_string,
    loads_string,
    parse_boundary,
    resolve_ends,
    string_from_dict,
)
from .modes import Modes, _eigen, _has_rigid_mode, corrected_eigenvalues, exact_frequencies, impedance_factor, modes
from .state_space import StateSpace, state_space
from .statics import StaticState, static_compliance, static_equilibrium

__all__ = [
    "G", "DEFAULT_MASS", "DEFAULT_RTOL", "DEFAULT_MAX_ELEMENT_LENGTH", "MASS_SCHEMES",
    "DrillStringError", "Section", "Boundary", "DrillString", "Mesh", "Assembly", "Modes",
    "StaticState", "StateSpace", "DampingModel", "parse_boundary", "resolve_ends", "load_string",
    "loads_string", "string_from_dict", "example_names", "example_path", "assemble", "modes",
    "exact_frequencies", "impedance_factor", "corrected_eigenvalues", "static_equilibrium",
    "static_compliance", "state_space", "dispersion_error", "bit_receptance", "bit_dynamic_stiffness",
    "exact_dynamic_stiffness", "exact_receptance", "reference_impedance",
]
