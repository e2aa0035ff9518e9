"""The build's check that a modelDescription.xml it ships declares exactly its FMU's table.

The value references, names, causalities and types of an FMU's variables are fixed by its table in
:mod:`hammerbit.model.fmu_description` (a variable's value reference is its index there); the C
headers are generated from the table, and pythonfmu writes the XML from the order in which the
slave registers them.  Before an FMU is written, :func:`check_description` compares the two, so a
slave that registers out of order, or an XML edited by hand, fails the build with the differences
named instead of shipping binaries that read the wrong variables.  Variables the build adds after
the table (``der(...)``, FMI 3.0's ``time`` and event indicators) are allowed with value
references past it.
"""
from __future__ import annotations

from xml.etree import ElementTree as ET

from hammerbit.model.fmu_description import FMI2_TYPE

__all__ = ["DescriptionMismatchError", "declared_variables", "check_description"]

#: the type elements of an FMI 2.0 ScalarVariable
_FMI2_ELEMENTS = ("Real", "Integer", "Boolean", "String")


class DescriptionMismatchError(RuntimeError):
    """A model description does not declare its FMU's table (the message lists each difference)."""


def declared_variables(xml) -> tuple:
    """``(fmi3, {name: (value reference, causality, type)})`` of an FMI 2.0 or 3.0 model
    description (``type``: the FMI 2.0 type element, or the FMI 3.0 variable tag)."""
    root = ET.fromstring(xml)
    fmi3 = root.get("fmiVersion", "").startswith("3.")
    out = {}
    for el in root.find("ModelVariables"):
        tag = el.tag if fmi3 else next((c.tag for c in el if c.tag in _FMI2_ELEMENTS), None)
        out[el.get("name")] = (int(el.get("valueReference")), el.get("causality", "local"), tag)
    return fmi3, out


def check_description(xml, table, fmu: str) -> None:
    """Raise :class:`DescriptionMismatchError` unless ``xml`` declares every variable of ``table``
    (a tuple of :class:`~hammerbit.model.fmu_description.FmuVariable`) at its index as value
    reference, with its causality and type, and nothing else below ``len(table)``."""
    fmi3, declared = declared_variables(xml)
    problems = []
    for vr, var in enumerate(table):
        want = (vr, var.causality, var.type if fmi3 else FMI2_TYPE[var.type])
        got = declared.get(var.name)
        if got != want:
            problems.append(f"{var.name}: the table gives value reference {want[0]}, {want[1]}, {want[2]}; "
                            f"the XML " + ("has no such variable" if got is None else
                                           f"declares {got[0]}, {got[1]}, {got[2]}"))
    names = {var.name for var in table}
    problems += [f"{name}: value reference {vr} is in the table's range but the table has no {name}"
                 for name, (vr, _, _) in declared.items() if name not in names and vr < len(table)]
    if problems:
        raise DescriptionMismatchError(
            f"the modelDescription.xml of {fmu} does not declare its table "
            f"(hammerbit.model.fmu_description): " + "; ".join(problems))
