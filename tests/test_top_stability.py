"""The auto-driller's closed loop: stable, retuned, or refused with gains that work (issue 33).

Two strings the shipped examples do not cover, on which the default tuning is unstable: a stiff
lab rig (a short rod on a 10 MN/m frame spring) and a 2,800 m string with tool joints, a derrick
spring and a 30 t block.  Oracle: the linear closed loop (hammer held) propagated over a long time
by scipy's matrix exponential grows or decays at the rate its largest real part says.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.linalg import expm

from cli_run import run_cli
from hammerbit.cosim.config import CosimConfig, CouplingInstabilityError, default_hammer
from hammerbit.cosim.stability import StabilityWatch
from hammerbit.cosim.string_side import StringSide
from hammerbit.drillstring import DrillStringError, loads_string, state_space
from hammerbit.drillstring.boundary import Boundary
from hammerbit.drillstring.top import TopCondition, top_matrices
from hammerbit.drillstring.top_stability import ControllerUnstableError

LAB_STIFF = '''name = "lab-stiff"
description = "1.2 m x 30 mm steel rod on a 10 MN/m frame spring above a 0.3 m x 80 mm bit holder"
modal_damping_ratio = 0.01
mud_density = 0.0
max_element_length = 0.05
[boundaries]
top = "spring:1e7"
bottom = "free"
[[section]]
name = "rod"
length = 1.2
od = 0.03
id = 0.0
[[section]]
name = "bit holder"
length = 0.3
od = 0.08
id = 0.02
'''

DEEP = '''name = "deep-2800m"
description = "2600 m of 5 in pipe with tool joints above 200 m of collars, derrick spring, 30 t block"
modal_damping_ratio = 0.02
mud_density = 1200.0
max_element_length = 20.0
[boundaries]
top = { kind = "spring", stiffness = 2.0e7, mass = 30000.0 }
bottom = "free"
[[section]]
name = "drill pipe"
length = 2600.0
od = 0.127
id = 0.1086
linear_mass = 33.6
[[section]]
name = "drill collars"
length = 200.0
od = 0.1651
id = 0.0714375
'''


def _config(string, top):
    return CosimConfig(rig=default_hammer(string), top=top, stop=0.2, estimate=False)


def _matrices(string, top, check):
    c = _config(string, top)
    ss = state_space(string, None, Boundary.hammer(c.interface_stiffness, c.interface_damping), mass=c.mass,
                     wob=c.weight_on_bit)
    return top_matrices(string, ss, top, interface_stiffness=c.interface_stiffness,
                        interface_damping=c.interface_damping, hammer_stiffness=c.rig.stiffness, check=check)


def _growth_rate(A, horizon):
    """Rate [1/s] at which the linear system X' = A X grows over the second half of ``horizon``
    (least squares on log |X| at 200 instants; matrix exponential of scipy)."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal(A.shape[0])
    dt = horizon / 400
    P = expm(A * dt)
    logs = []
    for _ in range(400):
        x = P @ x
        nx = np.linalg.norm(x)
        logs.append(math.log(nx))
        x /= nx                                   # the norm is kept in the log, not in x
    logs = np.cumsum(logs)
    t = dt * np.arange(1, 401)
    return float(np.polyfit(t[200:], logs[200:], 1)[0])


@pytest.fixture(scope="module", params=["lab-stiff", "deep-2800m"])
def string(request):
    return loads_string(LAB_STIFF if request.param == "lab-stiff" else DEEP)


def test_default_gains_unstable_then_retuned_as_the_oracle_says(string):
    """The default tuning grows on both strings (the oracle's rate matches the largest real part);
    the retuned gains decay, at the rate their largest real part says."""
    raw = _matrices(string, TopCondition.auto_driller(), check=False)
    lam = np.linalg.eigvals(raw.A1)
    worst = lam[np.argmax(lam.real)]
    assert worst.real > 0
    assert _growth_rate(raw.A1, 30.0 / worst.real) == pytest.approx(worst.real, rel=0.1)
    fixed = _matrices(string, TopCondition.auto_driller(), check=True)
    g = fixed.gains
    assert g.retuned_from == (raw.gains.proportional_gain, raw.gains.integral_gain)
    assert g.proportional_gain < raw.gains.proportional_gain and g.integral_gain < raw.gains.integral_gain
    assert g.damping_ratio == pytest.approx(raw.gains.damping_ratio)
    rate = _growth_rate(fixed.A1, 20.0 / abs(g.loop_eigenvalue.real))
    assert rate < 0
    assert rate == pytest.approx(g.loop_eigenvalue.real, rel=0.15)
    d = g.to_dict()
    assert d["retuned"] is True and "unstable" in d["retune_note"]


def test_given_unstable_gains_are_refused_with_gains_that_work(string):
    raw = _matrices(string, TopCondition.auto_driller(), check=False).gains
    top = TopCondition.auto_driller(min(raw.proportional_gain, 1.0), min(raw.integral_gain, 1.0))
    with pytest.raises(ControllerUnstableError) as e:
        _matrices(string, top, check=True)
    assert isinstance(e.value, DrillStringError)
    assert e.value.eigenvalue.real > 0
    assert "unstable" in str(e.value) and "gains that work" in str(e.value)
    kp, ki = e.value.working
    ok = _matrices(string, TopCondition.auto_driller(kp, ki), check=True)
    assert ok.gains.retuned_from is None
    assert np.linalg.eigvals(ok.A1).real.max() < 0


def test_the_shipped_strings_keep_their_default_gains():
    from hammerbit.drillstring import load_string
    for name in ("lab", "field-2200m"):
        s = load_string(name)
        g = _matrices(s, TopCondition.auto_driller(), check=True).gains
        assert g.retuned_from is None and g.loop_eigenvalue.real < 0


def test_cli_retunes_the_default_and_refuses_given_unstable_gains(tmp_path, capsys):
    path = tmp_path / "lab-stiff.toml"
    path.write_text(LAB_STIFF)
    code, out, err = run_cli(["cosim", "--string", str(path), "--stop", "0.05",
                              "--top", "auto-driller", "--json"], capsys)
    assert code in (0, 5), err
    top = json.loads(out)["top"]
    assert top["retuned"] is True and top["loop_max_real_part_per_s"] < 0
    assert "retuned" in err
    kp, ki = top["default_proportional_gain"], min(top["default_integral_gain"], 1.0)
    code, out, err = run_cli(["cosim", "--string", str(path), "--stop", "0.05",
                              "--top", f"auto-driller:kp={kp},ki={ki}"], capsys)
    assert code == 2
    assert "unstable" in err and "gains that work: --top auto-driller:kp=" in err
    assert "Traceback" not in err


def test_a_loop_unstable_in_the_run_is_named_as_the_controllers():
    """An interface force that blows up under an auto-driller whose loop is unstable while the bit
    slides names the controller and not the step."""
    s = loads_string(DEEP)
    c = _config(s, TopCondition.auto_driller(1e-4, 1e-4))
    side = StringSide.__new__(StringSide)
    side.matrices, side.ki, side.wob = _matrices(s, c.top, check=False), c.interface_stiffness, c.weight_on_bit
    watch = StabilityWatch(c, side, 0.1)
    with pytest.raises(CouplingInstabilityError) as e:
        watch.update(0.01, 1, 1e-3, 1e12, np.zeros(5), 0.0)
    msg = str(e.value)
    assert "auto-driller" in msg and "reduce H" not in msg
    # the same blow-up with a fixed hook is the coupling's
    c2 = _config(s, TopCondition())
    side.matrices = _matrices(s, c2.top, check=False)
    with pytest.raises(CouplingInstabilityError) as e:
        StabilityWatch(c2, side, 0.1).update(0.01, 1, 1e-3, 1e12, np.zeros(5), 0.0)
    assert "reduce H" in str(e.value)
