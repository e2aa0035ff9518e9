"""The hammer as the string's bottom boundary, against an independent oracle.

The oracle is the continuous bar: each uniform section carried by its exact
transfer matrix, the top fixed, the bottom loaded by the interface spring in
series with the hammer mass on its spring to the stuck bit.  It is written
here, separately from the library's finite elements, state space and
transfer-matrix code.
"""
import cmath
import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from hammerbit.cosim.config import CosimConfig, field_hammer
from hammerbit.cosim.linear_modes import coupled_modes, coupled_system
from hammerbit.drillstring import DrillStringError, load_string
from hammerbit.check.frequency import hammer_on_bottom_frequencies

F_MAX = 40.0


@pytest.fixture(scope="module")
def string():
    return load_string("field-2200m")


def oracle_frequencies(string, ki, m1, K, f_max):
    """Natural frequencies [Hz] of the continuous string (fixed top) with the hammer at the bottom.

    State [u, N] (N = EA u' the tension) from the top down:
    u(l) = cos(kl) u0 + sin(kl)/(EA k) N0, N(l) = -EA k sin(kl) u0 + cos(kl) N0, k = w/c.
    Bottom: the hammer (m1 on K to the stuck bit) through k_i gives N = -k_b u,
    k_b = k_i (K - m1 w^2)/(k_i + K - m1 w^2); multiplied through by the denominator.
    """
    def g(w):
        u, n = 0.0, 1.0
        for sec in string.sections:
            EA = sec.axial_stiffness
            k = w / sec.wave_speed
            kl = k * sec.length
            u, n = math.cos(kl) * u + math.sin(kl) / (EA * k) * n, -EA * k * math.sin(kl) * u + math.cos(kl) * n
        return ki * (K - m1 * w * w) * u + (ki + K - m1 * w * w) * n

    ws = np.linspace(1e-3, 2 * math.pi * f_max, 20001)
    vals = np.array([g(w) for w in ws])
    roots = [brentq(g, ws[i], ws[i + 1], xtol=1e-13, rtol=1e-15)
             for i in np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]]
    return np.array(roots) / (2 * math.pi)


def _undamped(string):
    """The co-simulated system with every dashpot removed (the oracle has none)."""
    cfg = CosimConfig(interface_damping=0.0, rig=field_hammer().replace(damping=0.0), estimate=False)
    return string.replace(modal_damping_ratio=0.0), cfg


def test_oracle_pair_near_the_drive_is_close(string):
    """The oracle itself: two modes near 23 Hz less than 1 % apart (the pair a 1 % window cannot tell)."""
    rig = field_hammer()
    f = oracle_frequencies(string, 2e6, rig.hammer_mass, rig.stiffness, F_MAX)
    pair = f[(f > 22.0) & (f < 24.0)]
    assert len(pair) == 2 and pair[1] / pair[0] - 1.0 < 1e-2


def test_coupled_modes_match_the_continuous_oracle(string):
    """The state matrix the master steps (string + interface + hammer, bit stuck) has the
    oracle's frequencies, one to one, each to 2e-4: well inside half the gap of the close pair."""
    s, cfg = _undamped(string)
    rig = cfg.rig
    f_or = oracle_frequencies(s, cfg.interface_stiffness, rig.hammer_mass, rig.stiffness, F_MAX)
    f_co = coupled_modes(s, cfg, f_max=F_MAX)
    assert len(f_co) == len(f_or)
    rel = np.abs(f_co / f_or - 1.0)
    gaps = np.diff(f_or) / f_or[:-1]
    print(f"\nmax relative error {rel.max():.2e}; smallest relative gap {gaps.min():.2e}")
    assert rel.max() < 2e-4
    assert rel.max() < 0.1 * gaps.min()


def damped_oracle_eigenvalues(string, ki, ci, m1, K, C, f_max):
    """Eigenvalues lambda (Im > 0, sorted) of the continuous string with the hammer's dashpots.

    The bar of :func:`oracle_frequencies` in the Laplace domain (``s = i w``, ``w``
    complex): the interface ``k_i + c_i s`` and the hammer spring ``K + C s``.  Each
    undamped root is followed while the dashpots grow from 0 to their value
    (Newton on the characteristic function at every stage), so every root keeps its mode.
    """
    def g(w, t):
        u, n = 0.0, 1.0
        for sec in string.sections:
            EA = sec.axial_stiffness
            k = w / sec.wave_speed
            kl = k * sec.length
            u, n = cmath.cos(kl) * u + cmath.sin(kl) / (EA * k) * n, -EA * k * cmath.sin(kl) * u + cmath.cos(kl) * n
        kis, Ks = ki + 1j * w * ci * t, K + 1j * w * C * t
        return kis * (Ks - m1 * w * w) * u + (kis + Ks - m1 * w * w) * n

    roots = []
    for f in oracle_frequencies(string, ki, m1, K, f_max):
        w = 2 * math.pi * f + 0j
        for t in np.linspace(0.05, 1.0, 20):
            for _ in range(50):
                h = 1e-7 * abs(w)
                step = g(w, t) / ((g(w + h, t) - g(w - h, t)) / (2 * h))
                w -= step
                if abs(step) < 1e-12 * abs(w):
                    break
        roots.append(1j * w)
    lam = np.array(roots)
    return lam[np.argsort(lam.imag)]


def test_damped_modes_match_the_continuous_oracle_with_dashpots(string):
    """The state matrix the master steps, with the interface's and the hammer's dashpots, has the
    oracle's eigenvalues: the decay rates Re lambda within 3 % (the mesh's error grows to 2 % at
    40 Hz), the frequencies within 2e-4; every mode decays."""
    s = string.replace(modal_damping_ratio=0.0)          # the oracle's bar has no internal damping
    cfg = CosimConfig(estimate=False)
    rig = cfg.rig
    lam_or = damped_oracle_eigenvalues(s, cfg.interface_stiffness, cfg.interface_damping, rig.hammer_mass,
                                       rig.stiffness, rig.damping, F_MAX)
    lam = np.linalg.eigvals(coupled_system(s, cfg)[0])
    lam = lam[(lam.imag > 0) & (lam.imag <= 2 * math.pi * F_MAX * (1 + 1e-3))]
    lam = lam[np.argsort(lam.imag)]
    assert len(lam) == len(lam_or)
    assert np.all(lam_or.real < 0.0) and np.all(lam.real < 0.0)
    assert np.max(np.abs(lam.imag / lam_or.imag - 1.0)) < 2e-4
    assert np.max(np.abs(lam.real - lam_or.real) / np.abs(lam_or.real)) < 0.03
    # the hammer's own mode: its dashpots damp it hard (the mode a wrong damper sign turns unstable)
    assert lam_or.real.min() < -1.0


@pytest.mark.parametrize("ki, K_factor", [(2e6, 1.0), (5e6, 0.5)])
def test_modal_check_matches_the_oracle(string, ki, K_factor):
    rig = field_hammer()
    K = rig.stiffness * K_factor
    f_check = hammer_on_bottom_frequencies(string, interface_stiffness=ki, hammer_mass=rig.hammer_mass,
                                           hammer_stiffness=K, f_max=F_MAX)
    f_or = oracle_frequencies(string, ki, rig.hammer_mass, K, F_MAX)
    assert len(f_check) == len(f_or)
    assert np.max(np.abs(f_check / f_or - 1.0)) < 2e-4
    f_exact = hammer_on_bottom_frequencies(string, interface_stiffness=ki, hammer_mass=rig.hammer_mass,
                                           hammer_stiffness=K, f_max=F_MAX, exact=True)
    assert np.allclose(f_exact, f_or, rtol=1e-9)


def test_bad_hammer_boundary(string):
    with pytest.raises(DrillStringError, match="hammer_mass"):
        hammer_on_bottom_frequencies(string, interface_stiffness=1e6, hammer_mass=0.0, hammer_stiffness=1e6)


def test_cli_modes_hammer_on_bottom_takes_the_cosim_options(capsys):
    """`modes --hammer-on-bottom` with --set and --interface-stiffness gives the oracle of that hammer."""
    from hammerbit.cli.main import main
    assert main(["modes", "--string", "field-2200m", "--hammer-on-bottom", "--fmax", "30", "--json",
                 "--set", "m1=500", "--interface-stiffness", "3e6", "--exact"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["bottom"] == "hammer-on-bottom" and d["hammer_mass_kg"] == pytest.approx(500.0)
    assert d["interface_stiffness_n_per_m"] == 3e6
    f = np.array(d["frequencies_hz"])
    assert len(f) > 5 and np.all(np.diff(f) > 0)
    f_or = oracle_frequencies(load_string("field-2200m"), 3e6, 500.0, d["hammer_stiffness_n_per_m"], 30.0)
    assert np.allclose(f, f_or, rtol=2e-4)
    assert np.max(np.abs(d["relative_error"])) < 2e-4
    assert main(["modes", "--string", "field-2200m", "--hammer-on-bottom", "--bottom", "free"]) == 2
    assert "--bottom" in capsys.readouterr().err
