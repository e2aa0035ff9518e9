"""Reference results of the native FMUs (FMI-LS-REF): the manifest and ``<Model>_out.csv``, computed by the library.

Each native FMU ships, as the FMI project's Reference-FMUs do,
``extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`` (one ``<Related>`` file of role
``result``) and ``<Model>_out.csv``: the outputs over the FMU's default experiment, a header
``time,<output>,...`` and one row per recorded communication point (every
:data:`RECORD_INTERVAL` seconds, or every step if the default experiment's step is longer),
written with the shortest digits that read back to the same double.

The values come from the library at build time, not from the FMU's binary:

* HammerBitRock and Drillstring: the library's own slave classes (:mod:`hammerbit.model.slave`,
  :mod:`hammerbit.model.string_slave`, the Python flavour of the model) run in this process over
  the default experiment's communication points;
* DrillingSystem: the library's :class:`~hammerbit.model.stepping.Stepper` on the build's
  subsystem (the arrays of :func:`hammerbit.fmu.build_system.system_data`), advanced to the same
  communication points; its columns are the states it integrates (bit and hammer position,
  hammer velocity).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from xml.etree import ElementTree as ET

import numpy as np

__all__ = ["LS_NAME", "LS_VERSION", "FOLDER", "RECORD_INTERVAL", "Experiment", "ReferenceResults",
           "default_experiment", "slave_results", "system_results"]

#: the layered standard's name and the version the Reference-FMUs declare
LS_NAME = "org.fmi-standard.fmi-ls-ref"
LS_VERSION = "1.0.0-alpha.1"
#: where its files go in the FMU
FOLDER = f"extra/{LS_NAME}"
#: seconds between recorded rows (the FMU steps at the default experiment's step size)
RECORD_INTERVAL = 0.01
#: decimals of the time column
TIME_DIGITS = 12
_FMI_LS = "http://fmi-standard.org/fmi-ls-manifest"


@dataclass(frozen=True)
class Experiment:
    """The default experiment: start and stop time [s], communication step [s], tolerance (or None)."""

    start: float
    stop: float
    step: float
    tolerance: float | None = None

    @property
    def steps(self) -> int:
        """Communication steps from start to stop."""
        return round((self.stop - self.start) / self.step)

    @property
    def every(self) -> int:
        """Steps between recorded rows."""
        return max(1, round(RECORD_INTERVAL / self.step))


def default_experiment(md_xml: bytes) -> Experiment:
    """The ``<DefaultExperiment>`` of an FMI 2.0 or 3.0 model description."""
    el = ET.fromstring(md_xml).find("DefaultExperiment")
    if el is None or el.get("stopTime") is None or el.get("stepSize") is None:
        raise ValueError("the model description has no DefaultExperiment with stopTime and stepSize")
    tol = el.get("tolerance")
    return Experiment(float(el.get("startTime", "0")), float(el.get("stopTime")), float(el.get("stepSize")),
                      None if tol is None else float(tol))


@dataclass(frozen=True)
class ReferenceResults:
    """Recorded outputs of one FMU: ``time`` [s] and ``columns`` {output name: values}."""

    model_name: str
    time: np.ndarray
    columns: dict
    description: str

    def csv(self) -> bytes:
        """``<Model>_out.csv``: ``time,name,...``; reals in shortest round-trip form, booleans
        ``true``/``false``, integers as integers."""
        def cell(v):
            if isinstance(v, (bool, np.bool_)):
                return "true" if v else "false"
            if isinstance(v, (int, np.integer)):
                return str(int(v))
            v = float(v)
            return repr(v) if math.isfinite(v) else {math.inf: "inf", -math.inf: "-inf"}.get(v, "nan")
        names = list(self.columns)
        lines = [",".join(["time", *names])]
        for i, t in enumerate(self.time):
            # the communication point as the master names it (start + n step, without its last-bit noise)
            lines.append(",".join([cell(round(float(t), TIME_DIGITS)), *(cell(self.columns[n][i]) for n in names)]))
        return ("\n".join(lines) + "\n").encode("ascii")

    def manifest(self) -> bytes:
        """``fmi-ls-manifest.xml``: the CSV as a related file of role ``result``."""
        ET.register_namespace("fmi-ls", _FMI_LS)
        root = ET.Element("fmiReferences", {f"{{{_FMI_LS}}}fmi-ls-name": LS_NAME,
                                            f"{{{_FMI_LS}}}fmi-ls-version": LS_VERSION})
        ET.SubElement(root, "Related", {"type": "text/csv", "source": self.csv_name, "role": "result",
                                        "description": self.description})
        ET.indent(root, space="    ")
        return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8") + b"\n"

    @property
    def csv_name(self) -> str:
        return f"{self.model_name}_out.csv"

    def files(self) -> dict:
        """{path in the FMU: bytes} of the manifest and the CSV."""
        return {f"{FOLDER}/fmi-ls-manifest.xml": self.manifest(), f"{FOLDER}/{self.csv_name}": self.csv()}


def _description(exp: Experiment, made_by: str) -> str:
    return (f"Output of the default experiment ({exp.start:g} to {exp.stop:g} s, communication step "
            f"{exp.step:g} s), every {exp.every * exp.step:g} s; computed by {made_by} at build time")


def slave_results(slave_class, model_name: str, md_xml: bytes, resources) -> ReferenceResults:
    """The outputs of ``md_xml`` over its default experiment from the library's slave class
    ``slave_class`` (a pythonfmu ``Fmi2Slave`` of :mod:`hammerbit.model`) run in this process with
    ``resources`` as its resources directory."""
    exp = default_experiment(md_xml)
    slave = slave_class(instance_name="reference", resources=str(resources))
    # by name: the slave's enumeration is that of the pythonfmu it was imported with, which need
    # not be the one ``import pythonfmu`` gives now (an FMU run in this process brings its own copy)
    outputs = [v for v in slave.vars.values() if v.causality.name == "output"]
    if not outputs:
        raise RuntimeError(f"the library's {model_name} declares no outputs: no reference results to record")
    slave.setup_experiment(exp.start, exp.stop, exp.tolerance)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    rows, times = [[v.getter() for v in outputs]], [exp.start]
    for k in range(exp.steps):
        t = exp.start + k * exp.step
        if slave.do_step(t, exp.step) is False:
            raise RuntimeError(f"the library's {model_name} failed at t = {t!r} s of its default experiment")
        if (k + 1) % exp.every == 0:
            rows.append([v.getter() for v in outputs])
            times.append(exp.start + (k + 1) * exp.step)
    slave.terminate()
    columns = {v.name: [r[i] for r in rows] for i, v in enumerate(outputs)}
    return ReferenceResults(model_name, np.array(times), columns,
                            _description(exp, f"the library's {slave_class.__module__}.{slave_class.__name__}"))


def system_results(model_name: str, data: dict, md_xml: bytes) -> ReferenceResults:
    """Bit position, hammer position and hammer velocity of DrillingSystem.fmu over its default
    experiment from the library's Stepper on the build's subsystem (``data``: its arrays and, as
    ``stepper``, the Stepper they were taken from, at its start; it is advanced)."""
    from hammerbit.model import kernel_layouts as KL
    from hammerbit.model.stepping import Stepper
    exp = default_experiment(md_xml)
    st = data["stepper"]
    if not isinstance(st, Stepper) or st.time != 0.0:
        raise ValueError("data['stepper'] is not the build's Stepper at its start")
    x0, om = data["x0"], data["Om"]
    rows, times = [], []

    def record(t):
        times.append(t)
        rows.append((st.y[KL.X_BIT] * x0, st.y[KL.X_HAMMER] * x0, st.y[KL.V_HAMMER] * x0 * om))
    record(exp.start)
    for k in range(exp.steps):
        t = exp.start + (k + 1) * exp.step
        # what the FMU's step starts with: the link force's integral and the step's lowest drive
        # (its mean WOB and tension flag) restarted; the integral is a state of the error control
        st.y[4 + data["iq"]] = 0.0
        st.fstate[KL.F_DRIVE_MIN] = np.inf
        if st.advance(t * om) != "done":
            raise RuntimeError(f"the library's Stepper stopped at t = {st.time / om!r} s of the default experiment")
        if (k + 1) % exp.every == 0:
            record(t)
    a = np.array(rows)
    columns = {"bit_position": a[:, 0], "hammer_position": a[:, 1], "hammer_velocity": a[:, 2]}
    return ReferenceResults(model_name, np.array(times), columns,
                            _description(exp, "the library's Stepper on the build's subsystem"))
