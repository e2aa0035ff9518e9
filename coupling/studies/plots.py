"""Figures of the studies (matplotlib, Agg backend)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["plot_map", "PERIOD_COLORS", "FLAG_HATCHES"]

#: Colours of period-n, one hue each: period-1 (the paper's "regions with period-1 behaviour")
#: green, then blue, orange, purple, brown, pink (tab10, no two alike).
PERIOD_COLORS = {1: "#2ca02c", 2: "#1f77b4", 3: "#ff7f0e", 4: "#9467bd", 5: "#8c564b", 6: "#e377c2"}
_HIGHER = "#bcbd22"      # period-n above 6
_NONE = "#525252"        # no period up to 32 (quasi-periodic, chaotic, not settled)
_FAILED = "#ffffff"
_STUCK = "#d9f0d3"       # period-1 with the bit stuck: no penetration

#: Group -> (SI label, factor from the scene's scales) for a secondary SI axis.
_SI_OF_GROUP = {
    "a": ("A [N]", lambda s: s["friction_force_n"]),
    "b": ("B [N]", lambda s: s["friction_force_n"]),
    "eta": ("f [Hz]", lambda s: s["omega_rad_per_s"] / (2 * np.pi)),
    "r": ("R [mm]", lambda s: s["length_m"] * 1e3),
}

_SI_LABEL = {"1": ""}


def _label(ds, name: str) -> str:
    unit = ds[name].attrs.get("units", "")
    return f"{name} [{unit}]" if unit and unit != "1" else f"{name} [-]"


def _codes(period: np.ndarray, status: np.ndarray, rop: np.ndarray):
    """Integer classes for the colour map and their colours/labels."""
    keys, colors, labels = [], [], []
    code = np.zeros(period.shape, dtype=int)
    present = sorted({int(p) for p in period[np.isfinite(period)]})
    scale = np.nanmax(np.abs(rop)) if np.isfinite(rop).any() else 0.0
    stuck = np.isfinite(period) & (period == 1) & (np.abs(np.nan_to_num(rop)) <= 1e-9 * max(scale, 1e-300))
    classes = [("P1, bit stuck (no drilling)", _STUCK, stuck)] if stuck.any() else []
    classes += [(f"P{p}", PERIOD_COLORS.get(p, _HIGHER), (np.isfinite(period) & (period == p) & ~stuck))
                for p in present if p <= 6]
    hi = np.isfinite(period) & (period > 6)
    if hi.any():
        classes.append(("P7-32", _HIGHER, hi))
    none = ~np.isfinite(period) & (status == 0)
    if none.any():
        classes.append(("none up to 32", _NONE, none))
    bad = status != 0
    if bad.any():
        classes.append(("did not run", _FAILED, bad))
    for i, (lab, col, mask) in enumerate(classes):
        code[mask] = i
        keys.append(i)
        colors.append(col)
        labels.append(lab)
    return code, colors, labels


#: Hatches of the cells that are not drilling points or carry a flag, by what they are.
FLAG_HATCHES = (("runaway or bounce (not valid)", "//"), ("tension (drive below zero)", "\\\\"),
                ("other flag of the scene", "++"), ("outside the paper's domain (a >= b, a + b > 1, b > mu)", ".."))


def _flag_marks(sel, valid: np.ndarray, status: np.ndarray) -> list:
    """``(label, hatch, mask)`` of each kind of flagged cell present (cells that ran); the
    transient flag is drawn apart (dots)."""
    from .map import DOMAIN_FIELDS, FLAG_FIELDS
    ran = status == 0
    kinds = dict(FLAG_HATCHES)
    other = np.zeros(valid.shape, dtype=bool)
    for name in FLAG_FIELDS:
        if name not in ("runaway", "bounce", "tension", "transient") and name in sel:
            other |= sel[name].values == 1
    outside = np.zeros(valid.shape, dtype=bool)
    for name in DOMAIN_FIELDS.values():
        if name in sel:
            outside |= sel[name].values == 1
    tension = sel["tension"].values == 1 if "tension" in sel else np.zeros(valid.shape, dtype=bool)
    masks = [("runaway or bounce (not valid)", ~valid & ran), ("tension (drive below zero)", tension & ran),
             ("other flag of the scene", other & ran),
             ("outside the paper's domain (a >= b, a + b > 1, b > mu)", outside & ran)]
    return [(label, kinds[label], m) for label, m in masks if m.any()]


def plot_map(ds, path, *, rop_levels: int = 8, overlay=None):
    """Period map coloured by period-n (period-1 green) with ROP contours [m/h].

    One axis: period-n and ROP against it.  Two axes: the map.  Three axes:
    the map over the first two at the middle value of the third.  Cells the
    scene's dynamics make invalid (runaway, bounce), cells with tension or
    another flag, and cells outside the paper's domain are hatched, each kind
    its own way (:data:`FLAG_HATCHES`), with a legend; the ROP contours use
    valid cells, the star the best unflagged cell inside the domain
    (:func:`~hammerbit.studies.map.eligible_cells`).  ``overlay``: curves of
    ``hammerbit continue --json`` drawn over a map of their two parameters.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    from .map import best_valid_cell, eligible_cells
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    dims = list(ds["period"].dims)
    title = f"{ds.attrs.get('preset', '')} map, {ds.attrs.get('periods')} periods per cell".strip()
    sel = ds
    if len(dims) == 3:
        mid = ds[dims[2]].values[len(ds[dims[2]]) // 2]
        sel = ds.isel({dims[2]: len(ds[dims[2]]) // 2})
        title += f", {dims[2]} = {mid:g}"
        dims = dims[:2]
    scales = json.loads(ds.attrs.get("scales", "{}"))
    if len(dims) == 1:
        x = sel[dims[0]].values
        fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        per = sel["period"].values
        ax[0].plot(x, per, "k.")
        ax[0].set_ylabel("period-n")
        rop1 = sel["rop_m_per_h"].values
        ok = eligible_cells(sel)
        ax[1].plot(x, np.where(sel["valid"].values == 1, rop1, np.nan), ".-", label="valid cells")
        if (~ok & (sel["status"].values == 0)).any():
            ax[1].plot(x[~ok], rop1[~ok], "rx", label="flagged or outside the paper's domain")
        if ok.any() and np.isfinite(rop1[ok]).any():
            k = int(np.nanargmax(np.where(ok, rop1, np.nan)))
            ax[1].plot([x[k]], [rop1[k]], marker="*", ms=14, mfc="gold", mec="k", ls="none",
                       label=f"best valid cell, {rop1[k]:.3g} m/h")
        ax[1].legend(fontsize=8)
        ax[1].set_ylabel("ROP [m/h]")
        ax[1].set_xlabel(_label(sel, dims[0]))
        ax[0].set_title(title, fontsize=10)
        fig.tight_layout()
        fig.savefig(path, dpi=130)
        plt.close(fig)
        return path
    xn, yn = dims[1], dims[0]            # rows: first axis on y; columns: second on x
    x, y = sel[xn].values, sel[yn].values
    per = sel["period"].values
    status = sel["status"].values
    code, colors, labels = _codes(per, status, sel["rop_m_per_h"].values)
    fig, ax = plt.subplots(figsize=(9, 6.5))
    ax.pcolormesh(x, y, code, cmap=ListedColormap(colors), vmin=-0.5, vmax=len(colors) - 0.5,
                  shading="nearest")
    valid = sel["valid"].values == 1
    marks = _flag_marks(sel, valid, status)
    for _, hatch, mask in marks:
        ax.contourf(x, y, mask.astype(float), levels=[0.5, 1.5], colors="none", hatches=[hatch])
    # contours and the best cell from valid cells only: a runaway cell's ROP is no drilling rate
    rop = np.where(valid, sel["rop_m_per_h"].values, np.nan)
    if np.isfinite(rop).sum() > 3 and np.nanmax(rop) > np.nanmin(rop):
        cs = ax.contour(x, y, rop, levels=rop_levels, colors="k", linewidths=0.7)
        ax.clabel(cs, fmt="%.3g m/h", fontsize=7)
    handles = [Patch(facecolor=c, edgecolor="0.5", label=l) for c, l in zip(colors, labels)]
    handles += [Patch(facecolor="none", hatch=hatch, edgecolor="k", label=label) for label, hatch, _ in marks]
    handles.append(plt.Line2D([], [], color="k", lw=0.7, label="ROP contours [m/h], valid cells"))
    trans = sel["transient"].values == 1
    if trans.any():
        ti, tj = np.nonzero(trans)
        ax.plot(x[tj], y[ti], ls="none", marker=".", ms=3, color="k")
        handles.append(plt.Line2D([], [], ls="none", marker=".", ms=5, color="k",
                                  label="period not settled (transient)"))
    best = best_valid_cell(sel)
    if best is not None:
        i, j = best["index"]
        ax.plot([x[j]], [y[i]], marker="*", ms=16, mfc="gold", mec="k", ls="none", gid="best-valid-cell")
        handles.append(plt.Line2D([], [], marker="*", ms=12, mfc="gold", mec="k", ls="none",
                                  label=f"best valid cell (unflagged, in the domain), {best['rop_m_per_h']:.3g} m/h"))
    if overlay:
        from hammerbit.continuation.output import draw_curves
        if draw_curves(ax, overlay, xn, yn):
            handles.append(plt.Line2D([], [], color="k", lw=2.0, label="bifurcation curves (continuation)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.12, 1.0), fontsize=8)
    ax.set_xlabel(_label(sel, xn))
    ax.set_ylabel(_label(sel, yn))
    const_scales = all(sel[d].attrs.get("units") == "1" for d in dims) and scales
    if const_scales:
        if xn in _SI_OF_GROUP:
            lab, fac = _SI_OF_GROUP[xn]
            k = fac(scales)
            sx = ax.secondary_xaxis("top", functions=(lambda v, k=k: v * k, lambda v, k=k: v / k))
            sx.set_xlabel(lab)
        if yn in _SI_OF_GROUP:
            lab, fac = _SI_OF_GROUP[yn]
            k = fac(scales)
            sy = ax.secondary_yaxis("right", functions=(lambda v, k=k: v * k, lambda v, k=k: v / k))
            sy.set_ylabel(lab)
    ax.set_title(title + "\nregions with period-1 behaviour in green", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
