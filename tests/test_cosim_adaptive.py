"""Adaptive macro step with rollback through the hammer's state (FMU: fmi2Get/SetFMUstate)."""
import json

import numpy as np
import pytest

from hammerbit.cosim import CosimConfig, cosimulate_adaptive, monolithic
from hammerbit.drillstring import load_string


@pytest.fixture(scope="module")
def string():
    return load_string("field-2200m")


@pytest.fixture(scope="module")
def reference(string):
    return monolithic(string, CosimConfig(stop=1.0, step=1e-3))


def test_adaptive_converges_to_the_monolithic_reference(string, reference):
    ref = reference.wob_amplitude()
    errs, steps = [], []
    for tol in (1e-2, 1e-3, 1e-4):
        res = cosimulate_adaptive(string, CosimConfig(stop=1.0, step=4e-3), tol=tol)
        errs.append(abs(res.wob_amplitude() / ref - 1.0))
        steps.append(res.macro_steps)
        assert res.stats["rejected"] > 0                 # the 4 ms start is too coarse: rolled back
        assert np.all(res.data["force_defect"][1:] <= tol) or res.stats["at_min_step"] > 0
        assert np.all(np.diff(res.data["time"]) > 0)
    assert errs[-1] < 1e-3
    assert errs[-1] < errs[0]
    assert steps[0] < steps[1] < steps[2]               # tighter tolerance, smaller steps


def test_adaptive_through_the_fmu_rolls_back_and_matches_in_process(string, built_fmu):
    cfg = CosimConfig(stop=0.2, step=4e-3)
    a = cosimulate_adaptive(string, cfg, tol=1e-3)
    b = cosimulate_adaptive(string, cfg, fmu=built_fmu, tol=1e-3)
    assert b.stats["rejected"] > 0
    assert a.stats == b.stats
    assert np.allclose(a.data["time"], b.data["time"], rtol=0, atol=1e-12)
    assert np.max(np.abs(a.data["wob"] - b.data["wob"])) < 1e-6 * 55e3


def test_adaptive_bad_options(string):
    with pytest.raises(ValueError, match="h_min"):
        cosimulate_adaptive(string, CosimConfig(stop=0.1, step=1e-3), h_min=2e-3)
    with pytest.raises(ValueError, match="tol"):
        cosimulate_adaptive(string, CosimConfig(stop=0.1, step=1e-3), tol=0.0)


def test_cli_cosim_adaptive(capsys):
    from hammerbit.cli import main
    assert main(["cosim", "--string", "field-2200m", "--stop", "0.1", "--step", "2e-3", "--adaptive",
                 "--tol", "1e-3", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["method"] == "cosim-adaptive" and d["adaptive"]["accepted"] == d["macro_steps"]


def test_harmonic_force_from_the_master(string, built_fmu):
    """The master drives the FMU's harmonic_force input (step mean, ZOH) with the internal source off:
    the same response as the FMU's own continuous source, to the ZOH error."""
    from hammerbit.cosim import cosimulate
    cfg = CosimConfig(stop=0.5, step=1e-3)
    own = cosimulate(string, cfg, fmu=built_fmu)
    mst = cosimulate(string, cfg.replace(harmonic_source="master"), fmu=built_fmu)
    inproc = cosimulate(string, cfg.replace(harmonic_source="master"))
    assert abs(mst.wob_amplitude() / own.wob_amplitude() - 1.0) < 1e-2
    assert np.max(np.abs(mst.data["wob"] - inproc.data["wob"])) < 1e-6 * 55e3
    with pytest.raises(ValueError, match="harmonic_source"):
        CosimConfig(harmonic_source="nowhere")
