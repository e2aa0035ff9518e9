"""The contact law's derivatives (``kernel_forces.contact_stiffness``, ``contact_damping``,
``contact_force_rate``) against central differences of the law ``contact_force`` itself."""
from __future__ import annotations

import numpy as np
import pytest

from hammerbit.model import kernel_forces as KF
from hammerbit.model import kernel_layouts as KL
from hammerbit.model.presets import preset


def _kernel_params(n):
    p = preset("paper-fig9").to_kernel()
    p[KL.P_N] = n
    p[KL.P_LAM] = 0.37
    return p


def _force(d, rate, p):
    return KF.contact_force(d, rate, p, KL.CONTACT)


@pytest.mark.parametrize("n", [1.5, 1.0, 2.3])
@pytest.mark.parametrize("d,rate", [(0.3, 0.8), (1e-2, -1.7), (-0.05, 0.4)])
def test_contact_derivatives_are_the_laws_own(n, d, rate):
    p = _kernel_params(n)
    h = 1e-6 * max(abs(d), 1e-3)
    k_fd = (_force(d + h, rate, p) - _force(d - h, rate, p)) / (2 * h)
    c_fd = (_force(d, rate + 1e-6, p) - _force(d, rate - 1e-6, p)) / 2e-6
    assert KF.contact_stiffness(d, rate, p) == pytest.approx(k_fd, rel=1e-7)
    assert KF.contact_damping(d, p) == pytest.approx(c_fd, rel=1e-7)
    # the force's rate along d(t) = d + rate t + accel t^2 / 2, d'(t) = rate + accel t, at t = 0
    accel, t = -0.9, 1e-6
    f_of_t = [_force(d + rate * s + 0.5 * accel * s * s, rate + accel * s, p) for s in (-t, t)]
    rate_fd = (f_of_t[1] - f_of_t[0]) / (2 * t)
    if d > 0.0:  # the rate's power term is the law's for an open contact (d > 0), where it is used
        assert KF.contact_force_rate(d, rate, accel, p) == pytest.approx(rate_fd, rel=1e-6)
    assert KF.contact_damping_factor_rate(accel, p) == pytest.approx(
        (KF.contact_damping_factor(rate + accel * t, p) - KF.contact_damping_factor(rate - accel * t, p)) / (2 * t),
        rel=1e-8)


def test_elastic_part_is_the_force_without_damping():
    p = _kernel_params(1.5)
    p[KL.P_LAM] = 0.0
    assert KF.contact_elastic_force(0.2, p) == KF.contact_force(0.2, 5.0, p, KL.CONTACT)
