"""The modal check with the hammer as the bottom boundary agrees with the co-simulation."""
import json

import numpy as np
import pytest

from hammerbit.cosim import CosimConfig, coupled_modes, field_hammer, wob_frf
from hammerbit.drillstring import DrillStringError, load_string
from hammerbit.modal_check import hammer_on_bottom_frequencies


@pytest.fixture(scope="module")
def string():
    return load_string("field-2200m")


def test_modal_check_matches_coupled_system(string):
    cfg, rig = CosimConfig(), field_hammer()
    f_check = hammer_on_bottom_frequencies(string, interface_stiffness=cfg.interface_stiffness,
                                           hammer_mass=rig.hammer_mass, hammer_stiffness=rig.stiffness,
                                           f_max=40.0)
    f_cosim = coupled_modes(string, cfg, f_max=40.0)  # damped |Im(lambda)| of the co-simulated system
    assert len(f_check) == len(f_cosim)
    # undamped (check) against damped (co-simulated) frequencies: 2 % modal damping, hammer dashpot
    assert np.max(np.abs(f_check / f_cosim - 1.0)) < 5e-3


def test_frf_peak_sits_on_a_modal_check_frequency(string):
    cfg, rig = CosimConfig(), field_hammer()
    f_check = hammer_on_bottom_frequencies(string, interface_stiffness=cfg.interface_stiffness,
                                           hammer_mass=rig.hammer_mass, hammer_stiffness=rig.stiffness,
                                           f_max=40.0)
    fine = np.linspace(21.0, 24.5, 351)
    frf = np.abs(wob_frf(string, fine, cfg))
    f_peak = fine[np.argmax(frf)]
    # the peak sits on a close pair of modes (22.84, 23.00 Hz): within 1 % of one of them
    assert np.min(np.abs(f_check - f_peak)) / f_peak < 1e-2


def test_bad_hammer_boundary(string):
    with pytest.raises(DrillStringError, match="hammer_mass"):
        hammer_on_bottom_frequencies(string, interface_stiffness=1e6, hammer_mass=0.0, hammer_stiffness=1e6)


def test_cli_modes_hammer_on_bottom(capsys):
    from hammerbit.cli import main
    assert main(["modes", "--string", "field-2200m", "--hammer-on-bottom", "--fmax", "30", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["bottom"] == "hammer-on-bottom" and len(d["frequencies_hz"]) > 5
    assert all(np.diff(d["frequencies_hz"]) > 0)
