"""The regime verdict's operational boundaries as curves (hammerbit.continuation.touch's bounce, .runaway): the
located onsets against dense sampling, the verdict of runs either side and bisections of long runs."""
import json

import numpy as np
import pytest
from orbit_sampling import dense_orbit_samples, settled_events_per_period
from cli_run import run_cli

from hammerbit.continuation import correct_orbit, orbit_from_simulation
from hammerbit.continuation.bifurcation import detect
from hammerbit.continuation.continuation import follow_branch
from hammerbit.continuation.output import MARKERS, draw_curves, load_curves
from hammerbit.continuation.parameter import Parameter
from hammerbit.continuation.runaway import detect_runaway, follow_runaway, runaway_side
from hammerbit.continuation.touch import bounce_margin, follow_touch
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.presets import preset
from hammerbit.model.stepping import Stepper
from hammerbit.scene.simulate import simulate

#: paper-fig9 driven far beyond the paper's domain (a = 1.5): the stuck bit's period-1 orbit bounces below b ~ 0.13
BOUNCE_SCENE = dict(a=1.5, b=0.2)
#: paper-fig9 at a = 0.2 with the preload above the friction floor mu = 0.795: the stick-slip orbit ends at a fold
RUNAWAY_SCENE = dict(a=0.2, b=0.78)
#: offset either side of a curve point at which the verdict is read (scaled parameter)
SIDE = 1e-5


def _bifurcations(scene, end):
    base = preset("paper-fig9").replace(**scene)
    n, s = orbit_from_simulation(base)
    param = Parameter.on("b", base)
    branch = follow_branch(param, base, correct_orbit(base, s, n), end)
    bifs = detect(param, base, branch.points, 0)
    return base, bifs + detect_runaway(param, base, bifs)


def _one(located, kind):
    base, bifs = located
    found = [b for b in bifs if b.kind == kind]
    assert len(found) == 1, [b.kind for b in bifs]
    return base, found[0]


@pytest.fixture(scope="module")
def bounce_onset():
    return _one(_bifurcations(BOUNCE_SCENE, 0.05), "bounce")


@pytest.fixture(scope="module")
def runaway_scene_bifurcations():
    return _bifurcations(RUNAWAY_SCENE, 0.84)


@pytest.fixture(scope="module")
def runaway_onset(runaway_scene_bifurcations):
    return _one(runaway_scene_bifurcations, "runaway")


def test_the_smooth_fold_is_located_as_a_fold_to_its_multiplier(runaway_scene_bifurcations):
    """The fold that ends the stick-slip family is smooth (its multiplier passes +1 continuously): located on
    the arclength, its multiplier is +1 to 1e-6, and it is named a fold, not a border collision."""
    _, fold = _one(runaway_scene_bifurcations, "fold")
    assert not [b for b in runaway_scene_bifurcations[1] if b.kind == "border-collision"]
    assert np.min(np.abs(fold.orbit.multipliers - 1.0)) < 1e-6


def _settled_bounces(g, state, periods=40):
    """Bounce events per period of the library's Stepper run from ``state``, over its second half."""
    return settled_events_per_period(g, state, KL.EV_BOUNCE, periods)


def test_the_bounce_margin_is_that_of_a_dense_sampling():
    g = preset("paper-fig9").replace(a=1.5, b=0.1)
    orbit, samples = dense_orbit_samples(g)
    stuck = samples[:, 6] == KL.STICK
    # no gap: the drive on the bit is the spring and the damper, (x1 - x3) + 2 xi (x2 - x4)
    drive = samples[:, 0] - samples[:, 2] + 2 * g.xi * (samples[:, 1] - samples[:, 3])
    dense = np.min(drive[stuck]) + 1.0
    assert dense < 0
    assert abs(bounce_margin(orbit) - dense) < 1e-8


def test_bounce_onset_is_where_the_settled_orbit_starts_to_bounce(bounce_onset):
    base, bif = bounce_onset
    assert abs(bounce_margin(bif.orbit)) < 1e-8
    below = correct_orbit(base.replace(b=bif.value - SIDE), bif.orbit.s, 1)
    above = correct_orbit(base.replace(b=bif.value + SIDE), bif.orbit.s, 1)
    assert _settled_bounces(below.groups, below.state) == pytest.approx(1.0)
    assert _settled_bounces(above.groups, above.state) == 0


def test_the_bounce_curve_separates_the_verdict_of_settled_runs(bounce_onset):
    base, bif = bounce_onset
    curve = follow_touch(base, bif, "b", "a", 1.3, 1.7, points=2)
    assert not curve.stopped and len(curve.points) == 3
    assert len({round(b, 6) for b, _ in curve.points}) == 3     # the onset moves with a
    for (b, a), orbit in zip(curve.points, curve.orbits):
        g = base.replace(a=a)
        for side, bounces in ((-SIDE, 1.0), (SIDE, 0.0)):
            o = correct_orbit(g.replace(b=b + side), orbit.s, 1)
            assert _settled_bounces(o.groups, o.state) == pytest.approx(bounces), (a, b, side)


def _runs_away(g, state, periods=400):
    return simulate(g, periods, y0=state).flags.runaway


def test_runaway_onset_is_the_fold_past_which_runs_from_the_orbit_run_away(runaway_onset):
    base, bif = runaway_onset
    assert bif.orbit.groups.b > bif.orbit.groups.mu
    assert np.min(np.abs(bif.orbit.multipliers - 1.0)) < 1e-6
    below = correct_orbit(base.replace(b=bif.value - SIDE), bif.orbit.s, 1)
    assert below.stable
    assert not _runs_away(below.groups, below.state)
    # past the fold no orbit: the run from the last one drifts away, the verdict's certificate proves it
    assert _runs_away(base.replace(b=bif.value + 1e-7), bif.orbit.state)
    assert runaway_side(Parameter.on("b", base), base, bif.value, bif.orbit) == 1.0
    assert "above" in bif.detail


def test_the_runaway_curve_separates_the_verdict_of_runs_from_its_orbits(runaway_onset):
    base, bif = runaway_onset
    curve = follow_runaway(base, bif, "b", "a", 0.19, 0.23, points=2)
    assert len(curve.points) == 3
    for (b, a), orbit in zip(curve.points, curve.orbits):
        g = base.replace(a=a)
        assert not _runs_away(g.replace(b=b - 1e-6), orbit.state), (a, b)
        assert _runs_away(g.replace(b=b + 1e-6), orbit.state), (a, b)


def _bisect(runs_over, lo, hi, tol):
    """The value in [lo, hi] where ``runs_over(v)`` turns from False to True, to ``tol``."""
    assert not runs_over(lo) and runs_over(hi)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if runs_over(mid) else (mid, hi)
    return 0.5 * (lo + hi)


def test_the_located_runaway_onset_is_that_of_a_bisection_of_long_runs(runaway_onset):
    base, bif = runaway_onset
    # the runs start on the stable orbit a little below the fold (inside its basin on both sides)
    start = correct_orbit(base.replace(b=bif.value - 1e-4), bif.orbit.s, 1)
    b_star = _bisect(lambda b: _runs_away(base.replace(b=b), start.state, periods=2000),
                     bif.value - 1e-4, bif.value + 1e-4, 1e-8)
    assert abs(b_star - bif.value) < 1e-7


def test_the_located_bounce_onset_is_that_of_a_bisection_of_long_runs_from_rest(bounce_onset):
    base, bif = bounce_onset

    def bounces(b):
        # the settled part of a run from rest: periods 300 to 400
        g = base.replace(b=b)
        st = Stepper(g, compile_helper=False)
        st.advance(300 * g.period)
        before = st.istate[KL.I_COUNT0 + KL.EV_BOUNCE]
        st.advance(400 * g.period)
        return st.istate[KL.I_COUNT0 + KL.EV_BOUNCE] == before
    b_star = _bisect(bounces, bif.value - 1e-3, bif.value + 1e-3, 1e-7)
    assert abs(b_star - bif.value) < 2e-7


@pytest.mark.slow
def test_the_diagram_reports_the_runaway_onset_and_a_run_from_rest_that_runs_away():
    from hammerbit.continuation.diagram import continue_orbits
    d = continue_orbits(preset("paper-fig9").replace(**RUNAWAY_SCENE), "b", 0.78, 0.84, seeds=2)
    assert [b.kind for b in d.bifurcations].count("runaway") == 1
    # the seed at b = 0.84 (past the onset, where no stick-slip orbit is left) runs away from rest
    assert any(s.startswith("b = 0.84: a run from rest runs away") for s in d.stops), d.stops
    assert simulate(preset("paper-fig9").replace(a=0.2, b=0.84), 100).flags.runaway


def test_a_fold_that_runs_from_its_orbit_do_not_confirm_is_no_runaway_onset():
    # lab at a = 0.15: the stable stick-slip orbit ends at a fold near b = 0.92008, where runs from the orbit
    # leave on both sides (the fold's ghost): the verdict check does not confirm it as a runaway onset
    base = preset("lab").replace(b=0.9)
    n, s = orbit_from_simulation(base)
    param = Parameter.on("b", base)
    bifs = detect(param, base, follow_branch(param, base, correct_orbit(base, s, n), 0.93).points, 0)
    corner = [b for b in bifs if b.kind == "fold" and abs(b.value - 0.92008) < 1e-4]
    assert len(corner) == 1
    assert _runs_away(base.replace(b=corner[0].value - 1e-6), corner[0].orbit.state)
    assert _runs_away(base.replace(b=corner[0].value + 1e-6), corner[0].orbit.state)
    assert detect_runaway(param, base, bifs) == []


def test_continue_json_gives_the_bounce_curve_that_map_overlay_draws(capsys, tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    code, out, err = run_cli(["continue", "--set", "a=1.5", "--set", "b=0.2", "--param", "b", "--range", "0.2",
                              "0.05", "--seeds", "2", "--param2", "a", "--range2", "1.4", "1.6", "--curve-points",
                              "2", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert [b["kind"] for b in d["bifurcations"]] == ["bounce"]
    (curve,) = d["curves"]
    assert curve["kind"] == "bounce" and not curve["stopped"] and [p["a"] for p in curve["points"]] == \
        pytest.approx([1.4, 1.5, 1.6])
    # each point is where the orbit's indicator is zero (an independent correction from the point's own b)
    for p in curve["points"]:
        g = preset("paper-fig9").replace(a=p["a"], b=p["b"])
        n, s = orbit_from_simulation(g)
        assert abs(bounce_margin(correct_orbit(g, s, n))) < 1e-8
    path = tmp_path / "curves.json"
    path.write_text(out)
    fig, ax = plt.subplots()
    assert draw_curves(ax, load_curves(path), "a", "b") == 1
    assert ax.get_lines()[0].get_marker() == MARKERS["bounce"]
    plt.close(fig)
