"""Figures of the paper's analyses (matplotlib, Agg backend)."""
from __future__ import annotations

import numpy as np

from hammerbit.model.stepping import SolverOptions

from .simulate import Record, simulate

__all__ = ["plot_scene", "plot_bifurcation", "plot_penetration", "plot_attractor"]


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_scene(groups, periods, path, *, solver: SolverOptions = SolverOptions(), last: int = 10,
               per_period: int = 400):
    """Time history, phase portrait of the bounded motion and Poincaré map of one scene."""
    plt = _plt()
    T = groups.period
    t0 = max(periods - last, 0) * T
    times = np.linspace(t0, periods * T, last * per_period + 1)
    r = simulate(groups, periods, record=Record(poincare=True, times=times), solver=solver)
    s, p = r.samples, r.poincare
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    ax[0].plot(s["time"] / T, s["bit_position"], label="bit x3 (penetration)")
    ax[0].plot(s["time"] / T, s["hammer_position"], label="hammer x1", lw=0.8)
    ax[0].set_xlabel("forcing periods")
    ax[0].set_ylabel("position [x0]")
    ax[0].legend()
    ax[1].plot(s["hammer_position"] - s["bit_position"], s["hammer_velocity"] - s["bit_velocity"], lw=0.8)
    half = p[len(p) // 2:]
    ax[1].plot(half["hammer_position"] - half["bit_position"], half["hammer_velocity"] - half["bit_velocity"],
               "r.", ms=6, label="Poincaré")
    ax[1].set_xlabel("x1 - x3")
    ax[1].set_ylabel("x2 - x4")
    ax[1].set_title("phase portrait (relative motion)")
    ax[1].legend()
    ax[2].plot(half["hammer_position"] - half["bit_position"], half["bit_velocity"], "k.", ms=4)
    ax[2].set_xlabel("x1 - x3")
    ax[2].set_ylabel("x4")
    ax[2].set_title("Poincaré map")
    fig.suptitle(f"a={groups.a:g}, b={groups.b:g}, eta={groups.eta:g}, r={groups.r:g}, mu={groups.mu:g}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_bifurcation(res, path):
    """Bifurcation diagram (x1 - x3 at the Poincaré section) and drift per period."""
    plt = _plt()
    fig, ax = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for i, v in enumerate(res.values):
        P = res.points[i]
        ax[0].plot(np.full(P.shape[0], v), P[:, 1] - P[:, 3], "k.", ms=1.5)
    ax[0].set_ylabel("x1 - x3 at Poincaré section")
    ax[0].set_title(f"bifurcation diagram over {res.param}")
    ax[1].plot(res.values, res.drift, "b.-", ms=3)
    ax[1].set_ylabel("penetration per period [x0]")
    ax[1].set_xlabel(res.param)
    for i, v in enumerate(res.values):
        n = res.periods[i]
        if n and (i == 0 or res.periods[i - 1] != n):
            ax[0].annotate(f"P{n}", (v, np.nanmax(res.points[i, :, 1] - res.points[i, :, 3])),
                           fontsize=7, color="r")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_penetration(values, curves: dict, path, *, periods: int = 100):
    """Penetration after ``periods`` forcing periods against a (Fig. 14)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for label, y in curves.items():
        ax.plot(values, y, ".-", label=label)
    ax.set_xlabel("a")
    ax.set_ylabel(f"penetration after {periods} periods [x0]")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_attractor(poincare, path, *, title=""):
    """Poincaré section of a (possibly strange) attractor (Fig. 15)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(poincare["hammer_position"] - poincare["bit_position"],
            poincare["hammer_velocity"] - poincare["bit_velocity"], "k.", ms=1)
    ax.set_xlabel("x1 - x3")
    ax.set_ylabel("x2 - x4")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
