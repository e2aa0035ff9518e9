"""The issue's own build command for DrillingSystem.fmu, as a user types it.

``hammerbit fmu build-system --string field-2200m --top auto-driller --wob 55000`` builds, fmpy's
validator finds no problem, and the FMU is what the options asked for: field-2200m's string, the
auto-driller (its set point the start of ``wob_set_point``; the feed input unused), and its first
steps equal those of the same FMU built through the library with the same configuration.
"""
from __future__ import annotations

import pytest

pytest.importorskip("fmpy")

from cli_run import run_cli  # noqa: E402


@pytest.mark.slow
def test_the_issues_build_command_builds_a_valid_fmu_of_its_options(capsys, tmp_path):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    from test_system_fmu import Slave

    from hammerbit.cosim.config import CosimConfig, default_hammer
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    from hammerbit.fmu.build_system import build_system_fmu
    out = tmp_path / "DrillingSystem.fmu"
    code, _, err = run_cli(["fmu", "build-system", "--string", "field-2200m", "--top", "auto-driller",
                            "--wob", "55000", "--out", str(out)], capsys)
    assert code == 0, err
    assert validate_fmu(str(out)) == []
    md = read_model_description(str(out))
    start = {v.name: v.start for v in md.modelVariables}
    assert float(start["wob_set_point"]) == 55000.0
    field = load_string("field-2200m")
    cfg = CosimConfig(stop=1.0, step=0.01, rig=default_hammer(field), top=TopCondition.parse("auto-driller"),
                      wob=55000.0)
    twin = build_system_fmu(field, cfg, tmp_path / "twin.fmu", log=lambda m: None)
    rows = []
    for path in (out, twin):
        s = Slave(path)
        try:
            for _ in range(20):
                s.step(0.01)
            rows.append(s.real("bit_position", "mean_wob", "hook_load"))
        finally:
            s.close()
    assert rows[0] == rows[1]
    assert rows[0][0] > 0.0, "the bit did not drill: not the auto-driller's run"
