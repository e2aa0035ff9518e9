"""The variables of the HammerBitRock FMU: names, units, ranges, start values, descriptions.

One table per causality.  Names are :class:`RigParameters` field names
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

from .params import RigParameters
from .validation import RANGES, Range

__all__ = ["MAX_PERIODS_PER_STEP", "UNITS", "PARAMETERS", "BOOL_PARAMETERS", "INPUTS", "OUTPUTS", "RIG_FIELDS",
           "FIXED_REALS", "range_key", "variable_range", "start_values", "nominal_values",
           "DEFAULT_TOLERANCE", "INPUT_GROUPS", "input_range", "accepted_bounds"]

_RIG = RigParameters()          # the lab rig at the paper's Fig. 9 operating point

#: unit name -> SI base-unit exponents (FMI 2.0 <UnitDefinitions>); None: no base unit
UNITS = {
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "s/m": {"s": 1, "m": -1},
    "Hz": {"s": -1},
    "rad": {"rad": 1},
    "s": {"s": 1},
    "1": {},
    "N/m^n": None,   # Hunt-Crossley stiffness: the exponent n is a parameter
}

#: Real parameters: (name, unit, description).
PARAMETERS = (
    ("hammer_mass", "kg", "m1, mass of the hammer (drillstring side); > 0"),
    ("bit_mass", "kg", "m2, mass of the bit/slider (rock side); > 0"),
    ("stiffness", "N/m", "K, stiffness of the spring joining hammer and bit; > 0"),
    ("damping", "N.s/m", "C, viscous damping between hammer and bit; >= 0"),
    ("mu_static", "1", "mu_e, static friction coefficient of the bit on the rock; > 0"),
    ("mu_kinetic", "1", "mu_d, kinetic friction coefficient at high speed; 0 < mu_d <= mu_e"),
    ("friction_decay", "s/m", "gamma, velocity-weakening decay of the kinetic friction; >= 0"),
    ("normal_force", "N", "F_N, normal force of the bit on the rock; static threshold F0 = mu_e F_N; > 0"),
    ("contact_stiffness", "N/m^n", "Kc, Hunt-Crossley contact stiffness [N/m^n, n = contact_exponent]; >= 0"),
    ("contact_exponent", "1", "n, Hunt-Crossley exponent; 0 < n <= 5"),
    ("contact_damping", "s/m", "lam, Hunt-Crossley damping; >= 0"),
    ("gap", "m", "R, hammer-bit gap that closes before an impact; used only when impact_enabled; >= 0"),
    ("amplitude", "N", "A, amplitude of the internal harmonic source A sin(2 pi f t + phase) on the "
                       "hammer, added to the input harmonic_force; >= 0"),
    ("frequency", "Hz", "f, frequency of the internal harmonic source; > 0"),
    ("phase", "rad", "phase of the internal harmonic source at t = 0"),
    ("initial_hammer_position", "m", "hammer position x_b at the start time (velocities start at 0)"),
    ("initial_bit_position", "m", "bit position x_s at the start time; penetration is measured from it"),
    ("tolerance", "1", "relative tolerance of the adaptive solver (DOP853; absolute tolerance "
                       "1e-2 * tolerance in the length scale F0/K); tunable"),
)
#: parameters that are RigParameters fields (the rest: gap, initial positions, tolerance)
RIG_FIELDS = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
              "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
              "contact_damping", "amplitude", "frequency", "phase")
FIXED_REALS = tuple(n for n, _, _ in PARAMETERS if n != "tolerance")

#: Boolean parameters: (name, description)
BOOL_PARAMETERS = (
    ("impact_enabled", "true: the hammer closes the gap and impacts the bit (Hunt-Crossley contact); "
                       "false: no impact device (R = infinity)"),
)

DEFAULT_TOLERANCE = 1e-8
_DEFAULT_GAP = 0.84 * _RIG.scales.length     # the paper's Fig. 12 gap r = 0.84 (impact off by default)

#: Real inputs: (name, unit, description)
INPUTS = (
    ("preload", "N", "B, weight on bit pushing the hammer toward the rock; held over each communication "
                     "step; |B| <= 1000 F0 (F0 = mu_static normal_force, the static friction threshold; "
                     "min/max are those of the start values)"),
    ("harmonic_force", "N", "F_h, instantaneous external harmonic force on the hammer; held over each "
                            "communication step (zero-order hold) and added to the internal source; "
                            "|F_h| <= 1000 F0 (F0 = mu_static normal_force; min/max are those of the "
                            "start values)"),
)

#: the nondimensional group of the library that bounds each input, in units of the static
#: friction threshold F0: the preload b = B/F0, the forcing amplitude a = A/F0 (both +-1000 F0)
INPUT_GROUPS = {"preload": "group.b", "harmonic_force": "group.a"}

#: Outputs: (name, type, unit, description)
OUTPUTS = (
    ("hammer_position", "Real", "m", "x_b, hammer position (drilling direction positive)"),
    ("hammer_velocity", "Real", "m/s", "v_b, hammer velocity"),
    ("bit_position", "Real", "m", "x_s, bit position: the penetration (from the start time on)"),
    ("bit_velocity", "Real", "m/s", "v_s, bit velocity (>= 0: the bit only moves forward)"),
    ("spring_force", "Real", "N", "F_k = K (x_b - x_s) + C (v_b - v_s), spring and damper force on the bit"),
    ("contact_force", "Real", "N", "F_c, Hunt-Crossley impact force of the hammer on the bit (0 when free)"),
    ("friction_force", "Real", "N", "friction of the rock on the bit, positive against drilling: "
                                    "F_N (mu_d + (mu_e - mu_d) exp(-gamma v_s)) in slip, the static "
                                    "reaction F_d in stick"),
    ("rock_force", "Real", "N", "F_d = F_k + F_c, the force the bit drives into the rock"),
    ("rate_of_penetration", "Real", "m/s", "mean rate of penetration since the start time, "
                                           "(x_s - x_s(t_start)) / (t - t_start)"),
    ("stick_slip", "Integer", None, "bit state: 0 stick, 1 slip"),
    ("in_contact", "Boolean", None, "true while the hammer is in contact with the bit (gap closed)"),
    ("impact_count", "Integer", None, "number of impacts (gap closures) since the start time"),
    ("slip_count", "Integer", None, "number of stick-to-slip transitions since the start time"),
    ("bounce_count", "Integer", None, "number of bit-bounce violations (F_d < -F_s while stuck: the "
                                      "rock would have to pull the bit back; the bit is held)"),
    ("regime", "Integer", None, "regime verdict known at the current time, a sum of bits: 1 runaway (the "
                                "bit slips and provably never sticks again with the inputs held), 2 bounce "
                                "(a bounce so far), 4 tension (the drive on the bit fell below zero so far), "
                                "8 stall (no slip for 20 forcing periods up to now); one warning is logged "
                                "when it changes"),
)


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
    for name in names or [n for n, _, _ in PARAMETERS]:
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
    """``nominal`` of the Real variables whose size is far from 1 (the rig's own scales)."""
    s = rig.scales
    x0, v0, F0 = s.length, s.velocity, s.friction_force
    out = {"hammer_position": x0, "bit_position": x0, "hammer_velocity": v0, "bit_velocity": v0,
           "spring_force": F0, "contact_force": F0, "friction_force": F0, "rock_force": F0,
           "rate_of_penetration": v0, "preload": F0, "harmonic_force": F0, "gap": x0,
           "initial_hammer_position": x0, "initial_bit_position": x0}
    for name in ("stiffness", "damping", "normal_force", "contact_stiffness", "friction_decay",
                 "hammer_mass", "bit_mass", "amplitude"):
        v = abs(float(getattr(rig, name)))
        if v > 0.0 and math.isfinite(v):
            out[name] = v
    return {k: float(f"{v:.6g}") for k, v in out.items() if not 0.1 <= v <= 10.0}
