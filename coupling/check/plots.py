"""Figures of the hammer-frequency check: frequency map or Campbell diagram, receptance and resonance factor.

A hammer's check (``--frequency``) shows the safe windows over the frequency
range with the modes below them; a rotary check (``--rpm``) shows the Campbell
diagram.  Only isolated modes get their +-margin band drawn: the bands of
crowded modes overlap and would cover the panel.

Safe windows are shaded by the rule that cleared them: green for the margin
rule (no band within +-margin), blue for the receptance rule over the whole
damping range, and hatched orange for a receptance pass at nominal damping
only.  The resonance factor is drawn at the nominal damping with a band
between the low and high ends of the damping range.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

__all__ = ["plot_campbell", "plot_frequency_map", "plot_receptance", "plot_check", "isolated_modes",
           "WINDOW_STYLE"]

#: Shading of the safe windows by label.
WINDOW_STYLE = {
    "margin": dict(color="tab:green", alpha=0.16, lw=0),
    "receptance": dict(color="tab:blue", alpha=0.16, lw=0),
    "receptance (nominal damping only)": dict(facecolor="none", edgecolor="tab:orange", hatch="///",
                                              alpha=0.7, lw=0),
}


#: Colour of the safe speed segments on the excitation line, by label.
_RPM_COLOR = {"margin": "tab:green", "receptance": "tab:blue", "receptance (nominal damping only)": "tab:orange"}


def _shade_windows(ax, result, vertical: bool = True, **span) -> None:
    seen = set()
    for w in result.windows:
        st = dict(WINDOW_STYLE[w.label])
        lab = None
        if w.label not in seen:
            seen.add(w.label)
            lab = f"safe: {w.label}"
        if vertical:
            ax.axvspan(w.lo_hz, w.hi_hz, label=lab, **st, **span)
        else:
            ax.axhspan(w.lo_hz, w.hi_hz, label=lab, **st, **span)


_COLORS = {"on_bottom": "tab:blue", "off_bottom": "tab:orange"}
_LABELS = {"on_bottom": "bit on bottom", "off_bottom": "bit off bottom"}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_campbell(result: CheckResult, ax=None, path: "str | Path | None" = None,
                  rpm_max: float | None = None):
    """Campbell-type diagram: natural frequencies with their +-margin bands
    (horizontal) against rotary speed, the excitation line(s) ``f = K N/60``
    (or the hammer frequency, with 1x and 3x rotary lines for reference), the
    operating point, and the safe windows.

    Returns the matplotlib Axes.
    """
    plt = _pyplot()
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(7, 5))
    c = result.config
    f_lo, f_hi = result.range_hz
    if rpm_max is None:
        rpm_max = (c.rpm_range[1] if (c.rpm is not None and c.rpm_range) else
                   2.0 * c.rpm if c.rpm is not None else 200.0)
    rpm = np.array([0.0, rpm_max])
    for cfg in result.configurations:
        col = _COLORS.get(cfg.name, "k")
        ls = "-" if cfg.name == "on_bottom" else "--"
        alone = isolated_modes(cfg.frequencies_hz, c.margin)
        for j, fn in enumerate(cfg.frequencies_hz):
            if fn <= 0 or fn * (1 - c.margin) > f_hi:
                continue
            if alone[j]:        # the bands of crowded modes overlap and would cover the whole panel
                ax.axhspan(fn * (1 - c.margin), fn * (1 + c.margin), color=col, alpha=0.07, lw=0)
            ax.axhline(fn, color=col, ls=ls, lw=0.8,
                       label=f"{_LABELS.get(cfg.name, cfg.name)} modes (+-{100 * c.margin:.0f} %)"
                       if j == int(np.argmax(cfg.frequencies_hz > 0)) else None)
    if c.rpm is not None:
        ax.plot(rpm, rpm / 60.0, color="0.4", lw=1, ls=":", label="1x rpm")
        ax.plot(rpm, c.factor * rpm / 60.0, color="k", lw=1.5, label=f"{c.factor:g}x rpm (excitation)")
        k = 60.0 / c.factor
        seen = set()
        for w in result.windows:
            lo, hi = w.lo_hz * k, min(w.hi_hz * k, rpm_max)
            ax.plot([lo, hi], [c.factor * lo / 60.0, c.factor * hi / 60.0], color=_RPM_COLOR[w.label], lw=5,
                    alpha=0.7, solid_capstyle="butt",
                    label=None if w.label in seen else f"safe speeds: {w.label}")
            seen.add(w.label)
        ax.plot([c.rpm], [result.excitation_hz], "o", ms=8,
                color="tab:red" if result.verdict == "fail" else "tab:green",
                label=f"operating point: {result.verdict_label}")
    else:
        for k, ls in ((1.0, ":"), (3.0, "-.")):
            ax.plot(rpm, k * rpm / 60.0, color="0.5", lw=0.8, ls=ls, label=f"{k:g}x rpm (bit, reference)")
        ax.axhline(result.excitation_hz, color="tab:red" if result.verdict == "fail" else "k", lw=1.8,
                   label=f"hammer {result.excitation_hz:g} Hz: {result.verdict_label}")
        _shade_windows(ax, result, vertical=False, xmin=0.93, xmax=1.0)
    ax.set_xlim(0, rpm_max)
    ax.set_ylim(f_lo if c.rpm is None else 0.0, f_hi)
    ax.set_xlabel("rotary speed [rpm]")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title(f"{result.string_name}: axial modes vs excitation")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    if own and path is not None:
        ax.figure.tight_layout()
        ax.figure.savefig(path, dpi=120)
        plt.close(ax.figure)
    return ax


def isolated_modes(frequencies_hz, margin: float) -> np.ndarray:
    """True for each mode whose band ``f (1 +- margin)`` touches neither neighbour's band."""
    f = np.asarray(frequencies_hz, dtype=float)
    lo, hi = f * (1 - margin), f * (1 + margin)
    ok = np.ones(f.size, dtype=bool)
    if f.size > 1:
        clash = hi[:-1] >= lo[1:]
        ok[:-1] &= ~clash
        ok[1:] &= ~clash
    return ok


#: Rows of the frequency map (hammer excitation): safe windows on top, then the two bit configurations.
_MAP_ROWS = {"windows": (1.0, 3.0), "on_bottom": (0.5, 1.0), "off_bottom": (0.0, 0.5)}


def plot_frequency_map(result: CheckResult, ax=None, path: "str | Path | None" = None):
    """The hammer check over its frequency range: the safe windows as the main content (top, tall,
    shaded by the rule that cleared them), the natural frequencies of each bit configuration below
    (a tick per mode; the +-margin band only around isolated modes, where the margin rule decides),
    and the excitation.  Returns the matplotlib Axes."""
    plt = _pyplot()
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(7, 5))
    c = result.config
    f_lo, f_hi = result.range_hz
    y0, y1 = _MAP_ROWS["windows"]
    seen = set()
    for w in result.windows:
        st = dict(WINDOW_STYLE[w.label])
        st["alpha"] = min(1.0, 3 * st.get("alpha", 0.3))
        ax.fill_between([w.lo_hz, w.hi_hz], y0, y1, label=None if w.label in seen else f"safe: {w.label}", **st)
        seen.add(w.label)
    if not result.windows:
        ax.text(0.5 * (f_lo + f_hi), 0.5 * (y0 + y1), "no safe window in this range", ha="center", va="center")
    for cfg in result.configurations:
        r0, r1 = _MAP_ROWS.get(cfg.name, (0.0, 0.5))
        col = _COLORS.get(cfg.name, "k")
        f = np.asarray(cfg.frequencies_hz, dtype=float)
        alone = isolated_modes(f, c.margin)
        sel = (f > 0) & (f * (1 + c.margin) >= f_lo) & (f * (1 - c.margin) <= f_hi)
        for fn, iso in zip(f[sel], alone[sel]):
            if iso:
                ax.fill_between([fn * (1 - c.margin), fn * (1 + c.margin)], r0, r1, color=col, alpha=0.15, lw=0)
        ax.vlines(f[sel], r0 + 0.05, r1 - 0.05, color=col, lw=1.0,
                  label=f"{_LABELS.get(cfg.name, cfg.name)}: {int(sel.sum())} mode{'' if sel.sum() == 1 else 's'}")
    ax.axvline(result.excitation_hz, color="tab:red" if result.verdict == "fail" else "k", lw=2,
               label=f"hammer {result.excitation_hz:g} Hz: {result.verdict_label}")
    ax.set_xlim(f_lo, f_hi)
    ax.set_ylim(0.0, y1 + 0.9)             # room for the legend above the windows
    ax.set_yticks([0.25, 0.75, 0.5 * (y0 + y1)], ["bit off bottom", "bit on bottom", "safe windows"])
    ax.set_xlabel("excitation frequency [Hz]")
    ax.set_title(f"{result.string_name}: safe windows and axial modes\n(+-{100 * c.margin:.0f} % bands shaded "
                 f"around isolated modes only)", fontsize=10)
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    if own and path is not None:
        ax.figure.tight_layout()
        ax.figure.savefig(path, dpi=120)
        plt.close(ax.figure)
    return ax


def plot_receptance(result: CheckResult, axes: Sequence | None = None, path: "str | Path | None" = None):
    """Bit receptance ``|H(f)|`` (log scale, with the reflection-free
    reference) and the resonance factor ``R(f)`` with its limit (bold where
    modes are crowded and the receptance rule applies, faint where the margin
    rule decides); excitation marked, safe windows shaded.  Returns the two
    Axes."""
    plt = _pyplot()
    own = axes is None
    if own:
        fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    ax1, ax2 = axes
    f = result.sweep_hz
    c = result.config
    for cfg in result.configurations:
        col = _COLORS.get(cfg.name, "k")
        h = result.sweep_receptance[cfg.name]
        ref = result.sweep_reference[cfg.name]
        lab = _LABELS.get(cfg.name, cfg.name)
        if cfg.excitation == "force":
            ax1.semilogy(f, h, color=col, lw=1, label=f"|H| {lab}")
            ax1.semilogy(f, ref, color=col, lw=0.8, ls=":", label=f"reflection-free {lab}")
        else:
            ax1.semilogy(f, 1.0 / h, color=col, lw=1, label=f"1/|D| {lab} (fixed bit)")
        r3 = result.sweep_factor[cfg.name]
        crowd = result.sweep_crowded[cfg.name]
        ax2.fill_between(f, np.minimum(r3[0], r3[2]), np.maximum(r3[0], r3[2]), color=col, alpha=0.15, lw=0,
                         label=f"{lab}: R over damping x{c.damping_range[0]:g}..x{c.damping_range[1]:g}")
        ax2.semilogy(f, r3[1], color=col, lw=0.6, alpha=0.35,
                     label=f"{lab} (faint: margin rule decides)")
        if np.any(crowd):
            ax2.semilogy(f, np.where(crowd, r3[1], np.nan), color=col, lw=1.2,
                         label=f"{lab} (bold: only crowded bands, receptance rule)")
    ax2.axhline(c.resonance_limit, color="tab:red", lw=1, ls="--", label=f"limit {c.resonance_limit:.3g}")
    _shade_windows(ax1, result)
    for ax in (ax1, ax2):
        ax.axvline(result.excitation_hz, color="k", lw=1.2)
    ax1.set_ylabel("bit receptance [m/N]")
    ax2.set_ylabel("resonance factor R [-]")
    ax2.set_xlabel("excitation frequency [Hz]")
    ax1.set_title(f"{result.string_name}: {result.excitation_hz:.4g} Hz -> {result.verdict_label} "
                  f"({result.rule} rule)", fontsize=10)
    ax1.legend(fontsize=7, loc="upper right")
    ax2.legend(fontsize=7, loc="upper right")
    ax2.set_xlim(f[0], f[-1])
    if own and path is not None:
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
    return axes


def plot_check(result: CheckResult, path: "str | Path", rpm_max: float | None = None) -> Path:
    """Campbell diagram and receptance plots side by side, saved to ``path`` (PNG/PDF/SVG)."""
    plt = _pyplot()
    fig = plt.figure(figsize=(13, 5.5))
    gs = fig.add_gridspec(2, 2, width_ratios=(1, 1.15))
    ax_c = fig.add_subplot(gs[:, 0])
    ax_h = fig.add_subplot(gs[0, 1])
    ax_r = fig.add_subplot(gs[1, 1], sharex=ax_h)
    if result.config.rpm is None:       # a hammer: its frequency does not follow the rotary speed
        plot_frequency_map(result, ax=ax_c)
    else:
        plot_campbell(result, ax=ax_c, rpm_max=rpm_max)
    plot_receptance(result, axes=(ax_h, ax_r))
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


