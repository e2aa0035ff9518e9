"""The one description of the FMUs (hammerbit.model.fmu_description) and its C form (hb_description.h).

The SI -> groups formulas are written once; Python evaluates them and the build writes them out
as C.  The C form, compiled with the native build's flags, must give the same bits as Python
over random rig parameters, and the codes in C must be those of Python.
"""
from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest

from hammerbit.fmu.c_description import c_formula, description_header, write_description_header
from hammerbit.fmu.native_build import C_FLAGS
from cached_compile import compile_c
from hammerbit.model import fmu_description as D
from hammerbit.model.params import RigParameters

HARNESS = r"""
#include <stdio.h>
#include "hb_description.h"
int main(void) {
    double si[HB_N_SI], sc[HB_N_SCALES], g[HB_NGROUPS];
    while (fread(si, sizeof(double), HB_N_SI, stdin) == HB_N_SI) {
        hb_si_to_groups(si, sc, g);
        fwrite(sc, sizeof(double), HB_N_SCALES, stdout);
        fwrite(g, sizeof(double), HB_NGROUPS, stdout);
    }
    return 0;
}
"""


def _random_rigs(n: int, seed: int = 7) -> np.ndarray:
    """n rows of SI parameters (SI_NAMES order), log-uniform over wide ranges, mu_d <= mu_e."""
    rng = np.random.default_rng(seed)

    def logu(lo, hi):
        return np.exp(rng.uniform(math.log(lo), math.log(hi), n))

    mu_e = logu(0.05, 2.0)
    cols = {"hammer_mass": logu(1e-2, 1e4), "bit_mass": logu(1e-2, 1e4), "stiffness": logu(1.0, 1e9),
            "damping": logu(1e-3, 1e5), "mu_static": mu_e, "mu_kinetic": mu_e * rng.uniform(0.01, 1.0, n),
            "friction_decay": logu(1e-3, 1e3), "normal_force": logu(1e-1, 1e6),
            "contact_stiffness": logu(1.0, 1e12), "contact_exponent": rng.uniform(0.5, 5.0, n),
            "contact_damping": logu(1e-3, 1e2), "gap": logu(1e-6, 1e-1), "preload": rng.normal(0, 1e3, n),
            "amplitude": logu(1e-2, 1e4), "frequency": logu(1e-1, 1e3), "phase": rng.uniform(-10, 10, n)}
    cols["gap"][:5] = math.inf      # no impact device
    return np.column_stack([cols[k] for k in D.SI_NAMES])


def _python(rows: np.ndarray) -> np.ndarray:
    out = []
    for row in rows:
        sc, g = D.si_to_groups(dict(zip(D.SI_NAMES, row.tolist())))
        out.append([sc[n] for n, _ in D.SCALE_FORMULAS] + [g[n] for n, _ in D.GROUP_FORMULAS])
    return np.array(out)


@pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")
def test_c_formulas_give_the_bits_of_python(tmp_path):
    write_description_header(tmp_path)
    (tmp_path / "harness.c").write_text(HARNESS)
    exe = tmp_path / "harness"
    compile_c(["cc", *C_FLAGS, "-I", str(tmp_path), "-o", str(exe), str(tmp_path / "harness.c"), "-lm"], exe, tmp_path)
    rows = _random_rigs(3000)
    out = subprocess.run([str(exe)], input=rows.tobytes(), capture_output=True, check=True).stdout
    c = np.frombuffer(out, dtype=np.float64).reshape(len(rows), -1)
    py = _python(rows)
    assert c.shape == py.shape
    differ = np.argwhere(c.view(np.uint64) != py.view(np.uint64))
    names = [n for n, _ in D.SCALE_FORMULAS] + [n for n, _ in D.GROUP_FORMULAS]
    assert not len(differ), (f"{len(differ)} values differ in their bits, first: {names[differ[0][1]]} of row "
                             f"{differ[0][0]}: C {c[tuple(differ[0])]!r}, Python {py[tuple(differ[0])]!r}")


def test_to_groups_evaluates_the_description_and_matches_the_paper():
    """RigParameters.to_groups is the description's formulas; the paper's definitions (section 2,
    written out here) agree to rounding."""
    rig = RigParameters(contact_stiffness=3.0e8, gap=2e-3, damping=12.0, friction_decay=150.0)
    g = rig.to_groups()
    _, want = D.si_to_groups({n: getattr(rig, n) for n in D.SI_NAMES})
    assert g.values() == want
    m1, K, F0 = rig.hammer_mass, rig.stiffness, rig.mu_static * rig.normal_force
    Om, x0 = math.sqrt(K / m1), F0 / K
    paper = {"rho": rig.bit_mass / m1, "xi": rig.damping / (2 * math.sqrt(K * m1)),
             "eta": 2 * math.pi * rig.frequency / Om, "a": rig.amplitude / F0, "b": rig.preload / F0,
             "r": rig.gap / x0, "mu": rig.mu_kinetic / rig.mu_static,
             "gamma_hat": rig.friction_decay * x0 * Om, "kc": rig.contact_stiffness * x0 ** 1.3 / F0,
             "n": 1.3, "lam_hat": rig.contact_damping * x0 * Om, "phi": rig.phase}
    for name, value in paper.items():
        assert want[name] == pytest.approx(value, rel=4e-16), name


def test_a_formula_with_a_wrong_arity_is_refused():
    with pytest.raises(ValueError, match="sqrt takes 1 operands"):
        D.evaluate(("sqrt", 1.0, 2.0), {})
    with pytest.raises(ValueError, match="div takes 2 operands"):
        c_formula(("div", "x"), {"x": "x"})


def test_every_formula_reads_only_known_names():
    known = set(D.SI_NAMES)
    for name, expr in D.SCALE_FORMULAS:
        assert D.formula_names(expr) <= known, name
        known.add(name)
    for name, expr in D.GROUP_FORMULAS:
        assert D.formula_names(expr) <= known, name


def test_codes_in_c_are_those_of_python():
    text = description_header()
    for top in D.TOP_CONDITIONS:
        assert f"#define HB_TOP_{top.name.upper().replace('-', '_')} {top.code}\n" in text
    for name, bit in D.REGIME_BITS.items():
        assert f"#define HB_REGIME_{name.upper()} {bit}\n" in text
    assert [t.code for t in D.TOP_CONDITIONS] == list(range(len(D.TOP_CONDITIONS)))
    assert D.top_condition("feed").code == 1 and D.top_condition(2).name == "auto-driller"
    with pytest.raises(ValueError, match=r"known: 0 \(fixed\), 1 \(feed\), 2 \(auto-driller\)"):
        D.top_condition("hover")
