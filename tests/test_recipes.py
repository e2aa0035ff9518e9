"""The recipes of docs/architecture.md, run: a new FMU output and a new top condition, each in at most three hand-written files.

A copy of the package (coupling/ and fmu_src/ laid out as ``hammerbit``) gets the edits the
recipe names and nothing else; both flavours of the FMUs, and the native FMI 3.0 ones, are then
built from the copy and run through fmpy.  Building six FMUs takes minutes: the slow set.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: hand-written files a recipe may touch, at most
MAX_FILES = 3
#: the builds a recipe must reach: (runtime, FMI version if not 2)
FLAVOURS = (("pythonfmu",), ("native",), ("native", "3"))

#: docs/architecture.md, "Add an FMU output": (file, text after which, text to add)
OUTPUT_RECIPE = (
    ("fmu_src/fmu_description.py", '    _out("bounce_count",',
     '    _out("recipe_output", "Float64", "m", "twice the bit position (the recipe test)", "length"),\n'),
    ("fmu_src/slave.py", '            "bounce_count": lambda',
     '            "recipe_output": lambda: 2.0 * (s._yi(2) * s._x0),\n'),
    ("coupling/fmu/native/model_values.c", "    case HB_VR_bit_velocity:",
     "    case HB_VR_recipe_output: return 2.0 * (s->y[2] * s->x0);\n"),
)
#: docs/architecture.md, "Add a top condition", one that steps with an existing form
TOP_RECIPE = (
    ("fmu_src/fmu_description.py", "\n)\n\n\ndef top_condition(",
     '\n    TopCondition("recipe-hold", 3, "fixed", False, "the hook held (the recipe test)"),'),
)


def _site_path(site: Path, rel: str) -> Path:
    top, rest = rel.split("/", 1)
    return site / "hammerbit" / ("model/" + rest if top == "fmu_src" else rest)


def _copy_package(site: Path) -> None:
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "coupling", site / "hammerbit", ignore=skip)
    shutil.copytree(ROOT / "fmu_src", site / "hammerbit" / "model", ignore=skip)


def _apply(site: Path, recipe) -> None:
    """Insert each piece of the recipe before its anchor (found exactly once)."""
    for rel, anchor, text in recipe:
        path = _site_path(site, rel)
        src = path.read_text()
        assert src.count(anchor) == 1, f"{rel}: the recipe's anchor {anchor!r} is not found once"
        if anchor.startswith("\n"):
            src = src.replace(anchor, text + anchor)
        else:
            at = src.index(anchor)
            src = src[:at] + text + src[at:]
        path.write_text(src)


def _changed(site: Path) -> set:
    """The repository files whose copy differs from the original."""
    out = set()
    for top, base in (("coupling", site / "hammerbit"), ("fmu_src", site / "hammerbit" / "model")):
        for path in (ROOT / top).rglob("*"):
            if path.is_file() and "__pycache__" not in path.parts:
                rel = path.relative_to(ROOT / top).as_posix()
                copy = base / rel
                if top == "coupling" and rel.startswith("model/"):
                    continue
                if not copy.exists() or copy.read_bytes() != path.read_bytes():
                    out.add(f"{top}/{rel}")
    return out


def _hammerbit(site: Path, *args) -> None:
    env = {**os.environ, "PYTHONPATH": str(site)}
    r = subprocess.run([sys.executable, "-m", "hammerbit", *args], env=env, capture_output=True, text=True,
                       cwd=site)
    assert r.returncode == 0, f"hammerbit {' '.join(args)} failed:\n{r.stdout[-2000:]}\n{r.stderr[-4000:]}"


def _simulate(fmu: Path, outputs, start_values=None, stop_time=0.05):
    """An fmpy run at the 1 ms step every build of the Drillstring carries."""
    from fmpy import simulate_fmu
    return simulate_fmu(str(fmu), stop_time=stop_time, output_interval=1e-3, output=list(outputs),
                        start_values=start_values or {})


@pytest.mark.soak
@pytest.mark.slow
def test_a_new_output_and_a_new_top_condition_need_at_most_three_hand_written_files(tmp_path):
    site = tmp_path / "site"
    _copy_package(site)
    _apply(site, OUTPUT_RECIPE)
    output_files = _changed(site)
    top_only = tmp_path / "top-only"          # both recipes edit fmu_description.py: count each alone
    _copy_package(top_only)
    _apply(top_only, TOP_RECIPE)
    top_files = _changed(top_only)
    _apply(site, TOP_RECIPE)
    assert output_files == {rel for rel, _, _ in OUTPUT_RECIPE} and len(output_files) <= MAX_FILES
    assert top_files == {rel for rel, _, _ in TOP_RECIPE} and len(top_files) <= MAX_FILES

    out = tmp_path / "dist"
    for runtime, *fmi in FLAVOURS:
        version = ["--fmi-version", fmi[0]] if fmi else []
        where = out / "-".join([runtime, *fmi])
        _hammerbit(site, "fmu", "build", "--runtime", runtime, *version, "--out", str(where / "HammerBitRock.fmu"))
        _hammerbit(site, "fmu", "build-string", "--string", "lab", "--runtime", runtime, *version,
                   "--out", str(where / "Drillstring.fmu"))
    runs = {}
    for flavour in FLAVOURS:
        runtime = "-".join(flavour)
        # a second: the spring first has to load the bit past the friction threshold
        r = _simulate(out / runtime / "HammerBitRock.fmu", ["bit_position", "recipe_output"],
                      {"preload": 60.0}, stop_time=1.0)
        assert (r["recipe_output"] == 2.0 * r["bit_position"]).all(), runtime
        assert r["bit_position"][-1] > 0.0, f"{runtime}: the bit did not move, the check says nothing"
        hold = _simulate(out / runtime / "Drillstring.fmu", ["hook_load", "interface_force"], {"top_condition": 3})
        fixed = _simulate(out / runtime / "Drillstring.fmu", ["hook_load", "interface_force"], {"top_condition": 0})
        assert (hold["hook_load"] == fixed["hook_load"]).all(), runtime
        assert (hold["interface_force"] == fixed["interface_force"]).all(), runtime
        runs[runtime] = r
    assert (runs["native"]["recipe_output"] == runs["pythonfmu"]["recipe_output"]).all()
    assert (runs["native-3"]["recipe_output"] == runs["native"]["recipe_output"]).all()
