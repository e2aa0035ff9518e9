"""Every FMU agrees with its table in the one description: the shipped modelDescription.xml, the generated C header and the Python slave.

Oracles: fmpy's reader of the shipped ``modelDescription.xml`` (not the build's own parser), the
text of the generated headers (their ``#define *_VR_<name> <vr>u``), the variables the pythonfmu
slaves register, and the FMI rules the table states (a variable's value reference is its index
in its FMU's table; FMI 2 types from the FMI 3 ones; ranges of the library's validation).
"""
from __future__ import annotations

import re
import zipfile

import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402

from hammerbit.model import fmu_description as D  # noqa: E402

#: fixture -> (its FMU's table, FMI version)
BUILDS = {
    "built_fmu": ("hammer", 2), "built_native_fmu": ("hammer", 2), "built_native_fmu3": ("hammer", 3),
    "built_string_fmu": ("string", 2), "built_native_string_fmu": ("string", 2),
    "built_native_string_fmu3": ("string", 3), "built_field_system_fmu": ("system", 2),
    "built_field_system_fmu3": ("system", 3),
}
TABLES = {"hammer": D.HAMMER_VARIABLES, "string": D.STRING_VARIABLES, "system": D.SYSTEM_VARIABLES}
#: the type fmpy reports for an FMI 2.0 variable of each FMI 3 type
FMPY_FMI2_TYPE = {"Float64": "Real", "Int32": "Integer", "UInt64": "Integer", "Boolean": "Boolean"}
_DEFINE = re.compile(r"^#define (?:HB|HS|HSYS)_VR_(\w+) (\d+)u$", re.M)


def _c_name(name: str) -> str:
    return "".join(c if c.isalnum() or c == "_" else "_" for c in name).rstrip("_")


def _header_vrs(text: str) -> dict:
    """``{C name: value reference}`` of a generated header's value-reference macros."""
    return {name: int(vr) for name, vr in _DEFINE.findall(text)}


def _shipped(fmu) -> dict:
    return {v.name: v for v in read_model_description(str(fmu), validate=False).modelVariables}


def _float(x):
    return None if x is None else float(x)


@pytest.mark.parametrize("built", sorted(BUILDS), indirect=True)
def test_the_shipped_description_declares_its_table(built, request):
    """Names, value references, causalities, types, units and ranges of every shipped FMU are its
    table's; nothing else has a value reference in the table's range."""
    which, version = BUILDS[request.node.callspec.params["built"]]
    table, fmu = TABLES[which], built
    shipped = _shipped(fmu)
    for vr, var in enumerate(table):
        v = shipped[var.name]
        assert (v.valueReference, v.causality) == (vr, var.causality), var.name
        assert v.type == (var.type if version == 3 else FMPY_FMI2_TYPE[var.type]), var.name
        assert (v.unit or "") == var.unit, var.name
        for bound in ("min", "max"):
            if getattr(var, bound) is not None and var.name not in D.SYSTEM_INPUT_TOPS:
                assert _float(getattr(v, bound)) == float(getattr(var, bound)), (var.name, bound)
    names = {var.name for var in table}
    assert [n for n, v in shipped.items() if v.valueReference < len(table) and n not in names] == []
    if which == "hammer":
        _check_hammer_ranges(shipped)


def _check_hammer_ranges(shipped: dict) -> None:
    """HammerBitRock's build ranges: each parameter's inside the library's range, the inputs'
    1000 static friction thresholds of the start values."""
    from hammerbit.model.fmu_variables import variable_range
    for var in D.PARAMETERS:
        v, rng = shipped[var.name], variable_range(var.name)
        assert rng.lo <= float(v.min) <= float(v.start) <= float(v.max) <= rng.hi, var.name
    f0 = float(shipped["mu_static"].start) * float(shipped["normal_force"].start)
    for var in D.INPUTS:
        v = shipped[var.name]
        assert float(v.max) == pytest.approx(1000.0 * f0, rel=1e-15) and float(v.min) == -float(v.max)


def test_the_native_headers_give_the_shipped_value_references(built_native_fmu, built_native_string_fmu,
                                                             built_field_system_fmu):
    """The value references the C models are compiled with (the headers, generated from the
    tables) are those of the shipped descriptions, every one of them."""
    from hammerbit.fmu.build_string import string_build
    from hammerbit.fmu.native_build import native_header
    from hammerbit.fmu.native_kernels import layout
    from hammerbit.fmu.native_string import DEFAULT_STEPS, string_header
    headers = ((built_native_fmu, native_header({}, layout()), D.HAMMER_VARIABLES),
               (built_native_string_fmu, string_header(string_build("lab"), DEFAULT_STEPS), D.STRING_VARIABLES),
               (built_field_system_fmu, _system_header(), D.SYSTEM_VARIABLES))
    for fmu, text, table in headers:
        shipped = {_c_name(name): v.valueReference for name, v in _shipped(fmu).items()}
        vrs = _header_vrs(text)
        assert {n: shipped.get(n) for n in vrs} == vrs, fmu.name
        # every variable of the table has its macro (HammerBitRock adds der(<state>) after it)
        assert {_c_name(v.name) for v in table} <= set(vrs), fmu.name


def _system_header() -> str:
    from conftest import field_system
    from hammerbit.fmu.build_system import system_data, system_header
    return system_header(system_data(*field_system()))


@pytest.mark.parametrize("which", ["hammer", "string"])
def test_the_python_slaves_register_their_table_in_order(which, built_string_fmu, tmp_path):
    """The pythonfmu slaves' variables, by value reference: the table's names, causalities,
    variabilities and types."""
    from pythonfmu import Boolean, Integer, Real
    from hammerbit.model.slave import HammerBitRock
    from hammerbit.model.string_slave import Drillstring
    if which == "string":
        with zipfile.ZipFile(built_string_fmu) as zf:
            zf.extractall(tmp_path, [n for n in zf.namelist() if n.startswith("resources/")])
        slave = Drillstring(instance_name="t", resources=str(tmp_path / "resources"))
    else:
        slave = HammerBitRock(instance_name="t", resources=str(tmp_path))
    kind = {"Float64": Real, "Int32": Integer, "UInt64": Integer, "Boolean": Boolean}
    table = TABLES[which]
    assert sorted(slave.vars) == list(range(len(table)))
    for vr, var in enumerate(table):
        got = slave.vars[vr]
        assert (got.name, got.causality.name) == (var.name, var.causality), vr
        assert isinstance(got, kind[var.type]), var.name
        if var.variability:
            assert got.variability.name == var.variability, var.name


def test_a_build_refuses_a_description_that_is_not_its_tables(tmp_path):
    """The build's check names each difference: two value references swapped, a causality
    changed, a variable missing, an extra one in the table's range; the slave's own passes."""
    import xml.etree.ElementTree as ET
    from hammerbit.fmu.table_check import DescriptionMismatchError, check_description
    from hammerbit.model.slave import HammerBitRock
    root = HammerBitRock(instance_name="t", resources=str(tmp_path)).to_xml()
    xml = ET.tostring(root)
    check_description(xml, D.HAMMER_VARIABLES, "HammerBitRock.fmu")

    def refused(edit, *words):
        doc = ET.fromstring(xml)
        edit({sv.get("name"): sv for sv in doc.find("ModelVariables")}, doc)
        with pytest.raises(DescriptionMismatchError) as e:
            check_description(ET.tostring(doc), D.HAMMER_VARIABLES, "HammerBitRock.fmu")
        for w in words:
            assert w in str(e.value)

    def swap(v, _):
        a, b = v["hammer_position"], v["bit_position"]
        va, vb = a.get("valueReference"), b.get("valueReference")
        a.set("valueReference", vb)
        b.set("valueReference", va)
    refused(swap, "hammer_position: the table gives value reference 21", "declares 23",
            "bit_position: the table gives value reference 23")
    refused(lambda v, _: v["gap"].set("causality", "input"), "gap:", "declares 13, input, Real")
    refused(lambda v, doc: doc.find("ModelVariables").remove(v["regime"]), "regime:", "has no such variable")
    refused(lambda v, _: v["slip_count"].set("name", "slips"), "slip_count:", "slips: value reference 33")
