"""The FMI 3.0 model description of a native FMU, and the FMI 3.0 front's header, from its FMI 2.0 one.

The native builds write the FMI 2.0 description (:mod:`hammerbit.fmu.native_build`); the FMI 3.0
one is that description in FMI 3.0's form, so both versions have the same variables, names,
value references, units, ranges and start values:

* the types of the FMU's table (:class:`hammerbit.model.fmu_description.FmuVariable`: Float64,
  Int32, UInt64, Boolean, String); a variable the build adds after the table (``der(...)``) is
  a Real, Float64;
* ``<CoSimulation>`` declares ``mightReturnEarlyFromDoStep`` and ``hasEventMode`` where the model
  has events, ``canHandleVariableCommunicationStepSize`` as in FMI 2.0; ``<ModelExchange>`` as
  in FMI 2.0;
* what FMI 3.0 has as variables: the independent variable ``time`` and the event indicators
  ``event_indicator_<kind>`` (one per event kind of the kernels, in the kernels' order), with
  value references after the FMI 2.0 ones;
* ``<ModelStructure>`` by value reference (``Output``, ``ContinuousStateDerivative``,
  ``InitialUnknown``, ``EventIndicator``).

``hb_fmi3.h`` (:func:`fmi3_header`) gives the FMI 3.0 front each value reference's FMI 3 type.
"""
from __future__ import annotations

from xml.etree import ElementTree as ET

from hammerbit.fmu.native import c_string

__all__ = ["FMI3_PLATFORMS", "Fmi3DescriptionError", "fmi3_model_description", "fmi3_header"]

#: FMI 3.0's platform directory of each platform of the native builds
FMI3_PLATFORMS = {"linux64": "x86_64-linux", "win64": "x86_64-windows", "aarch64-linux": "aarch64-linux"}
_TYPES = ("Float64", "Int32", "UInt64", "Boolean", "String")
#: attributes of an FMI 2.0 type element that FMI 3.0 keeps on the variable
_TYPE_ATTRS = ("start", "unit", "min", "max", "nominal", "declaredType", "quantity", "displayUnit")
_VARIABLE_ATTRS = ("name", "valueReference", "description", "causality", "variability", "initial",
                   "canHandleMultipleSetPerTimeInstant")


class Fmi3DescriptionError(ValueError):
    """The FMI 2.0 description cannot be written as FMI 3.0 (the message says why)."""


def _root_attrs(md2) -> dict:
    keep = ("modelName", "description", "author", "version", "copyright", "license",
            "generationTool", "generationDateAndTime", "variableNamingConvention")
    out = {"fmiVersion": "3.0", "modelName": md2.get("modelName"), "instantiationToken": md2.get("guid")}
    out.update({k: md2.get(k) for k in keep if md2.get(k) is not None})
    return out


def _fmi3_types(table):
    """``(name, FMI 2 type) -> FMI 3 type``: the table's types; Float64 for a Real the build
    added (``der(...)``)."""
    types = {v.name: v.type for v in table}

    def fmi3_type(name: str, fmi2_type: str) -> str:
        if name in types:
            return types[name]
        if fmi2_type != "Real":
            raise Fmi3DescriptionError(f"{name!r} ({fmi2_type}) is not in the FMU's table: no FMI 3 type")
        return "Float64"
    return fmi3_type


def _variables(md2, fmi3_type) -> tuple:
    """(FMI 3 variable elements, {FMI 2 index: value reference}, derivatives' value references)."""
    out, vr_of_index, der = [], {}, []
    svs = list(md2.find("ModelVariables"))
    seen = set()
    for i, sv in enumerate(svs, start=1):
        kind = next(c for c in sv if c.tag in ("Real", "Integer", "Boolean", "String"))
        vr = int(sv.get("valueReference"))
        if vr in seen:
            raise Fmi3DescriptionError(f"value reference {vr} is used by two variables (FMI 3.0 needs "
                                       f"one value reference per variable)")
        seen.add(vr)
        vr_of_index[i] = vr
        el = ET.Element(fmi3_type(sv.get("name"), kind.tag))
        for a in _VARIABLE_ATTRS:
            if sv.get(a) is not None:
                el.set(a, sv.get(a))
        for a in _TYPE_ATTRS:
            if kind.get(a) is not None:
                el.set(a, kind.get(a))
        if kind.get("derivative") is not None:
            der.append((el, int(kind.get("derivative"))))
        out.append(el)
    for el, index in der:
        el.set("derivative", str(vr_of_index[index]))
    return out, vr_of_index, [int(el.get("valueReference")) for el, _ in der]


def fmi3_model_description(xml2: bytes, event_names, table) -> bytes:
    """The FMI 3.0 ``modelDescription.xml`` of a native FMU from its FMI 2.0 one.

    ``event_names`` names the event indicators (the kernels' event kinds, in the order of
    ``fmi2GetEventIndicators``); empty for an FMU without events (no Model Exchange, no early
    return, no Event Mode: the Drillstring); ``table``: the FMU's variables
    (:mod:`hammerbit.model.fmu_description`), whose types the FMI 3.0 variables take."""
    md2 = ET.fromstring(xml2)
    if md2.get("fmiVersion") != "2.0":
        raise Fmi3DescriptionError("not an FMI 2.0 model description")
    root = ET.Element("fmiModelDescription", _root_attrs(md2))
    me2, cs2 = md2.find("ModelExchange"), md2.find("CoSimulation")
    flags = {"canGetAndSetFMUState": cs2.get("canGetAndSetFMUstate", "false"),
             "canSerializeFMUState": cs2.get("canSerializeFMUstate", "false")}
    if me2 is not None:
        ET.SubElement(root, "ModelExchange", {"modelIdentifier": me2.get("modelIdentifier"),
                                              "needsCompletedIntegratorStep": "false", **flags})
    # early return and Event Mode where the model has events (HammerBitRock; not the Drillstring)
    events = "true" if event_names else "false"
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": cs2.get("modelIdentifier"), **flags,
        "canHandleVariableCommunicationStepSize": cs2.get("canHandleVariableCommunicationStepSize", "false"),
        "hasEventMode": events, "mightReturnEarlyFromDoStep": events,
        "canReturnEarlyAfterIntermediateUpdate": "false",
        # the output derivatives of the FMI 2.0 description (fmi3GetOutputDerivatives)
        **({"maxOutputDerivativeOrder": cs2.get("maxOutputDerivativeOrder")}
           if cs2.get("maxOutputDerivativeOrder") else {})})
    units = md2.find("UnitDefinitions")
    if units is None:
        units = ET.Element("UnitDefinitions")
    if "s" not in {u.get("name") for u in units}:      # the unit of time
        ET.SubElement(ET.SubElement(units, "Unit", {"name": "s"}), "BaseUnit", {"s": "1"})
    root.append(units)
    for tag in ("LogCategories", "DefaultExperiment"):
        el = md2.find(tag)
        if el is not None:
            root.append(el)
    variables, vr_of_index, der_vrs = _variables(md2, _fmi3_types(table))
    top = max(vr_of_index.values()) + 1
    time_vr, ind_vr0 = top, top + 1
    mv = ET.SubElement(root, "ModelVariables")
    mv.append(ET.Element("Float64", {"name": "time", "valueReference": str(time_vr),
                                     "causality": "independent", "variability": "continuous",
                                     "description": "simulation time", "unit": "s"}))
    mv.extend(variables)
    for k, name in enumerate(event_names):
        mv.append(ET.Element("Float64", {
            "name": f"event_indicator_{name}", "valueReference": str(ind_vr0 + k), "causality": "local",
            "variability": "continuous", "initial": "calculated",
            "description": f"indicator of the {name} event in the current modes (the event happens "
                           f"when it becomes > 0; -1 while the modes do not watch it)"}))
    ms = ET.SubElement(root, "ModelStructure")
    ms2 = md2.find("ModelStructure")
    for u in (ms2.find("Outputs") if ms2.find("Outputs") is not None else ()):
        ET.SubElement(ms, "Output", {"valueReference": str(vr_of_index[int(u.get("index"))]),
                                     "dependencies": ""})
    for vr in der_vrs:
        ET.SubElement(ms, "ContinuousStateDerivative", {"valueReference": str(vr)})
    for u in (ms2.find("InitialUnknowns") if ms2.find("InitialUnknowns") is not None else ()):
        ET.SubElement(ms, "InitialUnknown", {"valueReference": str(vr_of_index[int(u.get("index"))])})
    for k in range(len(event_names)):
        ET.SubElement(ms, "EventIndicator", {"valueReference": str(ind_vr0 + k)})
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"


def fmi3_header(xml3: bytes, n_states: int) -> str:
    """Text of ``hb_fmi3.h``: each value reference's FMI 3 type and name, the value references of
    time and of the event indicators, the numbers of states and indicators."""
    root = ET.fromstring(xml3)
    rows = [(int(v.get("valueReference")), v.tag, v.get("name")) for v in root.find("ModelVariables")]
    size = max(vr for vr, _, _ in rows) + 1
    types, names = ["-1"] * size, ["NULL"] * size
    for vr, tag, name in rows:
        types[vr] = f"HB3_{tag.upper()}"
        names[vr] = c_string(name)
    time_vr = next(vr for vr, _, name in rows if name == "time")
    ind = [vr for vr, _, name in rows if name.startswith("event_indicator_")]
    if ind and ind != list(range(ind[0], ind[0] + len(ind))):
        raise Fmi3DescriptionError("the event indicators' value references are not consecutive")
    ind0 = ind[0] if ind else size
    return "\n".join([
        "/* generated by hammerbit.fmu.fmi3_description from the FMI 3.0 modelDescription.xml */",
        f"#define HB3_VR_LEN {size}u",
        f"static const signed char HB3_TYPE_OF_VR[HB3_VR_LEN] = {{{', '.join(types)}}};",
        f"static const char *const HB3_NAMES[HB3_VR_LEN] = {{{', '.join(names)}}};",
        f"#define HB3_TIME_VR {time_vr}u",
        f"#define HB3_INDICATOR_VR0 {ind0}u",
        f"#define HB3_NZ {len(ind)}u",
        f"#define HB3_NX {n_states}u",
        f"#define HB3_HAS_ME {int(root.find('ModelExchange') is not None)}",
        "#define HB3_IS_INDICATOR(vr) ((vr) >= HB3_INDICATOR_VR0 && (vr) < HB3_INDICATOR_VR0 + HB3_NZ)",
        ""])
