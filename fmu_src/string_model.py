"""The arrays of a built string side, as the Drillstring FMU carries them in its resources.

``hammerbit fmu build-string`` writes them (``string_model.npz``) from the
library's string side; the FMU and ``hammerbit cosim --ssp`` both turn them
into the exact step with :func:`string_matrices`.

Two *forms*: ``fixed`` (the fixed hook; a constant feed uses it too, its block
motion being an exact polynomial input of the exchange) and ``auto`` (the
auto-driller: the string side augmented by the block's position and the
controller's integral).  Each holds ``A1, E, frow`` and the output rows
(string bottom displacement, velocity, top tension, top position, top
velocity) at the build's parameters, and the derivatives of ``A1``, ``frow``
and the rows in the parameters they depend on: the damping ratio (the
string's damping enters affinely, ``C = C_viscous + zeta C_1``) and the
auto-driller's gains (a linear feedback, affine in each gain).  So the
matrices at other parameters are ``X + sum (p - p_build) dX/dp``, exactly ``X``
at the build's values.
"""
from __future__ import annotations

import json
import os

import numpy as np

from .fmu_description import TOP_CONDITIONS as _TOPS

__all__ = ["MODEL_FILE", "INFO_FILE", "FORMS", "OUTPUT_ROWS", "PARAMETERS", "MATRICES", "TOP_CONDITIONS", "form_of",
           "load_model", "save_model", "string_matrices"]

#: the arrays file in the FMU's resources directory
MODEL_FILE = "string_model.npz"
#: the description (geometry, build options, parameter values) in the FMU's resources directory
INFO_FILE = "string_info.json"
#: the forms of the string side
FORMS = ("fixed", "auto")
#: the output rows of a form's ``rows`` matrix, in order (the FMUs read them by these names)
OUTPUT_ROWS = ("bottom_position", "bottom_velocity", "hook_tension", "top_position", "top_velocity")
#: the parameters the matrices depend on (affinely)
PARAMETERS = ("damping_ratio", "proportional_gain", "integral_gain")
#: the matrices of a form that depend on the parameters (``E`` does not)
MATRICES = ("A1", "frow", "rows")
#: the top conditions' names in the order of the FMU's ``top_condition`` parameter (0, 1, 2, ...)
TOP_CONDITIONS = tuple(t.name for t in _TOPS)


def form_of(top_condition: int) -> str:
    """The form a top condition (by its code) steps with (:data:`fmu_description.TOP_CONDITIONS`)."""
    return _TOPS[int(top_condition)].form


def save_model(path, forms: dict, build_values: dict) -> None:
    """Write ``forms`` (``{form: {"A1", "E", "frow", "rows", "d": {param: {matrix: dX}}}}``) and
    the parameters' build values."""
    out = {"build_values": np.array([float(build_values[p]) for p in PARAMETERS])}
    for name, f in forms.items():
        for key in ("A1", "E", "frow", "rows"):
            out[f"{name}.{key}"] = np.asarray(f[key], dtype=float)
        for param, ds in f.get("d", {}).items():
            for key, value in ds.items():
                out[f"{name}.d{key}.{param}"] = np.asarray(value, dtype=float)
    np.savez(path, **out)


def load_model(resources: str) -> tuple:
    """``(arrays, info)`` from an FMU's resources directory: ``arrays`` as :func:`save_model` took it
    (``{"forms": ..., "build_values": ...}``)."""
    forms = {}
    with np.load(os.path.join(resources, MODEL_FILE)) as z:
        build_values = dict(zip(PARAMETERS, (float(v) for v in z["build_values"])))
        for key in z.files:
            if key == "build_values":
                continue
            name, rest = key.split(".", 1)
            f = forms.setdefault(name, {"d": {}})
            if rest.startswith("d") and "." in rest:
                matrix, param = rest[1:].split(".", 1)
                f["d"].setdefault(param, {})[matrix] = np.array(z[key])
            else:
                f[rest] = np.array(z[key])
    with open(os.path.join(resources, INFO_FILE), encoding="utf-8") as fh:
        info = json.load(fh)
    return {"forms": forms, "build_values": build_values}, info


def string_matrices(arrays: dict, form: str, values: dict) -> tuple:
    """``(A1, E, frow, rows)`` of ``form`` at the parameter ``values`` (missing ones: the build's)."""
    if form not in arrays["forms"]:
        raise ValueError(f"the string has no '{form}' form (built without it)")
    f = arrays["forms"][form]
    out = {}
    for param in PARAMETERS:
        value = float(values.get(param, arrays["build_values"][param]))
        if value != arrays["build_values"][param] and param not in f["d"] and (form == "auto" or
                                                                              param == "damping_ratio"):
            raise ValueError(f"{param} = {value!r}: these arrays hold the string's '{form}' form at its build "
                             f"value {arrays['build_values'][param]!r} only (a native Drillstring FMU's)")
    for key in MATRICES:
        x = f[key]
        for param, ds in f["d"].items():
            if key in ds:
                dp = float(values.get(param, arrays["build_values"][param])) - arrays["build_values"][param]
                x = x + dp * ds[key]
        out[key] = x
    return out["A1"], f["E"], out["frow"], out["rows"]
