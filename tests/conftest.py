"""Shared pytest fixtures."""
import os

# One BLAS thread for the tests' small dense algebra (5x5 expm oracles, modal pencils): with
# OpenBLAS's default of one thread per core, each small call pays thread hand-overs, which on a
# busy 2-core machine cost far more than the algebra itself.  Set
# before numpy is first imported (test modules import it after this file); a value the user
# exported wins.  Subprocesses of the tests inherit it.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest  # noqa: E402

try:
    from hypothesis import settings as _hypothesis_settings
except ImportError:  # pragma: no cover -- the property tests are skipped without hypothesis
    _hypothesis_settings = None
if _hypothesis_settings is not None:
    # no Hypothesis deadline anywhere: an example may compile a kernel (tens of seconds under load),
    # and the fast set asserts no wall time (timings live in benchmarks/)
    _hypothesis_settings.register_profile("hammerbit", deadline=None)
    _hypothesis_settings.load_profile("hammerbit")


@pytest.fixture(scope="session")
def built_fmu(tmp_path_factory):
    """``HammerBitRock.fmu`` built once per session (``hammerbit fmu build``) into a temporary directory."""
    from hammerbit.fmu.build import build_fmu
    return build_fmu(tmp_path_factory.mktemp("fmu") / "HammerBitRock.fmu")


@pytest.fixture(scope="session")
def built_ssp(tmp_path_factory):
    """``drilling.ssp`` built once per session, as the docs build it:
    ``hammerbit ssp build --string field-2200m --set frequency=22.5`` (2 s, H = 1 ms)."""
    from hammerbit.cosim.config import field_hammer
    from hammerbit.ssp.package import SSPOptions, build_ssp
    return build_ssp("field-2200m", tmp_path_factory.mktemp("ssp") / "drilling.ssp",
                     SSPOptions(stop=2.0, step=1e-3, rig=field_hammer().replace(frequency=22.5)))

@pytest.fixture(scope="session")
def built_native_fmu(tmp_path_factory):
    """The native flavour (``hammerbit fmu build --runtime native``), built once per session."""
    from hammerbit.fmu.build import build_fmu
    from hammerbit.fmu.native import FrontBuildError, find_compiler
    try:
        find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))
    return build_fmu(tmp_path_factory.mktemp("native") / "HammerBitRock.fmu", runtime="native")


@pytest.fixture(params=["pythonfmu", "native"])
def any_fmu(request):
    """Each runtime flavour of HammerBitRock.fmu in turn (built once per session each)."""
    return request.getfixturevalue("built_fmu" if request.param == "pythonfmu" else "built_native_fmu")


# ---------------------------------------------------------------------------
# The slow set.  The README's test command, ``python -m pytest -q``, leaves it
# out (``addopts = -m 'not slow' ...`` in pyproject.toml); ``-m slow`` runs only
# it and ``-m "slow or not slow"`` runs everything.  Besides the tests decorated
# with ``@pytest.mark.slow`` in their files, the tests below are slow: each
# costs seconds (a new process, a cluster, a compile) to tens of seconds, and its
# behaviour keeps a faster test in the default set (named beside it).
SLOW_TESTS = {
    "tests/test_cosim.py::test_linear_sweep_matches_frf_and_modes":
        "tests/test_hammer_boundary.py::test_coupled_modes_match_the_continuous_oracle",
    "tests/test_cosim.py::test_cli_sweep": "tests/test_cli.py::test_documented_command_parses",
    "tests/test_cosim.py::test_with_the_fmu":
        "tests/test_cosim_adaptive.py::test_adaptive_through_the_fmu_rolls_back_and_matches_in_process",
    "tests/test_cosim.py::test_schemes_and_extrapolation_orders":
        "tests/test_cosim.py::test_matches_monolithic_wob_amplitude",
    "tests/test_cosim.py::test_instability_detected_stiff_interface":
        "tests/test_cosim.py::test_instability_detected_by_energy_residual",
    "tests/test_startup.py::test_kernels_load_without_scipy_linalg_and_blas_functions_still_compile":
        "tests/test_startup.py::test_kernels_load_without_scipy_linalg_and_the_blas_flag_is_numbas_own",
    "tests/test_studies.py::test_cli_map_interrupted_leaves_no_processes":
        "tests/test_studies.py::test_ctrl_c_in_a_map_on_local_workers_exits_130_and_leaves_no_processes",
    "tests/test_studies.py::test_map_identical_on_a_dask_scheduler":
        "tests/test_studies.py::test_map_identical_on_every_executor",
    "tests/test_studies.py::test_map_identical_on_a_one_worker_dask_cluster":
        "tests/test_studies.py::test_map_identical_on_every_executor",
}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark :data:`SLOW_TESTS` slow before ``-m`` selects (hence ``tryfirst``)."""
    for item in items:
        if item.nodeid in SLOW_TESTS or item.nodeid.split("[")[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def built_string_fmu(tmp_path_factory):
    """``Drillstring.fmu`` of the lab string, pythonfmu flavour, built once per session."""
    from hammerbit.fmu.build_string import build_string_fmu
    return build_string_fmu("lab", tmp_path_factory.mktemp("string_py") / "Drillstring.fmu")


@pytest.fixture(scope="session")
def built_native_string_fmu(tmp_path_factory):
    """``Drillstring.fmu`` of the lab string, native flavour, built once per session."""
    from hammerbit.fmu.native import FrontBuildError, find_compiler
    from hammerbit.fmu.native_string import build_native_string_fmu
    try:
        find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))
    return build_native_string_fmu("lab", tmp_path_factory.mktemp("string_native") / "Drillstring.fmu",
                                   log=lambda msg: None)


@pytest.fixture(scope="session")
def built_system_fmu(tmp_path_factory):
    """``DrillingSystem.fmu`` (native) of the lab string under the auto-driller, built once per session."""
    from hammerbit.cosim.config import CosimConfig, default_hammer
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    from hammerbit.fmu.build_system import build_system_fmu
    from hammerbit.fmu.native import FrontBuildError, find_compiler
    try:
        find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))
    lab = load_string("lab")
    config = CosimConfig(stop=1.0, step=1e-3, rig=default_hammer(lab), top=TopCondition.parse("auto-driller"))
    return build_system_fmu(lab, config, tmp_path_factory.mktemp("system") / "DrillingSystem.fmu",
                            log=lambda msg: None)
