"""The coupling-stability watch of the co-simulation: the power-bond energy residual and blow-up checks."""
from __future__ import annotations

import math
from math import isfinite

from hammerbit.cosim.config import CosimConfig, CouplingInstabilityError
from hammerbit.cosim.hammer_interface import OUT_HAMMER_POSITION, OUT_HAMMER_VELOCITY
from hammerbit.cosim.string_side import StringSide

__all__ = ["StabilityWatch"]


class StabilityWatch:
    """The power-bond residual watch (see :mod:`hammerbit.cosim.master`)."""

    def __init__(self, c: CosimConfig, side: StringSide, t_steady: float):
        rig = c.rig
        W = side.wob
        self.c, self.ki = c, side.ki
        self.side = side
        E_ref = W * W / (2 * side.ki) + W * W / (2 * rig.stiffness) + rig.amplitude ** 2 / rig.stiffness
        self.E_ref = max(E_ref, 1e-12)
        self.F_scale = c.blowup * (W + rig.amplitude + rig.scales.friction_force)
        self.W = W
        self.win_sum, self.win_prev, self.n_grow, self.k_in_win = 0.0, math.inf, 0, 0
        self.max_win = self.max_steady = 0.0
        self.total = 0.0
        self.t_steady = t_steady
        # the options update() reads every step
        self.check, self.window = c.check_stability, c.stability_window

    def hammer_failed(self, err, t, n, H, F_held):
        # the hammer side gave up; if the interface was already growing, that is the cause
        c = self.c
        if c.check_stability and (self.n_grow > 0 or abs(F_held - self.W) > 0.2 * self.F_scale
                                  or not math.isfinite(F_held)):
            raise CouplingInstabilityError(
                f"coupling unstable: the hammer side failed at t = {t:.6g} s (step {n + 1}, "
                f"H = {H:g} s, k_i = {self.ki:g} N/m) under a growing interface force "
                f"{F_held:.4g} N: {err}{self._controller()}", time=t, step=n + 1, residual=math.nan,
                reference=self.E_ref) from err

    def update(self, t_end, n, H, F, out, r_step) -> None:
        self.total += r_step
        if not self.check:
            return
        if not (isfinite(F) and isfinite(out[OUT_HAMMER_POSITION]) and isfinite(out[OUT_HAMMER_VELOCITY])):
            raise CouplingInstabilityError(
                f"coupling unstable: non-finite interface values at t = {t_end:.6g} s "
                f"(step {n + 1}, H = {H:g} s, k_i = {self.ki:g} N/m){self._controller()}",
                time=t_end, step=n + 1, residual=math.inf, reference=self.E_ref)
        if abs(F - self.W) > self.F_scale:
            c = self.c
            raise CouplingInstabilityError(
                f"coupling unstable: interface force {F:.4g} N left {c.blowup:g} x its scale "
                f"at t = {t_end:.6g} s (step {n + 1}, H = {H:g} s, k_i = {self.ki:g} N/m); "
                f"{self._advice()}",
                time=t_end, step=n + 1, residual=self.win_sum, reference=self.E_ref)
        self.win_sum += abs(r_step)
        self.k_in_win += 1
        if self.k_in_win < self.window:
            return
        c = self.c
        w = self.win_sum
        self.max_win = max(self.max_win, w)
        if t_end >= self.t_steady + c.stability_window * H:
            self.max_steady = max(self.max_steady, w)
        self.n_grow = self.n_grow + 1 if w > c.growth * self.win_prev else 0
        if w > c.energy_tol * self.E_ref and self.n_grow >= c.growth_windows:
            raise CouplingInstabilityError(
                f"coupling unstable: interface energy residual {w:.4g} J over "
                f"{c.stability_window} steps (reference {self.E_ref:.4g} J) grew {self.n_grow} "
                f"windows in a row, at t = {t_end:.6g} s (step {n + 1}, H = {H:g} s, "
                f"k_i = {self.ki:g} N/m, scheme {c.scheme}, order {c.extrapolation}); "
                f"{self._advice()}",
                time=t_end, step=n + 1, residual=w, reference=self.E_ref)
        self.win_prev = w
        self.win_sum, self.k_in_win = 0.0, 0

    def _advice(self) -> str:
        """What to change: the auto-driller's gains when its loop is what grows, else the step."""
        blame = self._controller()
        return blame.lstrip("; ") if blame else "reduce H or the interface stiffness"

    def _controller(self) -> str:
        """``"; ..."`` naming the auto-driller's loop when it is unstable while the bit slides
        (with the hammer held it was checked before the run), else empty."""
        m = getattr(self.side, "matrices", None)
        if m is None or m.gains is None:
            return ""
        from hammerbit.drillstring.top_stability import sliding_check
        rig, c = self.c.rig, self.c
        chk = sliding_check(m, interface_stiffness=c.interface_stiffness, interface_damping=c.interface_damping,
                            hammer_mass=rig.hammer_mass, bit_mass=rig.bit_mass, stiffness=rig.stiffness,
                            damping=rig.damping)
        if chk.stable:
            return ""
        lam = chk.eigenvalue
        return (f"; not the step: the auto-driller's loop is unstable while the bit slides (eigenvalue "
                f"{lam.real:+.4g} {'+' if lam.imag >= 0 else '-'} {abs(lam.imag):.4g}i 1/s, "
                f"{abs(lam.imag) / (2 * math.pi):.4g} Hz, with kp = {chk.proportional_gain:.4g}, "
                f"ki = {chk.integral_gain:.4g}): lower the gains (--top auto-driller:kp=..,ki=..)")

    def stats(self) -> dict:
        return {"max_window_energy_residual_j": self.max_win,
                "steady_window_energy_residual_j": self.max_steady,
                "energy_residual_total_j": self.total, "reference_energy_j": self.E_ref}
