"""The grazing boundary in two parameters (hammerbit.continuation.touch): the orbit's largest contact
overlap, and its zero followed as a curve, against a regime map's impact count."""
import numpy as np
import pytest
from orbit_sampling import dense_orbit_samples

from hammerbit.continuation import correct_orbit, orbit_from_simulation
from hammerbit.continuation.bifurcation import Bifurcation
from hammerbit.continuation.touch import follow_touch, max_overlap
from hammerbit.model.presets import preset
from hammerbit.studies.map import run_cell

#: paper-fig9 with a gap: its period-1 orbit (the attractor from rest for a > 0.175) grazes near r = 1.01-1.04
A_RANGE = (0.18, 0.26)
R_RANGE = (0.98, 1.06)


@pytest.fixture(scope="module")
def grazing_curve():
    """The grazing curve of the period-1 orbit in (r, a), started from a guess of the grazing gap at a = 0.2."""
    base = preset("paper-fig9").replace(a=0.2, r=1.1)
    n, s = orbit_from_simulation(base)
    orbit = correct_orbit(base, s, n)
    # a rough guess: follow_touch refines it at a = 0.2 before going on
    guess = Bifurcation(kind="grazing", value=1.0, branch=0, orbit=orbit)
    return base, follow_touch(base, guess, "r", "a", *A_RANGE, points=8)


@pytest.fixture(scope="module")
def grazing_curves(grazing_curve):
    """{period: curve}: the period-1 curve and that of the stable period-2 orbit, which coexists with it (runs
    from rest reach it at the small amplitudes and gaps of the map)."""
    base, p1 = grazing_curve
    g = base.replace(a=0.19, r=1.012)
    n, s = orbit_from_simulation(g)
    assert n == 2
    p2 = correct_orbit(g, s, n)
    curve = follow_touch(g, Bifurcation(kind="grazing", value=1.02, branch=0, orbit=p2), "r", "a", *A_RANGE,
                         points=8)
    assert not curve.stopped
    return base, {1: p1, 2: curve}


def test_the_largest_overlap_is_that_of_a_dense_sampling():
    g = preset("paper-fig9").replace(a=0.2, r=1.0)
    orbit, samples = dense_orbit_samples(g)
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


def _wrong_side(base, curves, a_values, r_values, periods):
    """Cells whose impact count contradicts the curve of the period they settle to by more than one cell width
    in r, and the number of cells compared with each curve."""
    r_cell = r_values[1] - r_values[0]
    wrong, compared = [], {n: 0 for n in curves}
    for a in a_values:
        for r in r_values:
            cell = run_cell(base.replace(a=a, r=r), periods)
            if cell.period not in curves:
                continue
            pts = sorted((a_, r_) for r_, a_ in curves[cell.period].points)
            r_graze = np.interp(a, [p[0] for p in pts], [p[1] for p in pts])
            compared[cell.period] += 1
            impacts = cell.impacts_per_period > 0
            if impacts != (r < r_graze) and abs(r - r_graze) > r_cell:
                wrong.append((a, r, cell.period, impacts, r_graze))
    return wrong, compared


def test_the_curves_separate_the_maps_impacting_cells(grazing_curves):
    base, curves = grazing_curves
    r_values = np.linspace(*R_RANGE, 9)
    wrong, compared = _wrong_side(base, curves, np.linspace(*A_RANGE, 5), r_values, 300)
    assert not wrong
    # the map has period-1 cells on both sides of its curve, away from it
    r_graze = [r for r, _ in curves[1].points]
    assert r_values[0] < min(r_graze) - 0.02 and r_values[-1] > max(r_graze) + 0.02
    assert compared[1] >= 30


@pytest.mark.slow
def test_the_curves_separate_the_impacting_cells_of_a_41_by_41_map(grazing_curves):
    base, curves = grazing_curves
    wrong, compared = _wrong_side(base, curves, np.linspace(*A_RANGE, 41), np.linspace(*R_RANGE, 41), 1000)
    assert not wrong
    assert compared[1] >= 1400 and compared[2] > 0
