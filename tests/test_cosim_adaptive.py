"""Adaptive macro step with rollback through the hammer's state (FMU: fmi2Get/SetFMUstate),
driven by the coupling-error estimate; the CLI's accuracy contract."""
import json

import numpy as np
import pytest

from hammerbit.cosim.config import CosimConfig, field_hammer
from hammerbit.cosim.master import cosimulate, cosimulate_adaptive
from hammerbit.cosim.reference import monolithic
from hammerbit.drillstring import load_string

DRILL = field_hammer().replace(frequency=22.5)


@pytest.fixture(scope="module")
def string():
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def drilling_reference(string):
    return monolithic(string, CosimConfig(stop=1.0, step=1e-3, rig=DRILL))


def test_adaptive_meets_its_tolerance_on_a_drilling_case(string, drilling_reference):
    """Default tolerance 1e-3: the true penetration and WOB amplitude errors against the
    monolithic reference are within it, and the estimate says so."""
    ref = drilling_reference
    res = cosimulate(string, CosimConfig(stop=1.0, step=1e-3, rig=DRILL, adaptive=True,
                                         record=("wob", "bit_position", "step_size", "force_defect")))
    assert res.counts["slips"] >= 10
    e = res.estimate
    assert e.meets_tolerance and e.tol == 1e-3
    assert abs(res.penetration_m / ref.penetration_m - 1.0) <= 1e-3
    assert res.stats["rejected"] > 0 and res.stats["h_max_used"] > res.stats["h_min_used"]
    d = res.data
    assert d["time"][-1] == 1.0 and np.all(np.diff(d["time"]) > 0)
    assert np.allclose(np.diff(d["time"]), d["step_size"][1:], rtol=1e-9, atol=1e-15)


def test_tighter_tolerance_smaller_steps_smaller_error(string, drilling_reference):
    ref = drilling_reference
    errs, steps = [], []
    for tol in (1e-2, 1e-4):
        r = cosimulate_adaptive(string, CosimConfig(stop=1.0, step=1e-3, rig=DRILL), tol=tol)
        errs.append(abs(r.penetration_m / ref.penetration_m - 1.0))
        steps.append(r.macro_steps)
        assert r.estimate.tol == tol
    assert steps[0] < steps[1]
    # at 1e-4 the comparison reaches the reference's own error (a few 1e-5, rtol 1e-10 and
    # event location of 440 + 4 states): allow 2x
    assert errs[1] < errs[0] and errs[1] < 2e-4


def test_adaptive_through_the_fmu_rolls_back_and_matches_in_process(string, built_fmu):
    cfg = CosimConfig(stop=0.2, step=4e-3, adaptive=True)
    a = cosimulate(string, cfg)
    b = cosimulate(string, cfg, fmu=built_fmu)
    assert b.stats["rejected"] > 0
    assert a.macro_steps == b.macro_steps and a.stats["rejected"] == b.stats["rejected"]
    assert np.allclose(a.data["time"], b.data["time"], rtol=0, atol=1e-12)
    assert np.max(np.abs(a.data["wob"] - b.data["wob"])) < 1e-6 * 55e3


def test_adaptive_bad_options(string):
    with pytest.raises(ValueError, match="h_min"):
        cosimulate_adaptive(string, CosimConfig(stop=0.1, step=1e-3), h_min=2e-3)
    with pytest.raises(ValueError, match="tol"):
        cosimulate_adaptive(string, CosimConfig(stop=0.1, step=1e-3), tol=0.0)


# ---------------------------------------------------------------------------
# the CLI: accurate by default, or says it is not
# ---------------------------------------------------------------------------
def test_cli_default_is_adaptive_and_within_tolerance(capsys):
    from hammerbit.cli.main import main
    rc = main(["cosim", "--string", "field-2200m", "--stop", "0.3", "--set", "A=5000", "--json"])
    d = json.loads(capsys.readouterr().out)
    assert d["method"] == "cosim-adaptive" and d["adaptive"]["accepted"] == d["macro_steps"]
    assert rc == 0 and d["meets_tolerance"] and d["error_estimate"]["wob_amplitude_rel"] <= 1e-3


def test_cli_fixed_step_beyond_tolerance_exits_5_with_the_estimate(capsys):
    from hammerbit.cli.main import main
    from hammerbit.cli.common import EXIT_INACCURATE
    rc = main(["cosim", "--string", "field-2200m", "--stop", "0.4", "--set", "frequency=22.5",
               "--step", "0.01", "--json"])
    cap = capsys.readouterr()
    d = json.loads(cap.out)
    assert rc == EXIT_INACCURATE
    assert not d["meets_tolerance"]
    assert "estimated coupling error" in cap.err and "Traceback" not in cap.err


@pytest.mark.parametrize("argv, needle", [
    (["--stop", "0.01", "--step", "1"], "longer than the run"),
    (["--stop", "1", "--step", "0.03"], "cannot resolve"),
    (["--stop", "0.1", "--fmu", "__FILE__"], "not an FMU"),
    (["--stop", "0.1", "--set", "nonsense=1"], "nonsense"),
    (["--stop", "0.1", "--set", "A=-5"], "A"),
    (["--stop", "0.1", "--tol", "2"], "tol"),
])
def test_cli_bad_input_exits_2_without_traceback(capsys, tmp_path, argv, needle):
    from hammerbit.cli.main import main
    bad = tmp_path / "notazip.fmu"
    bad.write_text("not a zip")
    argv = [str(bad) if a == "__FILE__" else a for a in argv]
    assert main(["cosim", "--string", "field-2200m", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_cli_monolithic_same_output(capsys):
    from hammerbit.cli.main import main
    assert main(["cosim", "--string", "field-2200m", "--stop", "0.2", "--monolithic", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["method"] == "monolithic" and d["stop_s"] == 0.2 and d["meets_tolerance"] is None
    for key in ("wob_mean_n", "wob_amplitude_n", "penetration_m", "counts"):
        assert key in d


def test_harmonic_force_from_the_master(string, built_fmu):
    """The master drives the FMU's harmonic_force input (step mean, ZOH) with the internal source off:
    the same response as the FMU's own continuous source, to the ZOH error."""
    cfg = CosimConfig(stop=0.5, step=1e-3, estimate=False)
    own = cosimulate(string, cfg, fmu=built_fmu)
    mst = cosimulate(string, cfg.replace(harmonic_source="master"), fmu=built_fmu)
    inproc = cosimulate(string, cfg.replace(harmonic_source="master"))
    assert abs(mst.wob_amplitude() / own.wob_amplitude() - 1.0) < 1e-2
    assert np.max(np.abs(mst.data["wob"] - inproc.data["wob"])) < 1e-6 * 55e3
    with pytest.raises(ValueError, match="harmonic_source"):
        CosimConfig(harmonic_source="nowhere")


def test_step_counts_are_the_hammers_own(string, monkeypatch):
    """``hammer_steps``, ``companion_steps``, ``state_saves`` and ``rollbacks`` in the stats are
    what the hammer sides were actually asked to do (counted on the hammer class itself)."""
    from hammerbit.cosim import hammer_inprocess as C
    calls = {"step": 0, "get_state": 0, "set_state": 0}
    for name in calls:
        orig = getattr(C.StepperHammer, name)

        def wrapped(self, *a, _orig=orig, _name=name):
            calls[_name] += 1
            return _orig(self, *a)
        monkeypatch.setattr(C.StepperHammer, name, wrapped)
    r = cosimulate(string, CosimConfig(stop=0.2, step=4e-3, rig=DRILL, adaptive=True, record=("wob",)))
    s = r.stats
    assert s["rejected"] > 0 and s["passes"] >= 1
    assert s["hammer_steps"] + s["companion_steps"] == calls["step"]
    assert s["state_saves"] == calls["get_state"] and s["rollbacks"] == calls["set_state"] == s["rejected"]
    assert s["hammer_steps"] >= r.macro_steps + s["rejected"] and s["companion_steps"] >= 2 * r.macro_steps
    for k in calls:
        calls[k] = 0
    f = cosimulate(string, CosimConfig(stop=0.2, step=1e-3, rig=DRILL, record=("wob",)))
    assert f.stats["hammer_steps"] == f.macro_steps == 200 and f.stats["companion_steps"] == 400
    assert calls["step"] == 600 and calls["get_state"] == 0 and f.stats["rollbacks"] == 0
