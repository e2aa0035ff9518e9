"""Reference results (FMI-LS-REF) of the native FMUs: their layout and their agreement with fmpy.

Oracles: the layout of the FMI project's Reference-FMUs (``extra/org.fmi-standard.fmi-ls-ref/``
with ``fmi-ls-manifest.xml`` naming ``<Model>_out.csv`` of role ``result``; the CSV's header
``time,<variable>,...``); the FMU itself run in fmpy over its default experiment
(tests/reference_check.py: how close, and why).  The FMI 3.0 builds are checked in
tests/test_fmi3_native.py, test_fmi3_string.py and test_fmi3_system.py on their own builds.
"""
from __future__ import annotations

import csv
import io
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from reference_check import FMI_LS, compare_with_fmpy, shipped

fmpy = pytest.importorskip("fmpy")


def test_files_in_the_reference_fmus_layout():
    from hammerbit.fmu.reference_results import ReferenceResults
    r = ReferenceResults("Model", np.array([0.0, 0.1 + 0.2, 0.5]),
                         {"h": [1.0, 0.1, -2.5e-300], "on": [True, False, np.bool_(True)], "n": [0, 3, np.int64(7)]},
                         "Output of the default experiment")
    files = r.files()
    assert set(files) == {"extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml",
                          "extra/org.fmi-standard.fmi-ls-ref/Model_out.csv"}
    rows = list(csv.reader(io.StringIO(files["extra/org.fmi-standard.fmi-ls-ref/Model_out.csv"].decode())))
    assert rows[0] == ["time", "h", "on", "n"]
    assert rows[2] == ["0.3", "0.1", "false", "3"]                 # time as the master names it
    assert float(rows[3][1]) == -2.5e-300 and rows[3][2:] == ["true", "7"]   # round-trip digits
    root = ET.fromstring(files["extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml"])
    assert root.tag == "fmiReferences"
    assert (root.get(f"{FMI_LS}fmi-ls-name"), root.get(f"{FMI_LS}fmi-ls-version")) == \
        ("org.fmi-standard.fmi-ls-ref", "1.0.0-alpha.1")
    (rel,) = root
    assert (rel.tag, rel.get("type"), rel.get("source"), rel.get("role")) == \
        ("Related", "text/csv", "Model_out.csv", "result")


def test_native_hammer_reference_results_equal_its_run_in_fmpy(built_native_fmu):
    _, header, rows = shipped(built_native_fmu)
    assert {"hammer_position", "bit_position", "slip_count", "in_contact"} <= set(header)
    assert float(rows[-1][header.index("bit_position")]) > 0.0     # the default scene drills
    compare_with_fmpy(built_native_fmu)


def test_native_string_reference_results_equal_its_run_in_fmpy(built_native_string_fmu):
    _, header, _ = shipped(built_native_string_fmu)
    assert {"interface_force", "hook_load"} <= set(header)
    compare_with_fmpy(built_native_string_fmu)


def test_a_wrong_reference_is_caught(built_native_fmu, tmp_path):
    """The check can fail: the shipped CSV with one value off by 1e-9 of its column is refused."""
    import zipfile
    bad = tmp_path / "HammerBitRock.fmu"
    with zipfile.ZipFile(built_native_fmu) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename.endswith("_out.csv"):
                lines = data.decode().splitlines()
                header = lines[0].split(",")
                j = header.index("bit_position")
                cells = lines[-1].split(",")
                cells[j] = repr(float(cells[j]) * (1.0 + 1e-9))
                lines[-1] = ",".join(cells)
                data = ("\n".join(lines) + "\n").encode()
            dst.writestr(item, data)
    with pytest.raises(AssertionError, match="bit_position"):
        compare_with_fmpy(bad)


def test_the_slaves_outputs_are_recorded_whichever_pythonfmu_is_imported_now(monkeypatch, tmp_path):
    """A pythonfmu FMU run in this process brings its own copy of pythonfmu; once a build has
    forgotten it again, the library's slave (imported with the copy) and ``import pythonfmu``
    hold different enumerations.  The reference results still record every output of the slave
    (a second copy of the package stands in for the FMU's)."""
    import importlib.util
    import os
    import sys

    import pythonfmu
    from hammerbit.fmu.reference_results import slave_results
    from hammerbit.model.slave import HammerBitRock
    for name in [n for n in sys.modules if n == "pythonfmu" or n.startswith("pythonfmu.")]:
        monkeypatch.delitem(sys.modules, name)
    spec = importlib.util.spec_from_file_location(
        "pythonfmu", pythonfmu.__file__, submodule_search_locations=[os.path.dirname(pythonfmu.__file__)])
    copy = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "pythonfmu", copy)
    spec.loader.exec_module(copy)
    assert copy.Fmi2Causality is not pythonfmu.Fmi2Causality
    md = (b'<fmiModelDescription><DefaultExperiment startTime="0" stopTime="0.05" stepSize="0.001"/>'
          b'</fmiModelDescription>')
    r = slave_results(HammerBitRock, "HammerBitRock", md, tmp_path)
    declared = [v.name for v in HammerBitRock(instance_name="t", resources=str(tmp_path)).vars.values()
                if v.causality.name == "output"]
    assert declared and list(r.columns) == declared
    assert np.allclose(r.time, np.linspace(0.0, 0.05, 6), rtol=0, atol=1e-15)        # a row every 0.01 s
