"""The map's best valid cell and its figure: never on a flagged cell or outside the paper's domain.

Oracle: the domain rules recomputed by the test from the axis values and the preset's mu
(a < b, a + b <= 1, b <= mu), and the scene flags of each cell.
"""
from __future__ import annotations

import numpy as np
import pytest

from hammerbit.model.presets import preset
from hammerbit.studies.executor import ExecutorOptions
from hammerbit.studies.map import FLAG_FIELDS, Axis, best_valid_cell, regime_map


@pytest.fixture(scope="module")
def fig12_map():
    # the fastest valid cells of this grid have a + b > 1 and tension
    return regime_map(preset("paper-fig12"), [Axis.parse("a=0.05:0.6:4"), Axis.parse("b=0.3:0.9:4")],
                      periods=40, options=ExecutorOptions(workers=1))


def _allowed(ds):
    g = preset("paper-fig12")
    a = ds["a"].values[:, None]
    b = ds["b"].values[None, :]
    inside = (a < b) & (a + b <= 1.0) & (b <= g.mu)
    unflagged = np.ones(inside.shape, dtype=bool)
    for f in FLAG_FIELDS:
        unflagged &= ds[f].values == 0
    return inside & unflagged & (ds["valid"].values == 1)


def test_best_cell_is_the_fastest_unflagged_cell_inside_the_domain(fig12_map):
    ds = fig12_map
    ok = _allowed(ds)
    rop = ds["rop_m_per_h"].values
    valid = ds["valid"].values == 1
    # the case of issue 33: the fastest valid cell is flagged or outside the domain
    k = np.unravel_index(np.nanargmax(np.where(valid, rop, np.nan)), rop.shape)
    assert not ok[k]
    best = best_valid_cell(ds)
    i, j = best["index"]
    assert ok[i, j]
    assert best["rop_m_per_h"] == np.nanmax(np.where(ok, rop, np.nan))


def test_map_figure_star_and_flag_legend(fig12_map, tmp_path, monkeypatch):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from hammerbit.studies.plots import plot_map
    figs = []
    monkeypatch.setattr(plt, "close", lambda fig=None: figs.append(fig))
    plot_map(fig12_map, tmp_path / "map.png")
    ax = figs[-1].axes[0]
    star = [ln for ln in ax.get_lines() if ln.get_gid() == "best-valid-cell"]
    assert len(star) == 1
    x, y = star[0].get_xdata()[0], star[0].get_ydata()[0]
    i = int(np.argmin(abs(fig12_map["a"].values - y)))
    j = int(np.argmin(abs(fig12_map["b"].values - x)))
    assert _allowed(fig12_map)[i, j]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("tension" in t for t in labels)
    assert any("outside the paper's domain" in t for t in labels)
    hatches = {h.get_hatch() for h in ax.get_legend().legend_handles if hasattr(h, "get_hatch")}
    assert len(hatches - {None}) >= 2
