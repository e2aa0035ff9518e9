"""The variables of the HammerBitRock FMU: names, units, ranges, start values, descriptions.

The table of the variables is in the one description (:mod:`.fmu_description`:
``HAMMER_VARIABLES``, by causality ``PARAMETERS``, ``BOOL_PARAMETERS``, ``INPUTS``, ``OUTPUTS``,
and ``UNITS``); this module adds what the library's parameters and the build's start values
give them.  Names are :class:`RigParameters` field names
wherever one exists; allowed ranges come from :data:`validation.RANGES`, the
inputs' from the static friction threshold (:func:`input_range`); the
``modelDescription.xml`` declares as ``min``/``max`` exactly what the slave
accepts with the other start values (:func:`accepted_bounds`); start values
are the lab preset (``RigParameters()``), overridden by the build's
:data:`build_info.START_VALUES`.
"""
from __future__ import annotations

import math
import struct

from .fmu_description import BOOL_PARAMETERS, HAMMER_VARIABLES, INPUTS, OUTPUTS, PARAMETERS, UNITS
from .params import RigParameters
from .validation import RANGES, Range

__all__ = ["MAX_PERIODS_PER_STEP", "UNITS", "HAMMER_VARIABLES", "PARAMETERS", "BOOL_PARAMETERS", "INPUTS", "OUTPUTS", "RIG_FIELDS",
           "FIXED_REALS", "range_key", "variable_range", "start_values", "nominal_values",
           "DEFAULT_TOLERANCE", "INPUT_GROUPS", "input_range", "accepted_bounds"]

_RIG = RigParameters()          # the lab rig at the paper's Fig. 9 operating point

#: parameters that are RigParameters fields (the rest: gap, initial positions, tolerance)
RIG_FIELDS = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
              "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
              "contact_damping", "amplitude", "frequency", "phase")
FIXED_REALS = tuple(v.name for v in PARAMETERS if v.variability == "fixed")

DEFAULT_TOLERANCE = 1e-8
_DEFAULT_GAP = 0.84 * _RIG.scales.length     # the paper's Fig. 12 gap r = 0.84 (impact off by default)

#: the nondimensional group of the library that bounds each input, in units of the static
#: friction threshold F0: the preload b = B/F0, the forcing amplitude a = A/F0 (both +-1000 F0)
INPUT_GROUPS = {"preload": "group.b", "harmonic_force": "group.a"}

#: forcing periods one fmi2DoStep of HammerBitRock may span: the solver's limits count per period
#: (steps, events), so the work of a step is bounded in advance by this times those limits; a
#: longer step is refused at once, naming this limit, instead of running for minutes
MAX_PERIODS_PER_STEP = 100_000


def range_key(name: str) -> str:
    """Key of the FMU variable ``name`` in :data:`validation.RANGES`."""
    return name if name in RANGES and name != "preload" else f"fmu.{name}"


def variable_range(name: str) -> Range:
    """Allowed range of a Real parameter or input of the FMU."""
    return RANGES[range_key(name)]


def input_range(name: str, friction_force: float) -> Range:
    """Allowed range [N] of the input ``name`` for the static friction threshold ``friction_force``
    (F0 = mu_static normal_force [N]): the library's range of its group, times F0, symmetric."""
    limit = RANGES[INPUT_GROUPS[name]].hi * friction_force
    return Range(-limit, limit, unit="N")


def _ordered(x: float) -> int:
    """An integer that orders doubles as their values do (adjacent doubles: adjacent integers)."""
    bits = struct.unpack("<q", struct.pack("<d", x))[0]
    return bits if bits >= 0 else -(bits & 0x7FFF_FFFF_FFFF_FFFF)


def _from_ordered(i: int) -> float:
    bits = i if i >= 0 else (-i) | (1 << 63)
    return struct.unpack("<d", struct.pack("<Q", bits))[0]


def _edge(accepts, inside: float, outside: float) -> float:
    """The accepted double nearest ``outside``, from ``inside`` (accepted) on (acceptance an interval)."""
    if accepts(outside):
        return outside
    a, b = _ordered(inside), _ordered(outside)
    while abs(b - a) > 1:
        m = (a + b) // 2
        if accepts(_from_ordered(m)):
            a = m
        else:
            b = m
    return _from_ordered(a)


def accepted_bounds(values: dict, accepts, names=None) -> dict:
    """``{name: (lo, hi)}``: the exact interval of values of each Real parameter that
    ``accepts(values with that one changed)`` takes, the others at ``values`` -- what the model
    description declares as min/max (its own range in :data:`RANGES`, narrowed by the
    constraints between parameters, e.g. mu_kinetic <= mu_static, and by the library's
    ranges of the nondimensional groups)."""
    out = {}
    for name in names or [v.name for v in PARAMETERS]:
        rng = variable_range(name)

        def ok(x, name=name):
            return accepts({**values, name: x})

        start = values[name]
        out[name] = (_edge(ok, start, rng.lo), _edge(ok, start, rng.hi))
    return out


def start_values(overrides=None) -> dict:
    """Start values of every parameter and input: the lab preset, then ``overrides``."""
    vals = {name: float(getattr(_RIG, name)) for name in RIG_FIELDS}
    vals.update(gap=_DEFAULT_GAP, impact_enabled=False, initial_hammer_position=0.0,
                initial_bit_position=0.0, tolerance=DEFAULT_TOLERANCE,
                preload=float(_RIG.preload), harmonic_force=0.0)
    for name, value in (overrides or {}).items():
        if name not in vals:
            raise KeyError(name)
        vals[name] = bool(value) if name == "impact_enabled" else float(value)
    return vals


def nominal_values(rig: RigParameters) -> dict:
    """``nominal`` of the Real variables whose size is far from 1: each variable's rig scale or own
    value (:attr:`FmuVariable.nominal <.fmu_description.FmuVariable.nominal>`)."""
    out = {}
    for var in HAMMER_VARIABLES:
        if var.nominal == "rig":
            v = abs(float(getattr(rig, var.name)))
            if v > 0.0 and math.isfinite(v):
                out[var.name] = v
        elif var.nominal is not None:
            out[var.name] = float(getattr(rig.scales, var.nominal))
    return {k: float(f"{v:.6g}") for k, v in out.items() if not 0.1 <= v <= 10.0}
