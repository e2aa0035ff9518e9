"""The monolithic reference of the co-simulation: string, interface and hammer as one hybrid system.

The string with the interface spring is the linear subsystem of
:class:`hammerbit.model.stepping.Stepper` (nondimensional: lengths in ``x0``,
velocities in ``x0 Omega``, time ``tau = Omega t``, forces in ``F0``),
integrated by the same adaptive event-located solver as the hammer at
``config.rtol``.  A constant state (``z_c = 1``) carries the equilibrium
offsets.  No exchange, no macro step: the answer the co-simulation converges to.
"""
from __future__ import annotations

import time as _time

import numpy as np

from hammerbit.cosim.config import CosimConfig, CosimResult, event_counts, record_dtype
from hammerbit.cosim.string_side import StringSide

__all__ = ["monolithic"]


def monolithic(string, config=None):
    """The same coupled system as one hybrid system (reference solution).

    Parameters
    ----------
    string : DrillString
    config : CosimConfig
        Its hammer, interface, string options, ``stop``, ``ramp`` and ``rtol``;
        samples at ``t0 + n step`` (and at ``stop``).  With a ramp the harmonic
        amplitude is held per ``step`` at its midpoint value, as the master
        does for the in-process hammer.

    Returns
    -------
    CosimResult
        ``method='monolithic'``; string-side variables that the sampler does
        not return (``string_bit_*``, ``hook_load``, ``energy_residual``,
        ``force_defect``, ``wob_error_estimate``) are NaN, ``hammer_force`` =
        ``interface_force``, ``step_size`` the sampling step; ``counts`` the
        events by kind; no estimate.
    """
    from hammerbit.model import kernel_forces, kernel_layouts
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.model.stepping import LinearSubsystem, Stepper
    c = CosimConfig() if config is None else config
    ts = _time.perf_counter()
    side = StringSide(string, c)
    rig = c.rig
    s = rig.scales
    F0, x0, Om, v0 = s.friction_force, s.length, s.omega, s.velocity
    W = side.wob
    n = side.n
    nq = n // 2
    D = np.r_[np.full(nq, x0), np.full(n - nq, v0)]
    x1eq = W / F0  # hammer position [x0] with the bit at 0: spring compressed by W/K
    # z = [xi / D, 1]
    A = np.zeros((n + 1, n + 1))
    A[:n, :n] = (side.A1 * D[None, :]) / D[:, None] / Om
    Hm = (side.E * np.array([x0, v0])[None, :]) / D[:, None] / Om
    A[:n, n] = -Hm[:, 0] * x1eq
    Hz = np.zeros((n + 1, 2))
    Hz[:n] = Hm
    G = np.zeros(n + 1)
    G[:n] = side.frow * D / F0
    G[n] = (W + side.ki * x0 * x1eq) / F0
    g = np.array([-side.ki * x0 / F0, -side.ci * v0 / F0])
    z0 = np.zeros(n + 1)
    z0[n] = 1.0
    lin = LinearSubsystem(A=A, H=Hz, G=G, g=g, z0=z0)
    grp = rig.to_groups().replace(b=0.0)
    st = Stepper(grp, solver=SolverOptions(rtol=c.rtol, atol=c.rtol * 1e-2), linear=lin,
                 y0=[x1eq, 0.0, 0.0, 0.0])
    st.fstate[kernel_layouts.F_T] = Om * c.start
    n_full, rem = c.whole_steps
    idx = np.arange(0, n_full + 1, c.record_every)
    t_s = c.start + idx * c.step
    if rem > 0.0 or idx[-1] != n_full:
        t_s = np.r_[t_s, c.stop]
    samples = np.zeros((len(t_s), kernel_layouts.N_SAMPLE_COLS))
    setup = _time.perf_counter() - ts
    t_loop = _time.perf_counter()
    if c.ramp > 0.0:
        a = float(grp.a)
        t = c.start
        k = 0
        while t < min(c.start + c.ramp, c.stop) - 1e-12:
            h = min(c.step, c.stop - t)
            st.p[kernel_layouts.P_A] = a * c.ramp_factor(t + 0.5 * h)
            k += 1
            t = min(c.start + k * c.step, c.stop)
            st.advance(Om * t, sample_times=Om * t_s, samples=samples)
        st.p[kernel_layouts.P_A] = a
    st.advance(Om * c.stop, sample_times=Om * t_s, samples=samples)
    wall = _time.perf_counter() - t_loop
    data = np.full(len(t_s), np.nan, dtype=record_dtype(c.record))
    data["time"] = t_s
    x1, x2, x3, x4, fc, fl = (samples[:, i] for i in range(6))
    p = st.p
    fk = np.array([kernel_forces.spring_damper_force(row[:4], p) for row in samples])
    m = {"wob": (fk + fc) * F0, "interface_force": fl * F0, "hammer_force": fl * F0,
         "hammer_position": x1 * x0, "hammer_velocity": x2 * v0, "bit_position": x3 * x0,
         "bit_velocity": x4 * v0, "stick": (samples[:, 6] == kernel_layouts.STICK).astype(float),
         "contact": (samples[:, 7] != kernel_layouts.FREE).astype(float),
         "step_size": np.r_[0.0, np.diff(t_s)]}
    for r in c.record:
        if r in m:
            data[r] = m[r]
    stats = {"string_states": n, "events": st.counts}
    return CosimResult(data, c, len(t_s) - 1, wall, setup, float(st.y[2] * x0), stats, "monolithic",
                       counts=event_counts(st.counts))
