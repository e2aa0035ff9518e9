"""Operating-point studies over many scenes, on one executor.

* :mod:`~hammerbit.studies.executor` -- the study engine (in process or Dask);
* :mod:`~hammerbit.studies.bifurcation` -- bifurcation diagrams, penetration sweeps;
* :mod:`~hammerbit.studies.map` -- regime maps (period-n, ROP, flags) over 1-3 parameters;
* :mod:`~hammerbit.studies.optimize` -- the ROP optimum under the drilling constraints;
* :mod:`~hammerbit.studies.sweep` -- frequency sweeps of the co-simulation.

Submodules are imported on first use (Dask and xarray load only when needed).
"""
from __future__ import annotations

import importlib

__all__ = ["executor", "bifurcation", "map", "optimize", "sweep", "plots"]


def __getattr__(name):
    if name in __all__:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(name)
