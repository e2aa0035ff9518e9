"""Figures and tables for docs/drillstring.md.

Run from the repository root::

    python docs/make_string_figures.py            # figures into a scratch directory
    python docs/make_string_figures.py --update   # refresh docs/figures/string_*.png

Prints the tables quoted in the document (closed-form errors, convergence
orders, check verdicts, windows).  The tracked figures are written only with
``--update``.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hammerbit.drillstring import Boundary, DrillString, Section, exact_frequencies, load_string, modes  # noqa: E402
from hammerbit.check.frequency import CheckConfig, check, plot_check  # noqa: E402

FIGURES = Path(__file__).resolve().parent / "figures"
OUT = FIGURES


def closed_form_table(field: DrillString) -> None:
    print("\n## closed-form errors, field-2200m, default mesh (mixed mass)\n")
    print("| top | bottom | exact f1..f4 [Hz] | max rel. error | max estimate |")
    print("|---|---|---|---|---|")
    pairs = [("fixed", "free"), ("fixed", "fixed"), ("free", "free"), ("free", "fixed"),
             ("fixed", "spring:5e8"), ("fixed", "mass:20000"), ("spring:2e7", "free"), ("spring:2e7", "spring:5e8")]
    for top, bot in pairs:
        ex = exact_frequencies(field, top, bot, 4)
        m = modes(field, top, bot, count=4)
        fe = m.frequencies_hz
        err = np.max(np.abs(fe[ex > 0] / ex[ex > 0] - 1))
        print(f"| {top} | {bot} | {', '.join(f'{x:.4f}' for x in ex)} | {err:.1e} | "
              f"{np.max(m.error_estimate):.1e} |")
    lab = DrillString((Section("rod", 3.0, 0.025, 0.0), Section("holder", 0.25, 0.08, 0.02)), name="lab3",
                      top=Boundary.spring(2e4), bottom=Boundary.free(2.5))
    print("\n## lab string (3 m rod, 0.25 m holder, 2.5 kg bit), default settings, modes 1-8\n")
    print("| top | bottom | elements | f8 [Hz] | max rel. error | max estimate |")
    print("|---|---|---|---|---|---|")
    for top, bot in [("spring:2e4", None), ("spring:2e4", "spring:5e6"), ("fixed", None), ("fixed", "spring:5e6")]:
        ex = exact_frequencies(lab, top, bot, 8)
        m = modes(lab, top, bot, count=8)
        err = np.max(np.abs(m.frequencies_hz / ex - 1))
        print(f"| {top} | {m.bottom.spec()} | {m.elements_per_section} | {ex[-1]:.1f} | {err:.1e} | "
              f"{np.max(m.error_estimate):.1e} |")
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
    heavy = field.replace(sections=(field.sections[0], Section("heavy collars", 200.0, 0.1651, 0.0714375,
                                                                linear_mass=250.0)))
    print("\n## convergence (mode 3, observed order between the last two meshes)\n")
    for ax, (s, top, bot, title) in zip(axes, [
            (heavy, "fixed", "free", "pipe over heavy collars (unequal h/c), mode 3"),
            (field, "fixed", "mass:20000", "field-2200m with a 20 t point mass, mode 3")]):
        ex = exact_frequencies(s, top, bot, 3)[2]
        for mass, correct, style in (("lumped", False, "o-"), ("consistent", False, "s-"),
                                     ("mixed", False, "v-"), ("mixed", True, "^-")):
            err = np.array([abs(modes(s.with_elements(cnt), top, bot, count=3, mass=mass, rtol=None,
                                      correct=correct).frequencies_hz[2] / ex - 1) for cnt in counts])
            p = math.log2(err[-2] / err[-1])
            name = f"{mass}{' + impedance correction' if correct else ''}"
            ax.loglog(n_el, err, style, label=f"{name} (order {p:.2f})")
            print(f"{title:50s} {name:35s} order {p:.2f}")
        ax.loglog(n_el, 0.5 * (n_el / n_el[0]) ** -2.0 * 1e-1, "k:", lw=0.8, label="slope -2")
        ax.loglog(n_el, 0.5 * (n_el / n_el[0]) ** -4.0 * 1e-2, "k--", lw=0.8, label="slope -4")
        ax.set_xlabel("elements")
        ax.set_ylabel("relative frequency error")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(OUT / "string_convergence.png", dpi=120)
    plt.close(fig)


def mode_shape_figure(field: DrillString) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5), sharey=True)
    for ax, (bot, title) in zip(axes, [("free", "bit off bottom (free)"),
                                       (field.on_bottom, "bit on bottom (rock spring 5e8 N/m)")]):
        m = modes(field, "fixed", bot, count=4, rtol=None)
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
        ("string_check_field_nominal_only.png", field,
         CheckConfig(excitation_hz=5.2, frequency_range_hz=(4.0, 7.0)), None),
        ("string_check_field_hammer_band.png", field,
         CheckConfig(excitation_hz=30.0, frequency_range_hz=(15.0, 50.0), min_window=0.0), None),
    ]
    print("\n## check verdicts\n")
    print("| string | excitation | verdict | rule | on bottom | off bottom |")
    print("|---|---|---|---|---|---|")
    for name, s, cfg, rpm_max in cases:
        r = check(s, cfg)
        plot_check(r, OUT / name, rpm_max=rpm_max)
        exc = f"{cfg.rpm:g} rpm x {cfg.factor:g} = {r.excitation_hz:.3g} Hz" if cfg.rpm else f"{r.excitation_hz:g} Hz"
        per = {c.name: f"{c.verdict}, {c.regime}, R = {c.resonance_factor:.2g}; nearest mode "
               f"{c.nearest.index} at {c.nearest.frequency_hz:.4g} Hz ({c.nearest.separation_pct:+.1f} %)"
               for c in r.configurations}
        print(f"| {s.name} | {exc} | **{r.verdict_label}** | {r.rule} | {per['on_bottom']} | {per['off_bottom']} |")
        print(f"\n    {name}: {r.reason}\n")
        k = None if cfg.rpm is None else 60.0 / cfg.factor
        for w in r.windows:
            rpm = "" if k is None else f" ({w.lo_hz * k:.0f}-{w.hi_hz * k:.0f} rpm)"
            print(f"    window {w.lo_hz:.2f}-{w.hi_hz:.2f} Hz{rpm}: {w.label}")


def main(argv=()) -> None:
    global OUT
    ap = argparse.ArgumentParser(description="figures and tables of docs/drillstring.md")
    ap.add_argument("--update", action="store_true", help="write into docs/figures (tracked files)")
    ap.add_argument("--out", default=None, help="write the figures here instead")
    args = ap.parse_args(list(argv))
    OUT = FIGURES if args.update else Path(args.out or tempfile.mkdtemp(prefix="string_figures_"))
    OUT.mkdir(parents=True, exist_ok=True)
    field = load_string("field-2200m")
    closed_form_table(field)
    convergence_figure(field)
    mode_shape_figure(field)
    checks()
    print(f"figures written to {OUT}")


if __name__ == "__main__":
    import sys
    main(sys.argv[1:])
