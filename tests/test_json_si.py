"""Every SI field of the JSON outputs, recomputed from its nondimensional source with the scales.

The conversions are written out here from the model's definitions, not taken from the code:
``x0 = F0 / K``, ``Omega = sqrt(K / m1)``, ``t = tau / Omega``, forcing frequency
``f = eta Omega / 2 pi``, forces in ``F0``, lengths in ``x0``; m/h = m per forcing period times
``3600 f``.  Every numeric leaf whose key names an SI unit must be recomputed below or be listed
in an ``EXEMPT`` table with the reason it has no nondimensional source (a measured time, a
figure only in newtons).
"""
from __future__ import annotations

import json
import math

import pytest

from cli_run import run_cli

#: Key endings (and whole keys) that name an SI unit.
SI_SUFFIXES = ("_n", "_m", "_mm", "_s", "_hz", "_kg", "_m_per_s", "_m_per_h", "_rad_per_s", "_n_per_m", "_j",
               "_mm_per_period")
SI_KEYS = {"mm_per_period", "m_per_h"}

M1, K, FN, MU_E = 40.0, 3000.0, 100.0, 0.6          # scales set on the command line: m1, K, F_N, mu_e
F0 = MU_E * FN
X0 = F0 / K
OMEGA = math.sqrt(K / M1)


def _si_leaves(d, path=()):
    """Paths of numeric leaves (lists of numbers included) whose key names an SI unit."""
    if isinstance(d, dict):
        for k, v in d.items():
            key = str(k)
            if isinstance(v, (dict, list)) and not _numbers(v):
                yield from _si_leaves(v, path + (key,))
            elif (key.endswith(SI_SUFFIXES) or key in SI_KEYS) and (_numbers(v) or isinstance(v, (int, float))):
                if not isinstance(v, bool):
                    yield path + (key,)
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from _si_leaves(v, path + (i,))


def _numbers(v):
    if isinstance(v, list):
        return bool(v) and all(_numbers(x) or x is None or isinstance(x, (int, float)) for x in v)
    return False


def _get(d, path):
    for p in path:
        d = d[p]
    return d


def _flat(v):
    if isinstance(v, list):
        for x in v:
            yield from _flat(x)
    else:
        yield v


def _close(a, b, rel=1e-12):
    for x, y in zip(_flat(a), _flat(b)):
        if x is None or y is None:
            assert x is None and y is None
        else:
            assert x == pytest.approx(y, rel=rel, abs=1e-300), (x, y)


SCALES = ["--set", f"m1={M1}", "--set", f"K={K}", "--set", f"F_N={FN}", "--set", f"mu_e={MU_E}"]
SCENE = ["--set", "a=0.2", "--set", "b=0.25", "--set", "r=0.5"]


def _scales_checked(d, seen):
    s = d["scales"]
    _close([s["hammer_mass_kg"], s["stiffness_n_per_m"], s["friction_force_n"]], [M1, K, F0])
    _close([s["length_m"], s["omega_rad_per_s"], s["velocity_m_per_s"]], [X0, OMEGA, X0 * OMEGA])
    seen.update(("scales", k) for k in s)


def test_simulate_json_si_fields(capsys):
    # a scene that drills, with tension and impacts: every source below is non-zero
    code, out, err = run_cli(["simulate", "--preset", "paper-fig9", *SCALES, *SCENE, "--periods", "30", "--json"],
                             capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["penetration_x0"] > 0 and d["rop"]["x0_per_period"] > 0 and d["scene_flags"]["min_drive_f0"] < 0
    assert d["peak_contact_force_n"] > 0
    g = d["groups"]
    seen = set()
    _scales_checked(d, seen)
    Tf = 2 * math.pi / (g["eta"] * OMEGA)
    expect = {
        ("time_s",): d["periods"] * Tf,
        ("forcing_period_s",): Tf,
        ("frequency_hz",): g["eta"] * OMEGA / (2 * math.pi),
        ("preload_n",): g["b"] * F0,
        ("amplitude_n",): g["a"] * F0,
        ("penetration_m",): d["penetration_x0"] * X0,
        ("penetration_mm",): d["penetration_x0"] * X0 * 1e3,
        ("penetration_per_period_mm",): d["penetration_per_period_x0"] * X0 * 1e3,
        ("rop", "mm_per_period"): d["rop"]["x0_per_period"] * X0 * 1e3,
        ("rop", "m_per_h"): d["rop"]["x0_per_period"] * X0 * 3600.0 / Tf,
        ("scene_flags", "min_drive_n"): d["scene_flags"]["min_drive_f0"] * F0,
    }
    for path, v in expect.items():
        _close(_get(d, path), v)
    seen.update(expect)
    # the peak contact force: the library's nondimensional figure of the same scene, in F0
    from hammerbit.model.presets import preset
    from hammerbit.model.settings import apply_settings
    from hammerbit.scene.simulate import simulate
    gs = apply_settings(preset("paper-fig9"), {"m1": M1, "K": K, "F_N": FN, "mu_e": MU_E, "a": 0.2, "b": 0.25,
                                               "r": 0.5})
    _close(d["peak_contact_force_n"], simulate(gs, 30).peak_contact_force * F0, rel=1e-9)
    seen.add(("peak_contact_force_n",))
    EXEMPT = {("wall_time_s",): "measured wall time"}
    missing = [p for p in _si_leaves(d) if p not in seen and p not in EXEMPT]
    assert not missing, f"SI fields with no recomputation here: {missing}"


def test_map_json_si_fields(capsys):
    code, out, err = run_cli(["map", "--preset", "paper-fig9", *SCALES, *SCENE, "--axis", "f=1.0:2.0:3",
                              "--periods", "20", "--workers", "1", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    seen = set()
    _scales_checked(d, seen)
    f = d["axes"][0]["values"]                      # Hz: the forcing frequency of each cell
    x = d["rop_x0_per_period"]
    _close(d["rop_mm_per_period"], [v * X0 * 1e3 for v in x])
    _close(d["rop_m_per_h"], [v * X0 * 3600.0 * fi for v, fi in zip(x, f)])
    assert max(x) > 0 and min(d["min_drive_f0"]) < 0
    _close(d["min_drive_n"], [v * F0 for v in d["min_drive_f0"]])
    seen.update({("rop_mm_per_period",), ("rop_m_per_h",), ("min_drive_n",)})
    best = d["best_valid_cell"]
    if best is not None:
        i = best["index"][0]
        _close([best["rop_mm_per_period"], best["rop_m_per_h"]],
               [x[i] * X0 * 1e3, x[i] * X0 * 3600.0 * f[i]])
        seen.update({("best_valid_cell", "rop_mm_per_period"), ("best_valid_cell", "rop_m_per_h")})
    EXEMPT = {("wall_time_s",): "measured wall time",
              ("peak_contact_force_n",): "in newtons only (no F0 field in the map's JSON)",
              ("peak_contact_force_steady_n",): "in newtons only"}
    missing = [p for p in _si_leaves(d) if p not in seen and p not in EXEMPT]
    assert not missing, f"SI fields with no recomputation here: {missing}"


def test_optimize_json_si_fields(capsys):
    code, out, err = run_cli(["optimize", "--preset", "paper-fig9", *SCALES, "--bounds", "frequency=1.0:2.0",
                              "--grid", "3", "--periods", "20", "--workers", "1", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    points = [d["optimum"], d["best_grid_cell"], *d["runners_up"]]
    for p in points:
        _close([p["frequency_hz"], p["amplitude_n"], p["preload_n"]],
               [p["eta"] * OMEGA / (2 * math.pi), p["a"] * F0, p["b"] * F0])
        _close(p["rop_m_per_h"], p["rop_mm_per_period"] * 1e-3 * 3600.0 * p["frequency_hz"])
        _close(p["margins"]["threshold"]["margin"], (1.0 - p["a"] - p["b"]) * F0)
        _close(p["values"]["frequency"], p["frequency_hz"])


def test_cosim_json_si_fields(capsys):
    """The co-simulation's figures are SI at the source; those derived from the hammer's scales
    and the top's rate are recomputed."""
    code, out, err = run_cli(["cosim", "--string", "lab", "--stop", "0.05", "--top", "feed:3", "--json"], capsys)
    assert code in (0, 5), err
    d = json.loads(out)
    from hammerbit.model.presets import RIG                   # the lab string's hammer: the paper's rig
    x0 = RIG.scales.friction_force / RIG.stiffness
    _close(d["error_estimate"]["penetration_floor_m"], 1e-2 * x0)
    _close(d["top"]["feed_m_per_h"], d["top"]["feed_velocity_m_per_s"] * 3600.0)
    _close(d["top"]["feed_m_per_h"], 3.0)
    _close(d["wob_static_n"], RIG.preload)
