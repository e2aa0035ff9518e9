"""The continuation parameter: any group or SI parameter as ``--set`` names it, read and set on the groups."""
from __future__ import annotations

from dataclasses import dataclass

from hammerbit.model.params import Groups
from hammerbit.model.settings import apply_settings, setting_target

__all__ = ["Parameter"]


@dataclass(frozen=True)
class Parameter:
    """A named parameter of the scene (``a``, ``eta``, ``B``, ``frequency`` ...).

    Continuation runs in the scaled value ``value / scale`` (``scale`` the
    magnitude at the start), so that an SI parameter of 2170 N/m and a group
    of 0.1 take steps of the same size relative to the orbit's coordinates.
    """

    name: str
    scale: float = 1.0

    @classmethod
    def on(cls, name: str, groups: Groups) -> "Parameter":
        """The parameter ``name``, scaled by its magnitude in ``groups`` if an SI one (groups: scale 1)."""
        setting_target(name)  # a ParameterError naming it when unknown
        v = abs(cls(name).value(groups))
        kind = setting_target(name)[0]
        return cls(name, 1.0 if kind == "group" or v == 0.0 else v)

    def value(self, groups: Groups) -> float:
        """The parameter's value in ``groups`` (SI names in SI units)."""
        kind, target = setting_target(self.name)
        if kind == "group":
            return float(getattr(groups, target))
        return float(getattr(groups.to_rig(), target))

    def at(self, base: Groups, value: float) -> Groups:
        """``base`` with the parameter set to ``value``."""
        return apply_settings(base, {self.name: float(value)})
