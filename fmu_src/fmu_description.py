"""The one description of the FMUs: their variables, codes and SI formulas, from which the C headers are generated.

What both languages need to agree on is written here once, in Python, and the builds write it
into C (:mod:`hammerbit.fmu.c_description`); nothing of it is typed again in C:

* the FMI types of the variables (FMI 3 names, with the FMI 2 type each maps to);
* the variables of the three FMUs and their value references (below);
* the integer codes of the Drillstring's ``top_condition`` (:data:`TOP_CONDITIONS`) and the
  bits of the ``regime`` verdict (:mod:`.regime_codes`);
* the formulas from the SI rig parameters to the paper's groups and the scales
  (:data:`SCALE_FORMULAS`, :data:`GROUP_FORMULAS`), in a small expression form: a formula is a
  name, a number, or a tuple ``(operation, operand, ...)`` of :data:`OPERATIONS`.  Python
  evaluates it (:func:`evaluate`, used by ``RigParameters.to_groups``) and the generator writes
  it out as C with the same operations in the same order, so that both give the same bits.

Every variable of every FMU is an :class:`FmuVariable` of its FMU's table, in value-reference
order: ``HammerBitRock.fmu``'s :data:`HAMMER_VARIABLES` (:data:`INPUTS`, :data:`PARAMETERS`,
:data:`BOOL_PARAMETERS`, :data:`OUTPUTS`, then :data:`STATUS_VARIABLE`; the ranges and nominals
its build's start values give: :mod:`.fmu_variables`), ``Drillstring.fmu``'s
:data:`STRING_VARIABLES` and ``DrillingSystem.fmu``'s :data:`SYSTEM_VARIABLES`.  A variable's
value reference is its index in its table (:func:`value_references`): the slaves register the
tables in order, the C headers are generated from them, and the builds check that the
``modelDescription.xml`` they ship declares exactly these (:mod:`hammerbit.fmu.table_check`).
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass

from . import kernel_layouts
from .regime_codes import REGIME_BITS

__all__ = ["FMI2_TYPE", "FmuVariable", "value_references", "SYSTEM_VARIABLES", "SYSTEM_INPUT_TOPS", "STRING_VARIABLES", "string_description_fields", "UNITS", "PARAMETERS", "BOOL_PARAMETERS", "INPUTS", "OUTPUTS", "STATUS_VARIABLE", "HAMMER_VARIABLES", "TopCondition", "TOP_CONDITIONS", "top_condition", "top_conditions_text", "REGIME_BITS", "TWO_PI", "OPERATIONS",
           "SI_NAMES", "SCALE_FORMULAS", "GROUP_FORMULAS", "GROUP_SLOTS", "KERNEL_SLOTS", "evaluate", "si_to_groups", "formula_names"]

#: the FMI 3 type of a variable -> its FMI 2 type
FMI2_TYPE = {"Float64": "Real", "Int32": "Integer", "UInt64": "Integer", "Boolean": "Boolean",
             "String": "String"}


@dataclass(frozen=True)
class TopCondition:
    """One value of the Drillstring's ``top_condition`` parameter."""

    name: str           #: as the CLI and the build name it (``--top``)
    code: int           #: the parameter's value
    form: str           #: the string side's form it steps with (``string_model.FORMS``)
    takes_feed: bool    #: whether ``feed_velocity`` may be non-zero
    description: str
    #: a few words for the ``top_condition`` variable's description ("" : the name)
    summary: str = ""


#: the Drillstring's top conditions, in the order of their codes (0, 1, ...)
TOP_CONDITIONS = (
    TopCondition("fixed", 0, "fixed", False, "the hook is held at its static position", "fixed hook"),
    TopCondition("feed", 1, "fixed", True, "the hook moves down at feed_velocity",
                 "constant feed (feed_velocity)"),
    TopCondition("auto-driller", 2, "auto", False, "a PI controller moves the hook to hold the WOB set point",
                 "auto-driller (PI on the hook load holding wob)"),
)


def top_condition(key) -> TopCondition:
    """The top condition of a name (``fixed``, ``feed``, ``auto-driller``) or a code."""
    for top in TOP_CONDITIONS:
        if key in (top.name, top.code) and not isinstance(key, bool):
            return top
    raise ValueError(f"top condition {key!r} is unknown; known: {top_conditions_text()}")


def top_conditions_text(tops=None) -> str:
    """``0 (fixed), 1 (feed), 2 (auto-driller)``: the codes as a message lists them."""
    return ", ".join(f"{t.code} ({t.name})" for t in (TOP_CONDITIONS if tops is None else tops))


#: 2 pi as Python rounds 2.0 * math.pi (one constant, the same double in C)
TWO_PI = 2.0 * math.pi

#: name -> (arity, Python function, C template); the C template writes the same IEEE operation
OPERATIONS = {
    "add": (2, operator.add, "({0} + {1})"),
    "sub": (2, operator.sub, "({0} - {1})"),
    "mul": (2, operator.mul, "({0} * {1})"),
    "div": (2, operator.truediv, "({0} / {1})"),
    "sqrt": (1, math.sqrt, "sqrt({0})"),
    "pow": (2, math.pow, "pow({0}, {1})"),
}

#: the SI rig parameters the formulas read (``RigParameters`` fields)
SI_NAMES = ("hammer_mass", "bit_mass", "stiffness", "damping", "mu_static", "mu_kinetic",
            "friction_decay", "normal_force", "contact_stiffness", "contact_exponent",
            "contact_damping", "gap", "preload", "amplitude", "frequency", "phase")

#: the scales, in the order they are computed (each may use the ones before it)
SCALE_FORMULAS = (
    ("F0", ("mul", "mu_static", "normal_force")),              # static friction threshold [N]
    ("Omega", ("sqrt", ("div", "stiffness", "hammer_mass"))),  # time scale [rad/s]
    ("x0", ("div", "F0", "stiffness")),                        # length scale [m]
)

#: the paper's twelve groups (``Groups`` fields, in their order) from the SI parameters and scales
GROUP_FORMULAS = (
    ("rho", ("div", "bit_mass", "hammer_mass")),
    ("xi", ("div", "damping", ("mul", 2.0, ("sqrt", ("mul", "stiffness", "hammer_mass"))))),
    ("eta", ("div", ("mul", TWO_PI, "frequency"), "Omega")),
    ("a", ("div", "amplitude", "F0")),
    ("b", ("div", "preload", "F0")),
    ("r", ("div", "gap", "x0")),
    ("mu", ("div", "mu_kinetic", "mu_static")),
    ("gamma_hat", ("mul", ("mul", "friction_decay", "x0"), "Omega")),
    ("kc", ("div", ("mul", "contact_stiffness", ("pow", "x0", "contact_exponent")), "F0")),
    ("n", "contact_exponent"),
    ("lam_hat", ("mul", ("mul", "contact_damping", "x0"), "Omega")),
    ("phi", "phase"),
)

#: the slot of each group in the kernels' parameter vector (``kernel_layouts.P_*``)
GROUP_SLOTS = {"rho": "P_RHO", "xi": "P_XI", "eta": "P_ETA", "a": "P_A", "b": "P_B", "r": "P_R", "mu": "P_MU",
               "gamma_hat": "P_GAMMA", "kc": "P_KC", "n": "P_N", "lam_hat": "P_LAM", "phi": "P_PHI"}
#: ``((group, its index in the kernels' parameter vector), ...)`` in the order of the groups
KERNEL_SLOTS = tuple((name, getattr(kernel_layouts, GROUP_SLOTS[name])) for name, _ in GROUP_FORMULAS)


def formula_names(expr) -> set:
    """The names a formula reads."""
    if isinstance(expr, str):
        return {expr}
    if isinstance(expr, tuple):
        return set().union(*(formula_names(e) for e in expr[1:]))
    return set()


def evaluate(expr, env: dict) -> float:
    """The value of the formula ``expr`` with the names of ``env``."""
    if isinstance(expr, str):
        return env[expr]
    if isinstance(expr, tuple):
        arity, fn, _ = OPERATIONS[expr[0]]
        if len(expr) != arity + 1:
            raise ValueError(f"{expr[0]} takes {arity} operands, the formula {expr!r} gives {len(expr) - 1}")
        return fn(*(evaluate(e, env) for e in expr[1:]))
    return float(expr)


def si_to_groups(si: dict) -> tuple:
    """``(scales, groups)``: the dicts of :data:`SCALE_FORMULAS` and :data:`GROUP_FORMULAS` for the
    SI parameters ``si`` (every name of :data:`SI_NAMES`)."""
    env = dict(si)
    scales = {}
    for name, expr in SCALE_FORMULAS:
        env[name] = scales[name] = evaluate(expr, env)
    return scales, {name: evaluate(expr, env) for name, expr in GROUP_FORMULAS}


@dataclass(frozen=True)
class FmuVariable:
    """One variable of an FMU; its value reference is its index in its FMU's table
    (:data:`HAMMER_VARIABLES`, :data:`STRING_VARIABLES`, :data:`SYSTEM_VARIABLES`)."""

    name: str
    type: str           #: FMI 3 type name (:data:`FMI2_TYPE` gives the FMI 2 one)
    causality: str      #: parameter, input, output or local
    unit: str           #: SI unit ("" for counts, codes and where the description names it)
    description: str
    start: object = None  #: parameters and inputs: the start value (None: the build's value)
    #: a number; the name of a build value (``buoyed_weight``, ``max_feed``; ``-name`` its negative),
    #: which the build declares and enforces; None: unbounded, or the build's own range
    min: object = None
    max: object = None
    #: a number; or the rig scale that sizes the variable (``length``, ``velocity``,
    #: ``friction_force``: :class:`~.params.Scales` fields), or ``rig`` (the rig parameter's own
    #: value); None: none declared
    nominal: object = None
    variability: str = ""  #: FMI 2 variability ("": the FMU's rule by causality)


#: the variables of DrillingSystem.fmu, in value-reference order (the C model reads them by name)
SYSTEM_VARIABLES = (
    FmuVariable("tolerance", "Float64", "parameter", "", "relative accuracy of penetration and mean "
                   "WOB against the monolithic reference (the solver runs at rtol = tolerance / 10)",
                   1e-3, 1e-8, 0.1),
    FmuVariable("amplitude", "Float64", "input", "N", "amplitude of the hammer's harmonic force", None, 0.0,
                1e9),
    FmuVariable("frequency", "Float64", "input", "Hz", "frequency of the harmonic force (the phase is "
                   "kept continuous when it changes)", None, 1e-3, 1e4),
    FmuVariable("wob_set_point", "Float64", "input", "N", "the auto-driller's WOB set point (only "
                   "with the auto-driller; other top conditions refuse a change)", None, 0.0, "buoyed_weight"),
    FmuVariable("feed_velocity", "Float64", "input", "m/s", "the block's downward velocity (only with "
                   "the feed; other top conditions refuse a change)", None, "-max_feed", "max_feed"),
    FmuVariable("bit_position", "Float64", "output", "m", "bit position (down positive)"),
    FmuVariable("rate_of_penetration", "Float64", "output", "m/s", "mean bit velocity over the last "
                   "communication step"),
    FmuVariable("wob", "Float64", "output", "N", "weight on bit: spring, damper and contact force on "
                   "the bit at the communication point"),
    FmuVariable("mean_wob", "Float64", "output", "N", "weight on bit averaged over the last "
                   "communication step (from the hammer's momentum balance, exact to the solver's accuracy)"),
    FmuVariable("hook_load", "Float64", "output", "N", "tension at the top of the string"),
    FmuVariable("hammer_position", "Float64", "output", "m", "hammer position (down positive)"),
    FmuVariable("hammer_velocity", "Float64", "output", "m/s", "hammer velocity"),
    FmuVariable("contact_force", "Float64", "output", "N", "contact force between hammer and bit"),
    FmuVariable("stick_slip", "Int32", "output", "", "1 while the bit sticks, 0 while it slips"),
    FmuVariable("impact_count", "UInt64", "output", "", "impacts of the hammer on the bit so far"),
    FmuVariable("slip_count", "UInt64", "output", "", "slip phases of the bit started so far"),
    FmuVariable("coupling_error", "Float64", "output", "", "error estimate of the last communication "
                   "step: the larger of the relative errors of the bit position (to the largest penetration "
                   "so far) and of the mean WOB, from a shadow run at a 32 times tighter tolerance; at a step "
                   "corrected from the shadow, the shadow's error (the difference over 32^(8/9))"),
    FmuVariable("regime", "Int32", "output", "", "regime bits: bounce and tension seen in the last "
                   "communication step, runaway and stall the verdicts on the run so far"),
)

#: the inputs that only some top conditions use: input -> the top condition that uses it
SYSTEM_INPUT_TOPS = {"wob_set_point": "auto-driller", "feed_velocity": "feed"}


#: the variables of Drillstring.fmu, in value-reference order (both slaves register them from
#: here; variability: parameters fixed, inputs and outputs continuous, the locals constant).  A
#: description is a template: the slave fills ``{buoyed_weight}`` (its build's, N), ``{max_feed}``
#: (m/s), ``{tops}`` (the top conditions' codes and summaries) and ``{feed}``, ``{auto}`` (the codes
#: of the top conditions with a feed velocity and with the auto-driller's form).
STRING_VARIABLES = (
    FmuVariable("damping_ratio", "Float64", "parameter", "", "modal damping ratio of every string "
                   "mode [-]; [0, 1)"),
    FmuVariable("wob", "Float64", "parameter", "", "weight on bit of the static equilibrium [N]; "
                   "[0, buoyed weight {buoyed_weight:.6g} N]"),
    FmuVariable("hammer_position_at_rest", "Float64", "parameter", "", "hammer position of the "
                   "static equilibrium [m] (the hammer's initial_hammer_position)"),
    FmuVariable("extrapolation", "Int32", "parameter", "", "polynomial order of the hammer "
                   "motion over a step and of the held force: 0, 1 or 2"),
    FmuVariable("top_condition", "Int32", "parameter", "", "the top: {tops}"),
    FmuVariable("feed_velocity", "Float64", "parameter", "", "top_condition {feed}: downward velocity "
                   "of the block [m/s]; [-{max_feed:.4g}, {max_feed:.4g}] (1000 m/h)"),
    FmuVariable("proportional_gain", "Float64", "parameter", "", "top_condition {auto}: k_p of the "
                   "auto-driller [m/s per N of hook-load error]; [0, 1] (default: the build's tuning "
                   "from the string's stiffness)"),
    FmuVariable("integral_gain", "Float64", "parameter", "", "top_condition {auto}: k_i of the "
                   "auto-driller [m/s per N s]; [0, 1] (default: the build's tuning)"),
    FmuVariable("hammer_position", "Float64", "input", "", "hammer position at the step's start [m], "
                   "downward"),
    FmuVariable("hammer_velocity", "Float64", "input", "", "hammer velocity at the step's start "
                   "[m/s], downward"),
    FmuVariable("interface_force", "Float64", "output", "", "interface force on the hammer at the "
                   "communication point [N]"),
    FmuVariable("held_force", "Float64", "output", "", "interface force for the hammer to hold over "
                   "the next step [N]"),
    FmuVariable("held_force_change", "Float64", "output", "", "held_force - wob [N] (to the hammer's "
                   "harmonic_force input)"),
    FmuVariable("hook_load", "Float64", "output", "", "hook load: tension in the top element [N]"),
    FmuVariable("top_position", "Float64", "output", "", "top (hook) displacement [m], downward"),
    FmuVariable("top_velocity", "Float64", "output", "", "top (hook) velocity [m/s], downward"),
    FmuVariable("string_length", "Float64", "local", "", "length of the string [m] (fixed at build "
                   "time)"),
    FmuVariable("interface_stiffness", "Float64", "local", "", "interface stiffness k_i [N/m] (fixed "
                   "at build time)"),
    FmuVariable("interface_damping", "Float64", "local", "", "interface damping c_i [N s/m] (fixed at "
                   "build time)"),
    FmuVariable("buoyed_weight", "Float64", "local", "", "buoyed weight of the string [N] (fixed at "
                   "build time)"),
    FmuVariable("string_states", "Int32", "local", "", "states of the string side (fixed at build "
                   "time)"),
)


def string_description_fields(buoyed_weight: float, max_feed: float) -> dict:
    """The fields of :data:`STRING_VARIABLES`' description templates for a build."""
    def codes(tops):
        return " or ".join(str(t.code) for t in tops)
    return {"buoyed_weight": buoyed_weight, "max_feed": max_feed,
            "tops": ", ".join(f"{t.code} {t.summary or t.name}" for t in TOP_CONDITIONS),
            "feed": codes([t for t in TOP_CONDITIONS if t.takes_feed]),
            "auto": codes([t for t in TOP_CONDITIONS if t.form == "auto"])}


# ---------------------------------------------------------------------------------------------
# HammerBitRock.fmu's variables (ranges, start values and nominals: hammerbit.model.fmu_variables)
# ---------------------------------------------------------------------------------------------
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

def _real(name, unit, description, causality, nominal=None, variability=None) -> FmuVariable:
    return FmuVariable(name, "Float64", causality, unit, description, nominal=nominal, variability=variability)


#: Real parameters, in value-reference order (nominal: see :class:`FmuVariable`)
PARAMETERS = tuple(_real(name, unit, desc, "parameter", nominal,
                         "tunable" if name == "tolerance" else "fixed") for name, unit, nominal, desc in (
    ("hammer_mass", "kg", "rig", "m1, mass of the hammer (drillstring side); > 0"),
    ("bit_mass", "kg", "rig", "m2, mass of the bit/slider (rock side); > 0"),
    ("stiffness", "N/m", "rig", "K, stiffness of the spring joining hammer and bit; > 0"),
    ("damping", "N.s/m", "rig", "C, viscous damping between hammer and bit; >= 0"),
    ("mu_static", "1", None, "mu_e, static friction coefficient of the bit on the rock; > 0"),
    ("mu_kinetic", "1", None, "mu_d, kinetic friction coefficient at high speed; 0 < mu_d <= mu_e"),
    ("friction_decay", "s/m", "rig", "gamma, velocity-weakening decay of the kinetic friction; >= 0"),
    ("normal_force", "N", "rig", "F_N, normal force of the bit on the rock; static threshold F0 = mu_e F_N; > 0"),
    ("contact_stiffness", "N/m^n", "rig", "Kc, Hunt-Crossley contact stiffness [N/m^n, n = contact_exponent]; "
                                          ">= 0"),
    ("contact_exponent", "1", None, "n, Hunt-Crossley exponent; 0 < n <= 5"),
    ("contact_damping", "s/m", None, "lam, Hunt-Crossley damping; >= 0"),
    ("gap", "m", "length", "R, hammer-bit gap that closes before an impact; used only when impact_enabled; >= 0"),
    ("amplitude", "N", "rig", "A, amplitude of the internal harmonic source A sin(2 pi f t + phase) on the "
                              "hammer, added to the input harmonic_force; >= 0"),
    ("frequency", "Hz", None, "f, frequency of the internal harmonic source; > 0"),
    ("phase", "rad", None, "phase of the internal harmonic source at t = 0"),
    ("initial_hammer_position", "m", "length", "hammer position x_b at the start time (velocities start at 0)"),
    ("initial_bit_position", "m", "length", "bit position x_s at the start time; penetration is measured from it"),
    ("tolerance", "1", None, "relative tolerance of the adaptive solver (DOP853; absolute tolerance "
                             "1e-2 * tolerance in the length scale F0/K); tunable"),
))
#: Boolean parameters
BOOL_PARAMETERS = (
    FmuVariable("impact_enabled", "Boolean", "parameter", "", "true: the hammer closes the gap and impacts the "
                "bit (Hunt-Crossley contact); false: no impact device (R = infinity)", variability="fixed"),
)

#: Real inputs (min/max: the build's, from the static friction threshold of its start values)
INPUTS = tuple(_real(name, "N", desc, "input", "friction_force", "continuous") for name, desc in (
    ("preload", "B, weight on bit pushing the hammer toward the rock; held over each communication "
                "step; |B| <= 1000 F0 (F0 = mu_static normal_force, the static friction threshold; "
                "min/max are those of the start values)"),
    ("harmonic_force", "F_h, instantaneous external harmonic force on the hammer; held over each "
                       "communication step (zero-order hold) and added to the internal source; "
                       "|F_h| <= 1000 F0 (F0 = mu_static normal_force; min/max are those of the "
                       "start values)"),
))


def _out(name, fmi3, unit, description, nominal=None) -> FmuVariable:
    return FmuVariable(name, fmi3, "output", unit, description, nominal=nominal,
                       variability="continuous" if fmi3 == "Float64" else "discrete")


#: Outputs, in value-reference order
OUTPUTS = (
    _out("hammer_position", "Float64", "m", "x_b, hammer position (drilling direction positive)", "length"),
    _out("hammer_velocity", "Float64", "m/s", "v_b, hammer velocity", "velocity"),
    _out("bit_position", "Float64", "m", "x_s, bit position: the penetration (from the start time on)", "length"),
    _out("bit_velocity", "Float64", "m/s", "v_s, bit velocity (>= 0: the bit only moves forward)", "velocity"),
    _out("spring_force", "Float64", "N", "F_k = K (x_b - x_s) + C (v_b - v_s), spring and damper force on the "
                                         "bit", "friction_force"),
    _out("contact_force", "Float64", "N", "F_c, Hunt-Crossley impact force of the hammer on the bit (0 when "
                                          "free)", "friction_force"),
    _out("friction_force", "Float64", "N", "friction of the rock on the bit, positive against drilling: "
                                           "F_N (mu_d + (mu_e - mu_d) exp(-gamma v_s)) in slip, the static "
                                           "reaction F_d in stick", "friction_force"),
    _out("rock_force", "Float64", "N", "F_d = F_k + F_c, the force the bit drives into the rock", "friction_force"),
    _out("rate_of_penetration", "Float64", "m/s", "mean rate of penetration since the start time, "
                                                  "(x_s - x_s(t_start)) / (t - t_start)", "velocity"),
    _out("stick_slip", "Int32", "", "bit state: 0 stick, 1 slip"),
    _out("in_contact", "Boolean", "", "true while the hammer is in contact with the bit (gap closed)"),
    _out("impact_count", "UInt64", "", "number of impacts (gap closures) since the start time"),
    _out("slip_count", "UInt64", "", "number of stick-to-slip transitions since the start time"),
    _out("bounce_count", "UInt64", "", "number of bit-bounce violations (F_d < -F_s while stuck: the "
                                       "rock would have to pull the bit back; the bit is held)"),
    _out("regime", "Int32", "", "regime verdict known at the current time, a sum of bits: 1 runaway (the "
                                "bit slips and provably never sticks again with the inputs held), 2 bounce "
                                "(a bounce so far), 4 tension (the drive on the bit fell below zero so far), "
                                "8 stall (no slip for 20 forcing periods up to now); one warning is logged "
                                "when it changes"),
)
#: the status of the last call, for the native front of the pythonfmu flavour (``last_status``)
STATUS_VARIABLE = FmuVariable(
    "last_status", "Int32", "local", "", "FMI status the last call should return (0 OK, 1 Warning, 2 Discard, "
    "3 Error); the FMU's native front returns it to the master", variability="discrete")

#: every variable of HammerBitRock.fmu, in value-reference order (the slave registers them so)
HAMMER_VARIABLES = INPUTS + PARAMETERS + BOOL_PARAMETERS + OUTPUTS + (STATUS_VARIABLE,)


def value_references(variables) -> dict:
    """``{name: value reference}`` of an FMU's table: each variable's index in it."""
    vrs = {v.name: vr for vr, v in enumerate(variables)}
    if len(vrs) != len(variables):
        raise ValueError("two variables of one FMU's table share a name")
    return vrs
