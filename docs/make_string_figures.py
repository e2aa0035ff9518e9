"""Figures and tables for docs/drillstring.md.

Run from the repository root::

    python docs/make_string_figures.py

Writes PNGs to docs/figures/ and prints the tables quoted in the document
(closed-form errors, convergence orders, check verdicts).
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hammerbit.drillstring import DrillString, exact_frequencies, load_string, modes  # noqa: E402
from hammerbit.modal_check import CheckConfig, check, plot_check  # noqa: E402

OUT = Path(__file__).resolve().parent / "figures"


def closed_form_table(field: DrillString) -> None:
    print("\n## closed-form errors, field-2200m, default mesh (mixed mass)\n")
    print("| top | bottom | exact f1..f4 [Hz] | max rel. error |")
    print("|---|---|---|---|")
    pairs = [("fixed", "free"), ("fixed", "fixed"), ("free", "free"), ("free", "fixed"),
             ("fixed", "spring:5e8"), ("fixed", "mass:20000"), ("spring:2e7", "free"), ("spring:2e7", "spring:5e8")]
    for top, bot in pairs:
        ex = exact_frequencies(field, top, bot, 4)
        fe = modes(field, top, bot, count=4).frequencies_hz
        err = np.max(np.abs(fe[ex > 0] / ex[ex > 0] - 1))
        print(f"| {top} | {bot} | {', '.join(f'{x:.4f}' for x in ex)} | {err:.1e} |")
    pipe = DrillString.uniform(2200.0, 0.127, 0.1086)
    c = pipe.sections[0].wave_speed
    ref = (2 * np.arange(1, 5) - 1) * c / (4 * 2200.0)
    f = modes(pipe, "fixed", "free", count=4).frequencies_hz
    print(f"\nuniform 2200 m drill pipe fixed-free: (2n-1)c/4L = {np.round(ref, 4)} Hz, "
          f"max rel. error {np.max(np.abs(f / ref - 1)):.1e}")


def convergence_figure(field: DrillString) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    counts = [(10, 1), (20, 2), (40, 4), (80, 8), (160, 16)]
    n_el = np.array([a + b for a, b in counts])
    print("\n## convergence (mode 3, observed order between the last two meshes)\n")
    for ax, (top, bot, title) in zip(axes, [("fixed", "free", "field-2200m fixed-free, mode 3"),
                                            ("fixed", "mass:20000", "with a 20 t point mass at the bit")]):
        ex = exact_frequencies(field, top, bot, 3)[2]
        for mass, style in (("lumped", "o-"), ("consistent", "s-"), ("mixed", "^-")):
            err = np.array([abs(modes(field.with_elements(cnt), top, bot, count=3, mass=mass).frequencies_hz[2]
                                / ex - 1) for cnt in counts])
            p = math.log2(err[-2] / err[-1])
            ax.loglog(n_el, err, style, label=f"{mass} (order {p:.2f})")
            print(f"{title:40s} {mass:10s} order {p:.2f}")
        ax.loglog(n_el, 0.5 * (n_el / n_el[0]) ** -2.0 * 1e-1, "k:", lw=0.8, label="slope -2")
        ax.loglog(n_el, 0.5 * (n_el / n_el[0]) ** -4.0 * 1e-2, "k--", lw=0.8, label="slope -4")
        ax.set_xlabel("elements")
        ax.set_ylabel("relative frequency error")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "string_convergence.png", dpi=120)
    plt.close(fig)


def mode_shape_figure(field: DrillString) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5), sharey=True)
    for ax, (bot, title) in zip(axes, [("free", "bit off bottom (free)"),
                                       (field.on_bottom, "bit on bottom (rock spring 5e8 N/m)")]):
        m = modes(field, "fixed", bot, count=4)
        for j in range(4):
            shape = m.shapes[:, j] / np.max(np.abs(m.shapes[:, j]))
            ax.plot(shape, m.z, label=f"{m.frequencies_hz[j]:.3f} Hz")
        ax.axhline(2000.0, color="0.6", lw=0.8, ls="--")
        ax.text(1.0, 1990.0, "pipe / collars", fontsize=8, color="0.4", va="bottom", ha="right")
        ax.set_title(title)
        ax.set_xlabel("normalised axial displacement")
        ax.legend(fontsize=8, loc="lower left")
    axes[0].set_ylabel("depth [m]")
    axes[0].invert_yaxis()
    fig.suptitle("field-2200m: first four axial modes (hook fixed)")
    fig.tight_layout()
    fig.savefig(OUT / "string_modes_field.png", dpi=120)
    plt.close(fig)


def checks() -> None:
    field, lab = load_string("field-2200m"), load_string("lab")
    cases = [
        ("string_check_lab_hammer.png", lab, CheckConfig(excitation_hz=1.47, frequency_range_hz=(0.0, 10.0)),
         None),
        ("string_check_field_lab_frequency.png", field,
         CheckConfig(excitation_hz=1.47, frequency_range_hz=(0.0, 4.0)), None),
        ("string_check_field_tricone.png", field, CheckConfig(rpm=120.0, factor=3.0, rpm_range=(0.0, 200.0)),
         200.0),
        ("string_check_field_hammer.png", field, CheckConfig(excitation_hz=20.0, frequency_range_hz=(0.0, 40.0)),
         None),
    ]
    print("\n## check verdicts\n")
    print("| string | excitation | verdict | rule | on bottom | off bottom | safe windows |")
    print("|---|---|---|---|---|---|---|")
    for name, s, cfg, rpm_max in cases:
        r = check(s, cfg)
        plot_check(r, OUT / name, rpm_max=rpm_max)
        exc = f"{cfg.rpm:g} rpm x {cfg.factor:g} = {r.excitation_hz:.3g} Hz" if cfg.rpm else f"{r.excitation_hz:g} Hz"
        per = {c.name: f"{c.verdict}, {c.regime}, R = {c.resonance_factor:.2g}; nearest mode "
               f"{c.nearest.index} at {c.nearest.frequency_hz:.3g} Hz ({c.nearest.separation_pct:+.1f} %)"
               for c in r.configurations}
        if r.safe_windows_rpm is not None:
            win = ", ".join(f"{a:.0f}-{b:.0f}" for a, b in r.safe_windows_rpm) + " rpm"
        else:
            win = ", ".join(f"{a:.2f}-{b:.2f}" for a, b in r.safe_windows_hz) + " Hz"
        print(f"| {s.name} | {exc} | **{r.verdict}** | {r.rule} | {per['on_bottom']} | {per['off_bottom']} | {win} |")
        print(f"\n    {name}: {r.reason}\n")


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    field = load_string("field-2200m")
    closed_form_table(field)
    convergence_figure(field)
    mode_shape_figure(field)
    checks()
    print(f"figures written to {OUT}")


if __name__ == "__main__":
    main()
