"""Figures of the paper's analyses (matplotlib, Agg backend)."""
from __future__ import annotations

import math

import numpy as np

from hammerbit.model.solver_options import SolverOptions

from hammerbit.scene.figure import SceneFigure, draw_scene
from hammerbit.scene.simulate import Record, simulate

__all__ = ["scene_figure", "plot_scene", "plot_bifurcation", "plot_penetration", "plot_attractor"]


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def scene_figure(groups, periods, *, solver: SolverOptions = SolverOptions(), last: int = 10,
                 per_period: int = 400, preset: str | None = None, period: int | None = None) -> SceneFigure:
    """What the figure of one scene shows, in SI with the scene's own scales (:class:`SceneFigure`).

    Simulates ``periods`` forcing periods from rest, sampling the last
    ``last`` of them at ``per_period`` points per period, and keeps the
    Poincaré points: those inside that window (relative displacement and
    velocity) and those of the second half of the run, in the bounded
    coordinates (x_b - x_s [mm], v_b [m/s]) -- the bit's own velocity is 0
    there, since the bit sticks at the sampling phase.

    Parameters
    ----------
    groups : Groups
        The scene.
    periods : int
        Horizon in forcing periods.
    solver : SolverOptions
        Method and tolerances.
    last, per_period : int
        Periods shown in the time panels and samples per period.
    preset : str, optional
        Preset name for the title.
    period : int, optional
        Detected period-n for the title (``analysis.detect_period``); computed
        here when not given.
    """
    from hammerbit.scene.analysis import detect_period
    T = groups.period
    sc = groups.scales
    mm = sc.length * 1e3
    last = max(1, min(int(last), int(math.ceil(periods))))
    t0 = max(periods - last, 0) * T
    times = np.linspace(t0, periods * T, last * per_period + 1)
    r = simulate(groups, periods, record=Record(poincare=True, times=times), solver=solver)
    s, p = r.samples, r.poincare
    if period is None and len(p) > 8:
        period = detect_period(p)
    pw = p[p["time"] >= t0 - 1e-9 * T]
    half = p[len(p) // 2:]
    name = preset or "scene"
    pn = f"period {period}" if period else "no period up to 32"
    return SceneFigure(
        time_s=s["time"] * sc.time,
        hammer_mm=s["hammer_position"] * mm,
        bit_mm=s["bit_position"] * mm,
        relative_mm=(s["hammer_position"] - s["bit_position"]) * mm,
        relative_velocity=(s["hammer_velocity"] - s["bit_velocity"]) * sc.velocity,
        window_points_mm=(pw["hammer_position"] - pw["bit_position"]) * mm,
        window_points_velocity=(pw["hammer_velocity"] - pw["bit_velocity"]) * sc.velocity,
        section_mm=(half["hammer_position"] - half["bit_position"]) * mm,
        section_velocity=half["hammer_velocity"] * sc.velocity,
        periods_shown=last,
        window_s=last * groups.period_s,
        gap_mm=groups.length_m(groups.r) * 1e3 if groups.has_gap else None,
        title=(f"{name}: {pn}; a={groups.a:g}, b={groups.b:g}, eta={groups.eta:g}, r={groups.r:g}, "
               f"mu={groups.mu:g}; forcing {1.0 / groups.period_s:.4g} Hz, x0 = {sc.length * 1e3:.4g} mm"))


def plot_scene(groups, periods, path, *, solver: SolverOptions = SolverOptions(), last: int = 10,
               per_period: int = 400, preset: str | None = None, period: int | None = None):
    """The figure of one scene, in SI with the scene's own scales; returns ``path``.

    :func:`scene_figure` computes what it shows (same parameters) and
    :func:`hammerbit.scene.figure.draw_scene` draws it: hammer and bit
    displacement [mm] against time [s] over the last ``last`` forcing periods;
    the relative motion x_b - x_s [mm] with the gap R when there is one; its
    phase portrait with the Poincaré points; the Poincaré section of the second
    half of the run.  The format follows the extension of ``path``.
    """
    data = scene_figure(groups, periods, solver=solver, last=last, per_period=per_period,
                        preset=preset, period=period)
    return draw_scene(data, path)


def _scales(scales, res=None):
    """The scales of a figure: given, else the result's scene's, else the paper's rig."""
    from hammerbit.model.scales import DEFAULT_SCALES
    if scales is not None:
        return scales
    g = getattr(res, "groups", None)
    return getattr(g, "scales", None) or getattr(res, "scales", None) or DEFAULT_SCALES


def _si_top_axis(ax, param: str, scales):
    """A top axis in newtons when the x axis is the amplitude or preload group."""
    F0 = scales.friction_force
    if param in ("a", "b"):
        top = ax.secondary_xaxis("top", functions=(lambda v: v * F0, lambda v: v / F0))
        top.set_xlabel(("amplitude A" if param == "a" else "preload B") + " [N]")


def plot_bifurcation(res, path, *, scales=None, preset: str | None = None):
    """Bifurcation diagram (relative displacement at the Poincaré section [mm]) and drift per period [mm].

    ``scales`` (default: the scene's, else the paper's rig) turn lengths into mm; ``preset``
    names the scene in the title.
    """
    plt = _plt()
    sc = _scales(scales, res)
    mm = sc.length * 1e3
    fig, ax = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for i, v in enumerate(res.values):
        P = res.points[i]
        ax[0].plot(np.full(P.shape[0], v), (P[:, 1] - P[:, 3]) * mm, "k.", ms=1.5)
    ax[0].set_ylabel("x_b − x_s at the Poincaré section [mm]")
    ax[0].set_title((f"{preset}: " if preset else "") + f"bifurcation diagram over {res.param} "
                    f"(x0 = {mm:.4g} mm)")
    _si_top_axis(ax[0], res.param, sc)
    ax[1].plot(res.values, np.asarray(res.drift) * mm, "b.-", ms=3)
    ax[1].set_ylabel("penetration per period [mm]")
    ax[1].set_xlabel(res.param)
    ax[1].grid(alpha=0.3)
    for i, v in enumerate(res.values):
        n = res.periods[i]
        if n and (i == 0 or res.periods[i - 1] != n):
            ax[0].annotate(f"P{n}", (v, np.nanmax(res.points[i, :, 1] - res.points[i, :, 3]) * mm),
                           fontsize=7, color="r")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_penetration(values, curves: dict, path, *, periods: int = 100, scales=None, param: str = "a"):
    """Penetration [mm] after ``periods`` forcing periods against a group (Fig. 14).

    ``curves`` maps a label to penetrations in x0; ``scales`` (default: the
    paper's rig) turn them into mm.
    """
    plt = _plt()
    sc = _scales(scales)
    fig, ax = plt.subplots(figsize=(7, 4.8))
    for label, y in curves.items():
        ax.plot(values, np.asarray(y) * sc.length * 1e3, ".-", label=label)
    ax.set_xlabel(param)
    ax.set_ylabel(f"penetration after {periods} periods [mm]")
    _si_top_axis(ax, param, sc)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_attractor(poincare, path, *, title="", scales=None):
    """Poincaré section of a (possibly strange) attractor (Fig. 15), relative motion in mm and m/s."""
    plt = _plt()
    sc = _scales(scales)
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot((poincare["hammer_position"] - poincare["bit_position"]) * sc.length * 1e3,
            (poincare["hammer_velocity"] - poincare["bit_velocity"]) * sc.velocity, "k.", ms=1)
    ax.set_xlabel("relative displacement x_b − x_s [mm]")
    ax.set_ylabel("relative velocity v_b − v_s [m/s]")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
