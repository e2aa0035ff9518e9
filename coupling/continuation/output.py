"""The outputs of a continuation: the JSON record, CSV and netCDF tables and the bifurcation-diagram figure (like the paper's Fig. 9)."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from hammerbit.model.fmu_variables import PARAMETERS  # the one table of SI units
from hammerbit.model.settings import setting_target

from .diagram import Diagram

__all__ = ["diagram_json", "write_csv", "write_netcdf", "draw_diagram", "CSV_COLUMNS"]


def _point_json(name: str, point) -> dict:
    orb = point.orbit
    ms, mc = orb.modes
    return {name: float(point.value), "state": [float(v) for v in orb.state] + [ms, mc],
            "multipliers": [[float(m.real), float(m.imag)] for m in orb.multipliers],
            "stable": bool(orb.stable), "rop_x0_per_period": float(orb.rop_x0_per_period)}


def diagram_json(d: Diagram) -> dict:
    """The diagram as the JSON of ``hammerbit continue --json`` (nondimensional, named as such).

    ``state`` is the orbit's state at phase 0 as the library's Stepper takes it:
    (x1, x2, x3 = 0, x4) in x0 and x0 Omega, then the stick/slip mode (0 stick,
    1 slip) and the contact mode (0 free, 1 contact, 2 clamped).
    """
    name = d.parameter
    return {
        "parameter": name, "range": [d.start, d.end],
        "state_layout": ["x1", "x2", "x3", "x4", "stick_slip_mode", "contact_mode"],
        "branches": [{"period": br.period, "points": [_point_json(name, p) for p in br.points],
                      "ended": br.ended, "stopped": br.stopped} for br in d.branches],
        "bifurcations": [{"kind": b.kind, name: float(b.value), "branch": b.branch, "detail": b.detail,
                          "state": [float(v) for v in b.orbit.state]} for b in d.bifurcations],
        "coexistence": [{"from": float(c["from"]), "to": float(c["to"]), "branches": c["branches"], "from_rest": c["from_rest"],
                         "from_rest_switch": c["from_rest_switch"]} for c in d.coexistence],
        "rest_runs": [{name: float(r.value), "period": r.period, "branch": r.branch} for r in d.rest_runs],
        "curves": [],
        "stops": list(d.stops),
    }


def _unit(name: str) -> str:
    """The SI unit of a ``--set`` name ('1' for a group)."""
    kind, target = setting_target(name)
    if kind == "group":
        return "1"
    return next((v.unit for v in PARAMETERS if v.name == target), "1")


#: the CSV's columns after the parameter's: (name, unit)
CSV_COLUMNS = (("branch", "1"), ("period", "forcing periods"), ("stable", "1"), ("max_multiplier", "1"),
               ("rop", "m/h"), ("penetration_per_period", "mm"))


def write_csv(d: Diagram, path) -> int:
    """One row per branch point, SI headers ``name [unit]``; returns the rows written."""
    rows = 0
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([f"{d.parameter} [{_unit(d.parameter)}]"] + [f"{n} [{u}]" for n, u in CSV_COLUMNS])
        for i, br in enumerate(d.branches):
            for p in br.points:
                r = p.orbit.groups.rop(p.orbit.rop_x0_per_period)
                w.writerow([repr(float(p.value)), i, br.period, int(p.orbit.stable),
                            repr(float(p.orbit.max_multiplier)), repr(float(r["m_per_h"])),
                            repr(float(r["mm_per_period"]))])
                rows += 1
    return rows


def write_netcdf(d: Diagram, path) -> None:
    """The branch points as a netCDF dataset (dimension ``point``), SI units in the attributes."""
    import xarray as xr
    pts = [(i, br.period, p) for i, br in enumerate(d.branches) for p in br.points]
    kmax = max((len(p.orbit.multipliers) for _, _, p in pts), default=0)
    mult = np.full((len(pts), kmax), np.nan + 0j)
    for j, (_, _, p) in enumerate(pts):
        mult[j, :len(p.orbit.multipliers)] = p.orbit.multipliers
    rop = [p.orbit.groups.rop(p.orbit.rop_x0_per_period) for _, _, p in pts]
    ds = xr.Dataset(
        {d.parameter: ("point", [p.value for _, _, p in pts], {"units": _unit(d.parameter)}),
         "branch": ("point", [i for i, _, _ in pts]),
         "period": ("point", [n for _, n, _ in pts], {"units": "forcing periods"}),
         "stable": ("point", [int(p.orbit.stable) for _, _, p in pts]),
         "multiplier_re": (("point", "multiplier"), mult.real),
         "multiplier_im": (("point", "multiplier"), mult.imag),
         "rop": ("point", [r["m_per_h"] for r in rop], {"units": "m/h"}),
         "state": (("point", "component"), np.array([p.orbit.state for _, _, p in pts]).reshape(-1, 4),
                   {"units": "x0, x0 Omega (nondimensional)"})},
        attrs={"parameter": d.parameter, "bifurcations": "; ".join(f"{b.kind} at {d.parameter} = {b.value:.9g} "
                                                                   f"(branch {b.branch})" for b in d.bifurcations)})
    ds.to_netcdf(path)


#: marker of each bifurcation kind in the figure
MARKERS = {"period-doubling": "o", "fold": "s", "neimark-sacker": "D", "grazing": "^", "sliding": "v",
           "bounce": "x", "tension": "<", "runaway": ">", "branch-end": "|", "border-collision": "P"}


def section_points(orbit) -> np.ndarray:
    """The hammer velocity [m/s] at the orbit's n Poincaré points (phase 0 of each forcing period)."""
    from .monodromy import period_map
    out = [orbit.s[1]]
    s = orbit.s
    for _ in range(orbit.period - 1):
        s = period_map(orbit.groups, s, 1, jacobian=False).s_end
        out.append(s[1])
    return np.array(out) * orbit.groups.scales.velocity


def _draw_branches(ax, d: Diagram, values_of) -> None:
    """Each branch's curves ``values_of(point) -> (n,)`` against the parameter: stable solid, unstable dashed."""
    import matplotlib.pyplot as plt
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for br in d.branches:
        v = np.array([p.value for p in br.points])
        ys = np.array([values_of(p) for p in br.points]).reshape(len(br.points), -1)
        st = np.array([p.orbit.stable for p in br.points])
        c = colours[br.period % len(colours)]
        for k in range(ys.shape[1]):
            for mask, style in ((st, "-"), (~st, "--")):
                # each run of one stability, joined to its neighbour so the curve has no gap
                grow = mask | np.concatenate([[False], mask[:-1]]) if style == "--" else mask
                y = np.where(grow, ys[:, k], np.nan)
                ax.plot(v, y, style, color=c, lw=1.3,
                        label=f"P{br.period}" if (style == "-" and k == 0 and mask.any()) else None)


def draw_diagram(d: Diagram, path) -> None:
    """The bifurcation diagram like the paper's Fig. 9: the hammer velocity at the Poincaré section (every
    point of a period-n orbit) and the rate of penetration against the parameter; stable branches solid,
    unstable dashed, bifurcations marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    _draw_branches(top, d, lambda p: section_points(p.orbit))
    _draw_branches(bottom, d, lambda p: [p.orbit.groups.rop(p.orbit.rop_x0_per_period)["m_per_h"]])
    for b in d.bifurcations:
        m = MARKERS.get(b.kind, "*")
        top.plot([b.value] * b.orbit.period, section_points(b.orbit), m, color="k", ms=6, mfc="none")
        bottom.plot([b.value], [b.orbit.groups.rop(b.orbit.rop_x0_per_period)["m_per_h"]], m, color="k", ms=6,
                    mfc="none")
    handles = {}
    for h, lab in zip(*top.get_legend_handles_labels()):
        handles.setdefault(lab, h)
    for k in sorted({b.kind for b in d.bifurcations}):
        handles[k] = top.plot([], [], MARKERS.get(k, "*"), color="k", mfc="none")[0]
    top.legend(handles.values(), handles.keys(), fontsize=8)
    unit = _unit(d.parameter)
    bottom.set_xlabel(d.parameter if unit == "1" else f"{d.parameter} [{unit}]")
    top.set_ylabel("hammer velocity at the section [m/s]")
    bottom.set_ylabel("rate of penetration [m/h]")
    top.set_title("periodic orbits: stable solid, unstable dashed")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def load_curves(path) -> list:
    """The curves of a ``hammerbit continue --json`` file (its ``curves``), checked.

    Raises
    ------
    ValueError
        Not JSON, or no list ``curves`` of ``{"kind", "points": [{name: value, name2: value}]}``.
    """
    import json
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ValueError(f"not JSON ({e.msg} at line {e.lineno})") from None
    curves = data.get("curves") if isinstance(data, dict) else None
    if not isinstance(curves, list) or not all(
            isinstance(c, dict) and isinstance(c.get("points"), list)
            and all(isinstance(p, dict) and len(p) == 2 for p in c["points"]) for c in curves):
        raise ValueError("no 'curves' of 'hammerbit continue --json' (a list of {kind, points: [{name: value, "
                         "name2: value}]})")
    return curves


def draw_curves(ax, curves: list, x_name: str, y_name: str) -> int:
    """Draw the curves whose points name both map axes onto ``ax``; returns how many were drawn."""
    drawn = 0
    for c in curves:
        pts = [p for p in c["points"] if x_name in p and y_name in p]
        if len(pts) < 2:
            continue
        ax.plot([p[x_name] for p in pts], [p[y_name] for p in pts], "-", color="k", lw=2.0,
                marker=MARKERS.get(c.get("kind"), "*"), ms=4, mfc="w",
                label=f"{c.get('kind', 'curve')} (continuation)")
        drawn += 1
    return drawn
