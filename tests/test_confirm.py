"""``optimize --confirm``: the co-simulated operating point, its hook on the auto-driller.

Oracle: ``simulate`` of the same groups (the hammer on a rigid support with a
constant preload).  On a soft interface (k_i << K, so the interface carries the
preload as a nearly constant force) and with the hook following the drilling,
the co-simulation's sustained ROP is the standalone one; on a stiff interface
the hammer is detuned and the two differ.
"""
from __future__ import annotations

import pytest

from hammerbit.drillstring import load_string
from hammerbit.model.presets import preset
from hammerbit.model.settings import apply_settings
from hammerbit.scene.simulate import Record, simulate
from hammerbit.studies.confirm import confirm


@pytest.fixture(scope="module")
def point():
    """The lab optimum of the README (period-1, a + b = 1 at eta = 0.7)."""
    return apply_settings(preset("lab"), {"frequency": 1.0318, "amplitude": 24.2963})


def _standalone_rop(g, periods=200):
    r = simulate(g, periods, record=Record(poincare=True))
    return r.rop()["m_per_h"]


def test_confirm_on_a_soft_interface_sustains_the_standalone_rop(point):
    c = confirm(point, load_string("lab"), periods=20, interface_stiffness=30.0, interface_damping=1.0)
    assert c["rop_steady"] and c["top"] == "auto-driller"
    assert c["rop_m_per_h"] == pytest.approx(_standalone_rop(point), rel=0.02)
    # the auto-driller holds the static WOB (the point's preload)
    assert c["wob_mean_n"] == pytest.approx(point.b * point.scales.friction_force, rel=0.02)


def test_confirm_on_a_stiff_interface_detunes_the_hammer(point):
    c = confirm(point, load_string("lab"), periods=20, interface_stiffness=700.0, interface_damping=10.0)
    assert c["rop_m_per_h"] < 0.5 * _standalone_rop(point)
