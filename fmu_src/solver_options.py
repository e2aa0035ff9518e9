"""The options of the hybrid solver: the method (a Runge–Kutta tableau), tolerances and caps."""
from __future__ import annotations

import math
from dataclasses import dataclass

from . import tableaux as T
from .validation import ParameterError, check

__all__ = ["METHODS", "SolverOptions", "method_tableau"]

METHODS = ("adaptive", "dp54", "rk4")


def method_tableau(name: str):
    """Tableau arrays of a method name: (A, B, C, E, E3, W, ns, err_kind, err_exp) (``tableaux.METHODS``)."""
    key = "dop853" if name == "adaptive" else name
    if key not in T.METHODS:
        raise ParameterError("method", name, "one of " + ", ".join(METHODS))
    return T.METHODS[key]


@dataclass(frozen=True)
class SolverOptions:
    """Options of the hybrid integrators.

    Attributes
    ----------
    method : {'adaptive', 'dp54', 'rk4'}
        ``adaptive``: DOP853 with 7th-order dense output, events located on the
        dense output to a few ulp.  ``dp54``: Dormand–Prince 5(4), same event
        logic.  ``rk4``: the paper's fixed-step RK4 with bisection.
    rtol, atol : float
        Tolerances of the adaptive methods [-].
    steps_per_period : int
        rk4: N in dtau = 2 pi / (N eta) (the paper: 1000).
    bisection_tol : float
        rk4: event-time tolerance of the bisection in tau (the paper: 1e-6).
    max_events_per_period : int
        Events allowed in one forcing period before :class:`EventStormError`.
    max_step : float
        Largest step in tau (inf: no limit).
    graze_tol : float
        A grazing extremum of an indicator counts as an event above this value.
    max_steps : int
        Accepted steps allowed in one call (0: no limit).
    max_steps_per_period : int
        Accepted steps allowed in one forcing period before :class:`StepStormError`
        (0: no limit): a crawling solver fails loudly instead of hanging.
    """

    method: str = "adaptive"
    rtol: float = 1e-8
    atol: float = 1e-10
    steps_per_period: int = 1000
    bisection_tol: float = 1e-6
    max_events_per_period: int = 2000
    max_step: float = math.inf
    graze_tol: float = 1e-13
    max_steps: int = 0
    max_steps_per_period: int = 100_000

    def __post_init__(self):
        if self.method not in METHODS:
            raise ParameterError("method", self.method, "one of " + ", ".join(METHODS))
        check("solver.rtol", self.rtol, label="rtol")
        check("solver.atol", self.atol, label="atol")
        check("solver.steps_per_period", self.steps_per_period, label="steps_per_period")
        check("solver.bisection_tol", self.bisection_tol, label="bisection_tol")
        check("solver.max_events_per_period", self.max_events_per_period, label="max_events_per_period")
        check("solver.max_step", self.max_step, label="max_step")
        check("solver.graze_tol", self.graze_tol, label="graze_tol")
        check("solver.max_steps", self.max_steps, label="max_steps")
        check("solver.max_steps_per_period", self.max_steps_per_period, label="max_steps_per_period")
