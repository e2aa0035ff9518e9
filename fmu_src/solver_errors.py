"""The errors of the hybrid solver, and the one place that turns a kernel status code into them."""
from __future__ import annotations

from .kernel_layouts import (ST_BAD_INPUT, ST_DONE, ST_EVENT_STORM, ST_LOG_FULL, ST_MAX_STEPS, ST_NONFINITE,
                             ST_STEP_STORM, ST_STEP_TOO_SMALL)

__all__ = ["SolverError", "EventStormError", "StepSizeError", "NonFiniteStateError", "MaxStepsError",
           "StepStormError", "raise_for_status"]


class SolverError(RuntimeError):
    """The integration could not continue.

    Attributes
    ----------
    time : float
        Nondimensional time tau where it stopped.
    status : int
        Kernel status code.
    """

    def __init__(self, message: str, *, time: float, status: int):
        self.time = time
        self.status = status
        super().__init__(message)


class EventStormError(SolverError):
    """More events in one forcing period than ``max_events_per_period`` allows."""


class StepSizeError(SolverError):
    """The adaptive step fell below the floating-point resolution of t."""


class NonFiniteStateError(SolverError):
    """The state became NaN or infinite."""


class MaxStepsError(SolverError):
    """More steps than ``max_steps`` in one call."""


class StepStormError(SolverError):
    """More accepted steps in one forcing period than ``max_steps_per_period``: the
    solver crawls (a stiff or nearly singular regime) instead of hanging."""


def raise_for_status(status: int, *, time: float, solver, counts) -> str:
    """``'done'`` or ``'log_full'`` for a kernel status that lets the run go on, else the matching
    :class:`SolverError` raised (``time``: tau where the kernel stopped; ``solver``: its
    :class:`~.solver_options.SolverOptions`; ``counts``: a callable giving the event counts).
    """
    if status == ST_DONE:
        return "done"
    if status == ST_LOG_FULL:
        return "log_full"
    t = time
    if status == ST_MAX_STEPS:
        raise MaxStepsError(f"more than max_steps={solver.max_steps} steps in one call; stopped "
                            f"at tau = {t:.9g}", time=t, status=status)
    if status == ST_EVENT_STORM:
        raise EventStormError(
            f"event storm: more than {solver.max_events_per_period} events in the forcing "
            f"period around tau = {t:.9g} (counts {counts()}); raise max_events_per_period "
            f"or check the parameters (e.g. a chattering contact or a force at the friction threshold)",
            time=t, status=status)
    if status == ST_STEP_TOO_SMALL:
        raise StepSizeError(f"step size fell below the resolution of t at tau = {t:.9g} "
                            f"(rtol={solver.rtol:g}); the problem is too stiff for these "
                            f"tolerances", time=t, status=status)
    if status == ST_STEP_STORM:
        raise StepStormError(
            f"step storm: more than {solver.max_steps_per_period} accepted steps in the "
            f"forcing period around tau = {t:.9g} (rtol={solver.rtol:g}); the regime is too "
            f"stiff for these tolerances, or raise max_steps_per_period", time=t, status=status)
    if status == ST_NONFINITE:
        raise NonFiniteStateError(f"state became non-finite at tau = {t:.9g}", time=t, status=status)
    if status == ST_BAD_INPUT:
        raise SolverError(f"the kernel refused its input at tau = {t:.9g}: a non-finite state or "
                          f"end time, or an end time before the current time", time=t, status=status)
    raise SolverError(f"solver stopped with status {status} at tau = {t:.9g}", time=t, status=status)
