"""Test helper: an FMU's shipped reference results (FMI-LS-REF) against its run in fmpy.

The check reads ``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`` and the CSV it names,
runs the FMU's default experiment in fmpy (Co-Simulation, the default experiment's step as the
communication step) and compares every column at the CSV's times.

The tolerance: the CSV's reals are written with round-trip digits, so the file adds no error;
the library made them by running the same model (the same kernels, the same solver tolerance)
over the same communication points, so the FMU's binary differs only by the rounding of
differently compiled code (numba's JIT in the library, the ahead-of-time object in the binary),
amplified by the dynamics over the run: measured at most 1.3e-13 of a column's largest magnitude
(HammerBitRock, 20 s of stick-slip).  :data:`REL` allows a hundred times that, relative to the
largest magnitude of the columns of the same unit (a column at rounding level, as a force
difference at rest, against the forces); integer and Boolean columns (counters, modes) must be
equal.
"""
from __future__ import annotations

import csv
import io
import zipfile
from xml.etree import ElementTree as ET

import numpy as np

FOLDER = "extra/org.fmi-standard.fmi-ls-ref"
FMI_LS = "{http://fmi-standard.org/fmi-ls-manifest}"
#: agreement of the FMU's run with the library's reference results (see the module docstring)
REL = 1e-11


def shipped(fmu) -> tuple:
    """(manifest root, CSV header, CSV rows as text) of the FMU's reference results."""
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read(f"{FOLDER}/fmi-ls-manifest.xml"))
        assert root.tag == "fmiReferences"
        assert root.get(f"{FMI_LS}fmi-ls-name") == "org.fmi-standard.fmi-ls-ref"
        (rel,) = root.findall("Related")
        assert rel.get("type") == "text/csv" and rel.get("role") == "result"
        text = zf.read(f"{FOLDER}/{rel.get('source')}").decode("ascii")
    rows = list(csv.reader(io.StringIO(text)))
    return root, rows[0], rows[1:]


def _number(cell: str) -> float:
    return {"true": 1.0, "false": 0.0}.get(cell, None) if cell in ("true", "false") else float(cell)


def compare_with_fmpy(fmu, rel: float = REL) -> dict:
    """Run ``fmu``'s default experiment in fmpy and compare with its shipped CSV; returns
    ``{column: largest difference relative to its unit's magnitude}`` (asserted <= ``rel``)."""
    from fmpy import read_model_description, simulate_fmu
    md = read_model_description(str(fmu))
    root, header, rows = shipped(fmu)
    assert header[0] == "time" and len(header) > 1 and len(rows) > 1
    assert root.find("Related").get("source") == f"{md.modelName}_out.csv"
    types = {v.name: v.type for v in md.modelVariables}
    units = {v.name: v.unit for v in md.modelVariables}
    exp = md.defaultExperiment
    ref = np.array([[_number(c) for c in r] for r in rows])
    res = simulate_fmu(str(fmu), start_time=float(exp.startTime), stop_time=float(exp.stopTime),
                       output_interval=float(exp.stepSize), output=header[1:])
    idx = np.searchsorted(res["time"], ref[:, 0] - 1e-9)
    assert np.allclose(res["time"][idx], ref[:, 0], rtol=0, atol=1e-9), "the CSV's times are not communication points"
    # a column's scale: the largest magnitude among the columns of its unit (a force that stays
    # at rounding level, held_force_change at rest, is measured against the forces)
    magnitude = {}
    for j, name in enumerate(header[1:], start=1):
        magnitude[units[name]] = max(magnitude.get(units[name], 0.0), float(np.abs(ref[:, j]).max()))
    worst = {}
    for j, name in enumerate(header[1:], start=1):
        got, want = res[name][idx].astype(float), ref[:, j]
        if types[name] in ("Real", "Float64"):
            scale = max(magnitude[units[name]], 1e-300)
            worst[name] = float(np.abs(got - want).max()) / scale
            assert worst[name] <= rel, f"{md.modelName} {name}: off by {worst[name]:.3g} of its magnitude"
        else:
            assert np.array_equal(got, want), f"{md.modelName} {name}: differs"
    return worst
