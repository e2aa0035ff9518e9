"""The scene figure: what it shows (:class:`SceneFigure`, SI arrays) and how it is drawn.

This module imports numpy and matplotlib only, never the solver, so that a
process that only draws (:mod:`hammerbit.scene.figure_worker`) does not load numba.
:func:`hammerbit.scene.plots.scene_figure` computes a :class:`SceneFigure` from a
scene; :func:`draw_scene` turns it into a file.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

__all__ = ["SceneFigure", "draw_scene"]


@dataclass(frozen=True)
class SceneFigure:
    """The data of the four panels of a scene figure, all in SI.

    The time panels cover the last forcing periods of the run, sampled
    densely; the Poincaré points are the states at the sampling phase (one per
    forcing period).
    """

    time_s: np.ndarray
    """sample times [s]"""
    hammer_mm: np.ndarray
    """hammer displacement x_b [mm] at ``time_s``"""
    bit_mm: np.ndarray
    """bit displacement x_s (the penetration) [mm] at ``time_s``"""
    relative_mm: np.ndarray
    """relative displacement x_b - x_s [mm] at ``time_s``"""
    relative_velocity: np.ndarray
    """relative velocity v_b - v_s [m/s] at ``time_s``"""
    window_points_mm: np.ndarray
    """relative displacement [mm] at the Poincaré points inside the time window"""
    window_points_velocity: np.ndarray
    """relative velocity [m/s] at the Poincaré points inside the time window"""
    section_mm: np.ndarray
    """relative displacement [mm] at the Poincaré points of the second half of the run"""
    section_velocity: np.ndarray
    """hammer velocity v_b [m/s] at the same points"""
    periods_shown: int
    """forcing periods in the time window"""
    window_s: float
    """length of the time window [s]"""
    gap_mm: Optional[float]
    """the gap R [mm], or None for a scene without impacts"""
    title: str
    """the figure's title (preset, detected period, groups, forcing frequency, x0)"""


def draw_scene(data: SceneFigure, path, *, dpi: int = 110):
    """Draw ``data`` into ``path`` (the format follows the extension); returns ``path``.

    Four panels: hammer and bit displacement [mm] against time [s]; the
    relative motion [mm] with the gap; its phase portrait (relative
    displacement [mm], relative velocity [m/s]) with the Poincaré points; the
    Poincaré section (x_b - x_s [mm], v_b [m/s]).  Uses matplotlib's Agg canvas
    directly (no pyplot state).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415
    from matplotlib.figure import Figure  # noqa: PLC0415

    fig = Figure(figsize=(12, 8))
    FigureCanvasAgg(fig)
    a0, a1, a2, a3 = fig.subplots(2, 2).ravel()
    a0.plot(data.time_s, data.hammer_mm, label="hammer x_b", lw=0.9)
    a0.plot(data.time_s, data.bit_mm, label="bit x_s (penetration)", lw=1.4)
    a0.set_xlabel("time [s]")
    a0.set_ylabel("displacement [mm]")
    a0.set_title(f"last {data.periods_shown} forcing periods ({data.window_s:.3g} s)")
    a0.legend(loc="upper left")
    a0.grid(alpha=0.3)
    a1.plot(data.time_s, data.relative_mm, lw=0.9)
    if data.gap_mm is not None:
        a1.axhline(data.gap_mm, color="r", ls="--", lw=0.8)
        a1.annotate("gap R: contact above", xy=(1.0, data.gap_mm), xycoords=("axes fraction", "data"),
                    xytext=(-4, 3), textcoords="offset points", ha="right", va="bottom", color="r", fontsize=8)
    a1.set_xlabel("time [s]")
    a1.set_ylabel("relative displacement x_b − x_s [mm]")
    a1.set_title("relative motion")
    a1.grid(alpha=0.3)
    a2.plot(data.relative_mm, data.relative_velocity, lw=0.8)
    a2.plot(data.window_points_mm, data.window_points_velocity, "r.", ms=8, label="Poincaré points")
    a2.set_xlabel("relative displacement x_b − x_s [mm]")
    a2.set_ylabel("relative velocity v_b − v_s [m/s]")
    a2.set_title("phase portrait of the relative motion")
    a2.legend(loc="best")
    a2.grid(alpha=0.3)
    a3.plot(data.section_mm, data.section_velocity, "k.", ms=4)
    a3.set_xlabel("relative displacement x_b − x_s [mm]")
    a3.set_ylabel("hammer velocity v_b [m/s]")
    a3.set_title(f"Poincaré section ({len(data.section_mm)} periods of the second half)")
    a3.grid(alpha=0.3)
    fig.suptitle(data.title)
    # fixed margins: tight_layout would draw the figure once more
    fig.subplots_adjust(left=0.065, right=0.985, bottom=0.07, top=0.9, wspace=0.2, hspace=0.3)
    fig.savefig(path, dpi=dpi)
    return path
