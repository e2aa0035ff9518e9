"""The monolithic reference of the co-simulation: string, interface and hammer as one hybrid system.

The string with the interface spring is the linear subsystem of
:class:`hammerbit.model.stepping.Stepper` (nondimensional: lengths in ``x0``,
velocities in ``x0 Omega``, time ``tau = Omega t``, forces in ``F0``),
integrated by the same adaptive event-located solver as the hammer at
``config.rtol``, its string block in real modal form where that form is well
conditioned (:mod:`hammerbit.cosim.modal_form`: the same linear system, a
sparse matrix instead of a dense one).  A constant state (``z_c = 1``) carries
the equilibrium offsets.  No exchange, no macro step: the answer the co-simulation converges to.
"""
from __future__ import annotations

import math
import time as _time

import numpy as np

from hammerbit.cosim.config import CosimConfig, CosimResult, event_counts, record_dtype, steady_start
from hammerbit.cosim.string_side import StringSide

__all__ = ["monolithic", "monolithic_subsystem", "DENSE_PER_PERIOD"]

#: Samples of the reference's dense output per forcing period over the steady window (the WOB
#: figures: a contact spike lasts a few hundredths of a period), at most DENSE_MAX in all.
DENSE_PER_PERIOD = 4096
DENSE_MAX = 400_000


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
    from hammerbit.cosim.modal_form import in_modal_form
    from hammerbit.model import kernel_layouts
    from hammerbit.model.solver_options import SolverOptions
    from hammerbit.model.stepping import Stepper
    c = CosimConfig() if config is None else config
    ts = _time.perf_counter()
    side = StringSide(string, c)
    rig = c.rig
    s = rig.scales
    F0, x0, Om, v0 = s.friction_force, s.length, s.omega, s.velocity
    lin, x1eq = monolithic_subsystem(string, side, c)
    lin, _ = in_modal_form(lin, side.n, c.rtol)   # the hammer sees only G . z, the same in both forms
    grp = rig.to_groups().replace(b=0.0)
    st = Stepper(grp, solver=SolverOptions(rtol=c.rtol, atol=c.rtol * 1e-2), linear=lin,
                 y0=[x1eq, 0.0, 0.0, 0.0])
    st.fstate[kernel_layouts.F_T] = Om * c.start
    n_full, rem = c.whole_steps
    idx = np.arange(0, n_full + 1, c.record_every)
    t_s = c.start + idx * c.step
    if rem > 0.0 or idx[-1] != n_full:
        t_s = np.r_[t_s, c.stop]
    # the dense output: DENSE_PER_PERIOD samples per forcing period besides the record, for the
    # WOB figures (the amplitude of 1 ms samples is biased by the sampling)
    f = rig.frequency if rig.frequency > 0.0 else 1.0 / max(c.step, 1e-300)
    t_w = steady_start(c)
    n_d = min(int(math.ceil((c.stop - t_w) * f * DENSE_PER_PERIOD)), DENSE_MAX)
    t_d = np.linspace(t_w, c.stop, max(n_d, 2) + 1)
    t_all = np.union1d(t_s, t_d)
    samples_all = np.zeros((len(t_all), kernel_layouts.N_SAMPLE_COLS))
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
            st.advance(Om * t, sample_times=Om * t_all, samples=samples_all)
        st.p[kernel_layouts.P_A] = a
    st.advance(Om * c.stop, sample_times=Om * t_all, samples=samples_all)
    wall = _time.perf_counter() - t_loop
    samples = samples_all[np.searchsorted(t_all, t_s)]
    L = kernel_layouts
    fk_d = ((samples_all[:, L.X_HAMMER] - samples_all[:, L.X_BIT])
            + 2.0 * st.p[L.P_XI] * (samples_all[:, L.V_HAMMER] - samples_all[:, L.V_BIT]))
    dense = np.zeros(len(t_all), dtype=[("time", "f8"), ("wob", "f8")])
    dense["time"] = t_all
    dense["wob"] = (fk_d + samples_all[:, 4]) * F0
    data = np.full(len(t_s), np.nan, dtype=record_dtype(c.record))
    data["time"] = t_s
    x1, x2, x3, x4, fc, fl = (samples[:, i] for i in range(6))
    p = st.p
    fk = ((samples[:, L.X_HAMMER] - samples[:, L.X_BIT])
          + 2.0 * p[L.P_XI] * (samples[:, L.V_HAMMER] - samples[:, L.V_BIT]))
    m = {"wob": (fk + fc) * F0, "interface_force": fl * F0, "hammer_force": fl * F0,
         "hammer_position": x1 * x0, "hammer_velocity": x2 * v0, "bit_position": x3 * x0,
         "bit_velocity": x4 * v0, "stick": (samples[:, 6] == kernel_layouts.STICK).astype(float),
         "contact": (samples[:, 7] != kernel_layouts.FREE).astype(float),
         "step_size": np.r_[0.0, np.diff(t_s)]}
    for r in c.record:
        if r in m:
            data[r] = m[r]
    stats = {"string_states": side.n, "events": st.counts}
    return CosimResult(data, c, len(t_s) - 1, wall, setup, float(st.y[2] * x0), stats, "monolithic",
                       counts=event_counts(st.counts), dense=dense)


def monolithic_subsystem(string, side, config, *, feed_velocity=None, set_point_offset=0.0):
    """``(LinearSubsystem, x1eq)``: the string with the interface spring as the linear subsystem of
    the hammer's :class:`~hammerbit.model.stepping.Stepper` (nondimensional), and the hammer's
    position of the static equilibrium [x0].

    ``z = [xi / D, u_feed / x0, 1]``: the string's state in the hammer's scales, the feed's block
    and a constant state carrying the equilibrium offsets.  ``feed_velocity`` [m/s] (default the top
    condition's) and ``set_point_offset`` [N] (the auto-driller's WOB set point minus the WOB of the
    static equilibrium) enter only the constant state's column of ``A`` and its entry of ``G``, both
    affinely: a host that changes them between steps changes those entries alone.
    """
    from hammerbit.drillstring.top import rigid_inertia
    from hammerbit.model.stepping import LinearSubsystem
    s = config.rig.scales
    F0, x0, Om, v0 = s.friction_force, s.length, s.omega, s.velocity
    W = side.wob
    n = side.n
    scale = {"x": x0, "v": v0, "z": F0 / Om}
    D = np.array([scale[k] for k in side.matrices.kinds])
    x1eq = W / F0  # hammer position [x0] with the bit at 0: spring compressed by W/K
    V = float(side.feed[0] if feed_velocity is None else feed_velocity)
    # z = [xi / D, u_feed / x0, 1]: a feed's block is one more state, u' = V (exact for the solver)
    iu, ic = n, n + 1
    A = np.zeros((n + 2, n + 2))
    A[:n, :n] = (side.A1 * D[None, :]) / D[:, None] / Om
    Hm = (side.E * np.array([x0, v0])[None, :]) / D[:, None] / Om
    A[:n, ic] = -Hm[:, 0] * x1eq - Hm[:, 1] * V / v0   # the hammer relative to the block
    A[:n, iu] = -Hm[:, 0]
    A[iu, ic] = V / v0
    Hz = np.zeros((n + 2, 2))
    Hz[:n] = Hm
    G = np.zeros(n + 2)
    G[:n] = side.frow * D / F0
    G[iu] = side.ki * x0 / F0
    G[ic] = (W + side.ki * x0 * x1eq + side.ci * V) / F0
    dW = float(set_point_offset)
    if dW != 0.0:
        # the auto-driller's error e = hook load - set point gains dW: v_top = kp e + ki z gains
        # kp dW, a_top = kp e' + ki e gains ki dW, z' = e gains dW (top.top_matrices' X coordinates)
        m, kp, ki = side.matrices, side.gains.proportional_gain, side.gains.integral_gain
        ns = m.n_string
        nq = ns // 2
        g_acc = np.zeros(ns)
        g_acc[nq:] = -np.linalg.solve(side.ss.mass_matrix, rigid_inertia(string, side.ss, config.mass))
        c = np.zeros(n)
        c[:ns] = g_acc * ki - m.E[:ns, 1] * kp
        c[ns] = kp
        c[ns + 1] = 1.0
        A[:n, ic] += c * dW / D / Om
        G[ic] += side.ci * kp * dW / F0
    g = np.array([-side.ki * x0 / F0, -side.ci * v0 / F0])
    z0 = np.zeros(n + 2)
    z0[ic] = 1.0
    return LinearSubsystem(A=A, H=Hz, G=G, g=g, z0=z0), x1eq
