"""``SystemStructure.ssd`` of the drilling system: written from a :class:`SystemDescription`, read back.

SSP 1.0: one system with two components (the Drillstring FMU and the
HammerBitRock FMU), their connectors, their parameter values (inline
``ssd:ParameterBindings``), the connections, a ``ssd:DefaultExperiment``
and, in the default experiment, the Open Simulation Platform's annotation
that libcosim reads for its fixed step
(``osp:Algorithm/osp:FixedStepAlgorithm baseStepSize``, in seconds); without it
libcosimpy's ``CosimExecution.from_ssp_file`` needs the step as an argument.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from xml.etree import ElementTree as ET

__all__ = ["SSD_NAME", "NS", "Component", "Connection", "SystemDescription", "write_ssd", "read_ssd"]

#: the file name SSP 1.0 gives the system structure in a package
SSD_NAME = "SystemStructure.ssd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
#: the annotation type libcosim's SSP parser looks for (in ``ssd:DefaultExperiment``)
OSP_ANNOTATION = "com.opensimulationplatform"
_FMU_TYPE = "application/x-fmu-sharedlibrary"


@dataclass
class Component:
    """One FMU of the system: its name, its file in the package, its connectors and parameter values.

    ``connectors``: ``{name: (kind, unit)}`` with kind ``input``/``output``; ``parameters``:
    ``{name: value}`` (float, int or bool)."""

    name: str
    source: str
    connectors: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Connection:
    """An output of one component wired to an input of another."""

    start_element: str
    start_connector: str
    end_element: str
    end_connector: str


@dataclass
class SystemDescription:
    """The system: components, connections, default experiment [s] and the fixed step [s]."""

    name: str
    components: list
    connections: list
    start_time: float = 0.0
    stop_time: float = 2.0
    step_size: float = 1e-3

    def component(self, name: str) -> Component:
        for c in self.components:
            if c.name == name:
                return c
        raise KeyError(f"the system has no component {name!r}; it has "
                       f"{', '.join(c.name for c in self.components)}")


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def _value_element(parent, value) -> None:
    if isinstance(value, bool):
        ET.SubElement(parent, _q("ssv", "Boolean"), {"value": "true" if value else "false"})
    elif isinstance(value, int):
        ET.SubElement(parent, _q("ssv", "Integer"), {"value": str(value)})
    else:
        ET.SubElement(parent, _q("ssv", "Real"), {"value": repr(float(value))})


def write_ssd(system: SystemDescription) -> bytes:
    """The XML of ``SystemStructure.ssd`` (UTF-8)."""
    for prefix, uri in NS.items():
        ET.register_namespace(prefix, uri)
    root = ET.Element(_q("ssd", "SystemStructureDescription"), {"version": "1.0", "name": system.name})
    sysel = ET.SubElement(root, _q("ssd", "System"), {"name": system.name})
    elements = ET.SubElement(sysel, _q("ssd", "Elements"))
    for comp in system.components:
        c = ET.SubElement(elements, _q("ssd", "Component"),
                          {"name": comp.name, "source": comp.source, "type": _FMU_TYPE})
        conns = ET.SubElement(c, _q("ssd", "Connectors"))
        for name, (kind, unit) in comp.connectors.items():
            cn = ET.SubElement(conns, _q("ssd", "Connector"), {"name": name, "kind": kind})
            ET.SubElement(cn, _q("ssc", "Real"), {"unit": unit} if unit else {})
        if comp.parameters:
            pb = ET.SubElement(ET.SubElement(c, _q("ssd", "ParameterBindings")), _q("ssd", "ParameterBinding"))
            pv = ET.SubElement(pb, _q("ssd", "ParameterValues"))
            ps = ET.SubElement(pv, _q("ssv", "ParameterSet"), {"version": "1.0", "name": comp.name})
            params = ET.SubElement(ps, _q("ssv", "Parameters"))
            for name, value in comp.parameters.items():
                _value_element(ET.SubElement(params, _q("ssv", "Parameter"), {"name": name}), value)
    conns = ET.SubElement(sysel, _q("ssd", "Connections"))
    for cn in system.connections:
        ET.SubElement(conns, _q("ssd", "Connection"), {
            "startElement": cn.start_element, "startConnector": cn.start_connector,
            "endElement": cn.end_element, "endConnector": cn.end_connector})
    exp = ET.SubElement(root, _q("ssd", "DefaultExperiment"), {"startTime": repr(float(system.start_time)),
                                                               "stopTime": repr(float(system.stop_time))})
    ann = ET.SubElement(ET.SubElement(exp, _q("ssd", "Annotations")), _q("ssc", "Annotation"),
                        {"type": OSP_ANNOTATION})
    algorithm = ET.SubElement(ann, _q("osp", "Algorithm"))
    ET.SubElement(algorithm, _q("osp", "FixedStepAlgorithm"), {"baseStepSize": repr(float(system.step_size))})
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def _parse_value(el):
    for kind in ("Real", "Integer", "Boolean"):
        v = el.find(f"ssv:{kind}", NS)
        if v is not None:
            text = v.get("value")
            if kind == "Real":
                return float(text)
            if kind == "Integer":
                return int(text)
            return text.strip().lower() in ("true", "1")
    raise ValueError(f"parameter {el.get('name')!r}: no Real, Integer or Boolean value")


def read_ssd(xml: bytes) -> SystemDescription:
    """The system of a ``SystemStructure.ssd`` written by :func:`write_ssd` (or shaped like it)."""
    root = ET.fromstring(xml)
    sysel = root.find("ssd:System", NS)
    if sysel is None:
        raise ValueError("SystemStructure.ssd: no ssd:System")
    comps = []
    for c in sysel.findall("ssd:Elements/ssd:Component", NS):
        conn = {}
        for cn in c.findall("ssd:Connectors/ssd:Connector", NS):
            real = cn.find("ssc:Real", NS)
            conn[cn.get("name")] = (cn.get("kind"), real.get("unit") if real is not None else None)
        params = {}
        for p in c.findall("ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterValues/"
                           "ssv:ParameterSet/ssv:Parameters/ssv:Parameter", NS):
            params[p.get("name")] = _parse_value(p)
        comps.append(Component(c.get("name"), c.get("source"), conn, params))
    connections = [Connection(x.get("startElement"), x.get("startConnector"), x.get("endElement"),
                              x.get("endConnector")) for x in sysel.findall("ssd:Connections/ssd:Connection", NS)]
    step = math.nan
    exp = root.find("ssd:DefaultExperiment", NS)
    fsa = None if exp is None else exp.find("ssd:Annotations/ssc:Annotation/osp:Algorithm/osp:FixedStepAlgorithm", NS)
    if fsa is not None:
        step = float(fsa.get("baseStepSize"))
    start = float(exp.get("startTime", 0.0)) if exp is not None else 0.0
    stop = float(exp.get("stopTime", math.nan)) if exp is not None else math.nan
    return SystemDescription(sysel.get("name"), comps, connections, start, stop, step)
