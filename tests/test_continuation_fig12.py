"""paper-fig12 along a: the paper's period sequence P4, P3, P2, P1 (at a = 0.044, 0.05, 0.06, 0.11, the
sections of its Fig. 13) appears as stable branches of the continuation (slow: several minutes)."""
import pytest

from hammerbit.continuation.diagram import continue_orbits, stable_intervals
from hammerbit.model.presets import preset

RANGE = (0.12, 0.04)
#: runs from rest every 1e-3 in a: the P4 window is about 2e-3 wide
SEEDS = 81
#: the paper's sections (Fig. 13): (a, period)
SECTIONS = [(0.044, 4), (0.05, 3), (0.06, 2), (0.11, 1)]


@pytest.mark.slow
def test_the_fig12_sequence_appears_as_stable_branches():
    d = continue_orbits(preset("paper-fig12"), "a", *RANGE, seeds=SEEDS)
    for a, n in SECTIONS:
        spans = [(lo, hi) for br in d.branches if br.period == n for lo, hi, _, _ in stable_intervals(br)]
        assert any(lo <= a <= hi for lo, hi in spans), (a, n, spans)
