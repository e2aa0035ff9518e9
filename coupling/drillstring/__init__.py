"""Axial model of a vertical drillstring.

One concept per module:

* :mod:`.validation` -- defaults, the input error and the number checks;
* :mod:`.section`, :mod:`.boundary`, :mod:`.mesh` -- a section, the end conditions, the mesh sizes;
* :mod:`.drill_string` -- the string: sections top to bottom and its ends;
* :mod:`.loading` -- the TOML schema, the shipped examples;
* :mod:`.assembly` -- tridiagonal stiffness, mass and damping;
* :mod:`.eigen` -- selected eigenpairs of a tridiagonal pencil (Sturm bisection);
* :mod:`.modes` -- discrete modes (impedance-corrected, accuracy target) and
  exact modes (transfer matrix);
* :mod:`.damping` -- the damping model of the frequency response (hysteretic
  loss factor, viscous per unit length) and the bit receptance;
* :mod:`.statics` -- the hanging string with a weight on bit;
* :mod:`.state_space` -- the linear model the co-simulation master steps.

Displacements are positive **downward**; depth ``z`` is 0 at the top node.

Names are imported on first use (PEP 562): ``from hammerbit.drillstring import
DEFAULT_RTOL`` loads :mod:`.validation` only, not the numba kernels of
:mod:`.eigen`, so a command that does not touch the string does not pay for it.
"""
from __future__ import annotations

import importlib
import sys
import types

#: the submodule that defines each public name
_SOURCES = {name: module for module, names in {
    "assembly": ("Assembly", "assemble"),
    "damping": (
        "DampingModel", "bit_dynamic_stiffness", "bit_receptance", "exact_dynamic_stiffness",
        "exact_receptance", "reference_impedance",
    ),
    "validation": ("DEFAULT_MASS", "DEFAULT_MAX_ELEMENT_LENGTH", "DEFAULT_RTOL", "G", "MASS_SCHEMES",
                   "DrillStringError"),
    "section": ("Section",),
    "boundary": ("Boundary", "parse_boundary"),
    "mesh": ("Mesh", "dispersion_error"),
    "drill_string": ("DrillString", "resolve_ends"),
    "loading": ("example_names", "example_path", "load_string", "loads_string", "string_from_dict"),
    "modes": ("Modes", "corrected_eigenvalues", "exact_frequencies", "impedance_factor", "modes"),
    "state_space": ("StateSpace", "state_space"),
    "statics": ("StaticState", "static_compliance", "static_equilibrium"),
}.items() for name in names}

__all__ = [
    "G", "DEFAULT_MASS", "DEFAULT_RTOL", "DEFAULT_MAX_ELEMENT_LENGTH", "MASS_SCHEMES",
    "DrillStringError", "Section", "Boundary", "DrillString", "Mesh", "Assembly", "Modes",
    "StaticState", "StateSpace", "DampingModel", "parse_boundary", "resolve_ends", "load_string",
    "loads_string", "string_from_dict", "example_names", "example_path", "assemble", "modes",
    "exact_frequencies", "impedance_factor", "corrected_eigenvalues", "static_equilibrium",
    "static_compliance", "state_space", "dispersion_error", "bit_receptance", "bit_dynamic_stiffness",
    "exact_dynamic_stiffness", "exact_receptance", "reference_impedance",
]


class _Package(types.ModuleType):
    """This package's module type: a function keeps its name when its same-named submodule loads.

    The import system sets a package attribute to every submodule it loads;
    :func:`modes` and :func:`state_space` share their names with their
    submodules, and the package's name stays the function's, as it was when
    everything was imported at once.
    """

    def __setattr__(self, name, value):
        if isinstance(value, types.ModuleType) and _SOURCES.get(name) == name:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str):
    module = _SOURCES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_SOURCES))
