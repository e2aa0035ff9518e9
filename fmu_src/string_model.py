"""The arrays of a built string side, as the Drillstring FMU carries them in its resources.

``hammerbit fmu build-string`` writes them (``string_model.npz``) from the
library's string side at the damping ratio of the string's file; the FMU and
``hammerbit cosim --ssp`` both turn them into the exact step with
:func:`string_matrices`.  The string's own damping enters the state matrix
affinely (``C = C_viscous + zeta C_1``), so the matrix at another damping
ratio is ``A1 + (zeta - zeta_build) dA1`` (exactly ``A1`` at the build's ratio).
"""
from __future__ import annotations

import json
import os

import numpy as np

__all__ = ["MODEL_FILE", "INFO_FILE", "ARRAYS", "SCALARS", "load_model", "save_model", "string_matrices"]

#: the arrays file in the FMU's resources directory
MODEL_FILE = "string_model.npz"
#: the description (geometry, build options, ranges) in the FMU's resources directory
INFO_FILE = "string_info.json"
#: every array of a model: the state matrix at the build's damping ratio and its derivative in
#: the damping ratio, the input matrix of the hammer motion, the interface force row, the output
#: rows (string bottom displacement, velocity, top tension), the scalars
ARRAYS = ("A1", "dA1", "E", "frow", "rows3", "scalars")
#: names of the entries of ``scalars``
SCALARS = ("interface_stiffness", "interface_damping", "damping_ratio", "wob", "hook_load", "buoyed_weight")


def save_model(path, arrays: dict) -> None:
    """Write the arrays (``ARRAYS``; ``scalars`` as a dict of :data:`SCALARS`)."""
    out = {k: np.asarray(arrays[k], dtype=float) for k in ARRAYS if k != "scalars"}
    out["scalars"] = np.array([float(arrays["scalars"][k]) for k in SCALARS])
    np.savez(path, **out)


def load_model(resources: str) -> tuple:
    """``(arrays, info)`` from an FMU's resources directory."""
    with np.load(os.path.join(resources, MODEL_FILE)) as z:
        arrays = {k: np.array(z[k]) for k in ARRAYS}
    arrays["scalars"] = dict(zip(SCALARS, (float(v) for v in arrays["scalars"])))
    with open(os.path.join(resources, INFO_FILE), encoding="utf-8") as fh:
        info = json.load(fh)
    return arrays, info


def string_matrices(arrays: dict, damping_ratio: float) -> tuple:
    """``(A1, E, frow, rows3)`` at ``damping_ratio``."""
    dz = float(damping_ratio) - arrays["scalars"]["damping_ratio"]
    A1 = arrays["A1"] + dz * arrays["dA1"]
    return A1, arrays["E"], arrays["frow"], arrays["rows3"]
