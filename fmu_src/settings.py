"""The ``--set NAME=VALUE`` resolution: group names, SI symbols and SI/FMU names onto the parameters."""
from __future__ import annotations

from dataclasses import fields

from .params import GROUP_NAMES, Groups, RigParameters
from .validation import ParameterError

__all__ = ["SI_ALIASES", "FMU_ALIASES", "RIG_FIELDS", "setting_target", "apply_settings", "is_real"]

#: Short SI names accepted by ``--set`` (the spec's symbols) -> RigParameters field.
SI_ALIASES = {
    "m1": "hammer_mass", "m2": "bit_mass", "K": "stiffness", "C": "damping",
    "mu_e": "mu_static", "mu_d": "mu_kinetic", "gamma": "friction_decay",
    "F_N": "normal_force", "Kc": "contact_stiffness", "lam": "contact_damping",
    "R": "gap", "B": "preload", "A": "amplitude", "f": "frequency",
}



#: FMU variable names that are not RigParameters fields, accepted by ``--set`` too.
FMU_ALIASES = {"impact_gap": "gap"}


def setting_target(key: str, value=None) -> tuple[str, str]:
    """Where a ``--set`` name points: ``("group", name)`` or ``("rig", field)``.

    Accepted names: the groups (``a``, ``b``, ``eta`` ...), the spec's SI
    symbols (``m1``, ``K``, ``mu_d``, ``B``, ``A``, ``f`` ...), the
    :class:`RigParameters` fields, which are also the FMU's variable names
    (``hammer_mass``, ``preload``, ``amplitude``, ``frequency`` ...).
    """
    if key in GROUP_NAMES:
        return "group", key
    if key in SI_ALIASES:
        return "rig", SI_ALIASES[key]
    if key in RIG_FIELDS:
        return "rig", key
    if key in FMU_ALIASES:
        return "rig", FMU_ALIASES[key]
    raise ParameterError(key, "?" if value is None else value, "a known name: a group (" + ", ".join(GROUP_NAMES)
                         + "), an SI symbol (" + ", ".join(SI_ALIASES)
                         + ") or an SI/FMU name (" + ", ".join(RIG_FIELDS) + ")")


def apply_settings(groups: Groups, settings: dict) -> Groups:
    """Apply ``{name: value}`` overrides given by group, SI symbol or SI/FMU name.

    Group names change the group directly.  SI names are applied to the scene's
    SI parameters (at its own scales) and converted back, so e.g. ``K`` changes
    every group that depends on it *and* the scales that turn results into SI.
    Errors name the parameter as it was typed.
    """
    g_changes, si_changes, typed = {}, {}, {}
    for key, value in settings.items():
        kind, name = setting_target(key, value)
        typed[name] = key
        (g_changes if kind == "group" else si_changes)[name] = value
    try:
        if si_changes:
            groups = groups.to_rig(mu_static=float(si_changes.get("mu_static", groups.mu_static))
                                   if is_real(si_changes.get("mu_static", groups.mu_static))
                                   else groups.mu_static).replace(**si_changes).to_groups()
        if g_changes:
            groups = groups.replace(**g_changes)
    except ParameterError as e:
        raise e.renamed(typed.get(e.name, e.name)) from None
    return groups


def is_real(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


RIG_FIELDS = tuple(f.name for f in fields(RigParameters))
