"""A periodic orbit sampled densely over its period: the independent reading that the continuation's
indicators (smallest drive, largest overlap, bounce margin) are checked against."""
import numpy as np

from hammerbit.continuation import correct_orbit, orbit_from_simulation
from hammerbit.continuation.monodromy import ORBIT_SOLVER
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.stepping import Stepper

#: samples over one orbit period (the extremum between two samples is then below 1e-9 off)
DENSE_SAMPLES = 400_001


def dense_orbit_samples(g):
    """The orbit a simulation of ``g`` settles to, corrected, and the Stepper's samples of it over its
    period: ``(orbit, samples)``, a row of ``KL.N_SAMPLE_COLS`` columns per sample."""
    n, s = orbit_from_simulation(g)
    orbit = correct_orbit(g, s, n)
    times = np.linspace(0.0, n * g.period, DENSE_SAMPLES)
    samples = np.zeros((times.size, KL.N_SAMPLE_COLS))
    Stepper(g, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False).advance(times[-1], sample_times=times,
                                                                                   samples=samples)
    return orbit, samples


def settled_events_per_period(g, state, event: int, periods: int):
    """Events of kind ``event`` (``KL.EV_*``) per forcing period of the library's Stepper run from
    ``state``, counted over the run's second half (the first lets a transient die)."""
    st = Stepper(g, solver=ORBIT_SOLVER, y0=state, compile_helper=False)
    st.advance(periods // 2 * g.period)
    before = st.istate[KL.I_COUNT0 + event]
    st.advance(periods * g.period)
    return (st.istate[KL.I_COUNT0 + event] - before) / (periods - periods // 2)
