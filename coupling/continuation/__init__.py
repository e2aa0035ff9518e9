"""Numerical continuation of the periodic orbits of the hammer–bit–rock model: orbits, Floquet multipliers, bifurcations."""
from .monodromy import ContinuationError, MapResult, period_map
from .orbit import PeriodicOrbit, correct_orbit, orbit_from_simulation

__all__ = ["ContinuationError", "MapResult", "period_map", "PeriodicOrbit", "correct_orbit", "orbit_from_simulation"]
