"""The grazing boundary in two parameters (hammerbit.continuation.touch): the orbit's largest contact
overlap, and its zero followed as a curve, against a regime map's impact count."""
import numpy as np
import pytest

from hammerbit.continuation import correct_orbit, orbit_from_simulation
from hammerbit.continuation.bifurcation import Bifurcation
from hammerbit.continuation.touch import follow_touch, max_overlap
from hammerbit.continuation.monodromy import ORBIT_SOLVER
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.presets import preset
from hammerbit.model.stepping import Stepper
from hammerbit.studies.map import run_cell

#: paper-fig9 with a gap: its period-1 orbit (the attractor from rest for a > 0.175) grazes near r = 1.01-1.04
A_RANGE = (0.18, 0.26)
R_RANGE = (0.98, 1.06)


@pytest.fixture(scope="module")
def grazing_curve():
    """The grazing curve in (r, a), started from a guess of the grazing gap at a = 0.2."""
    base = preset("paper-fig9").replace(a=0.2, r=1.1)
    n, s = orbit_from_simulation(base)
    orbit = correct_orbit(base, s, n)
    # a rough guess: follow_touch refines it at a = 0.2 before going on
    guess = Bifurcation(kind="grazing", value=1.0, branch=0, orbit=orbit)
    return base, follow_touch(base, guess, "r", "a", *A_RANGE, points=8)


def test_the_largest_overlap_is_that_of_a_dense_sampling():
    g = preset("paper-fig9").replace(a=0.2, r=1.0)
    n, s = orbit_from_simulation(g)
    orbit = correct_orbit(g, s, n)
    times = np.linspace(0.0, n * g.period, 400_001)
    samples = np.zeros((times.size, KL.N_SAMPLE_COLS))
    Stepper(g, solver=ORBIT_SOLVER, y0=orbit.state, compile_helper=False).advance(times[-1], sample_times=times,
                                                                                   samples=samples)
    dense = np.max(samples[:, 0] - samples[:, 2] - g.r)
    assert dense > 0  # impacts: the largest overlap is the peak of an impact
    assert abs(max_overlap(orbit) - dense) < 1e-9


def test_a_scene_without_gap_has_no_grazing():
    g = preset("paper-fig9").replace(a=0.2)
    n, s = orbit_from_simulation(g)
    with pytest.raises(ValueError, match="no gap"):
        max_overlap(correct_orbit(g, s, n))


def test_every_point_of_the_curve_is_an_orbit_that_grazes(grazing_curve):
    base, curve = grazing_curve
    assert not curve.stopped
    a_values = [a for _, a in curve.points]
    assert min(a_values) == pytest.approx(A_RANGE[0]) and max(a_values) == pytest.approx(A_RANGE[1])
    for r, a in curve.points[::3]:
        # the period-1 orbit at a, from its state without impacts (r = 1.1)
        n, s = orbit_from_simulation(base.replace(a=a))
        orbit = correct_orbit(base.replace(a=a, r=r), s, n)
        assert n == 1 and abs(max_overlap(orbit)) < 1e-8


def _wrong_side(base, curve, a_values, r_values, periods):
    """Cells whose impact count contradicts the curve by more than one cell width in r."""
    pts = sorted((a, r) for r, a in curve.points)
    r_cell = r_values[1] - r_values[0]
    wrong = []
    for a in a_values:
        r_graze = np.interp(a, [p[0] for p in pts], [p[1] for p in pts])
        for r in r_values:
            impacts = run_cell(base.replace(a=a, r=r), periods).impacts_per_period > 0
            if impacts != (r < r_graze) and abs(r - r_graze) > r_cell:
                wrong.append((a, r, impacts, r_graze))
    return wrong


def test_the_curve_separates_the_maps_impacting_cells(grazing_curve):
    base, curve = grazing_curve
    r_values = np.linspace(*R_RANGE, 9)
    assert not _wrong_side(base, curve, np.linspace(*A_RANGE, 5), r_values, 300)
    # the map has cells on both sides, away from the curve
    r_graze = [r for r, _ in curve.points]
    assert r_values[0] < min(r_graze) - 0.02 and r_values[-1] > max(r_graze) + 0.02


@pytest.mark.slow
def test_the_curve_separates_the_impacting_cells_of_a_41_by_41_map(grazing_curve):
    base, curve = grazing_curve
    assert not _wrong_side(base, curve, np.linspace(*A_RANGE, 41), np.linspace(*R_RANGE, 41), 1000)
