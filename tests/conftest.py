"""Shared pytest fixtures."""
import contextlib
import gc
import os

# One BLAS thread for the tests' small dense algebra (5x5 expm oracles, modal pencils): with
# OpenBLAS's default of one thread per core, each small call pays thread hand-overs, which on a
# busy 2-core machine cost far more than the algebra itself.  Set
# before numpy is first imported (test modules import it after this file); a value the user
# exported wins.  Subprocesses of the tests inherit it.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402

import pytest  # noqa: E402

from shared_builds import shared_build  # noqa: E402

#: where the test processes keep the test modules' bytecode when PYTHONDONTWRITEBYTECODE is set
TEST_BYTECODE_DIR = "test-bytecode"


def _bytecode_dir():
    """The directory for the test modules' bytecode, or None: with PYTHONDONTWRITEBYTECODE set (as
    many containers do), every worker would rewrite the asserts of all ~100 test modules on every
    run (seconds of CPU each); they are kept under hammerbit's cache root instead, nothing beside
    the sources.  Only while test modules are collected: an FMU extracted later would leave
    bytecode under its temporary path there on every run."""
    if not sys.dont_write_bytecode:
        return None
    from hammerbit.fmu.compile_cache import cache_dir
    path = cache_dir(TEST_BYTECODE_DIR)
    return None if path is None else str(path)


_BYTECODE = _bytecode_dir()


@contextlib.contextmanager
def _bytecode_kept():
    """Modules imported inside keep their bytecode (asserts rewritten) in :data:`_BYTECODE`."""
    if _BYTECODE is None:
        yield
        return
    saved = sys.pycache_prefix, sys.dont_write_bytecode
    sys.pycache_prefix, sys.dont_write_bytecode = _BYTECODE, False
    try:
        yield
    finally:
        sys.pycache_prefix, sys.dont_write_bytecode = saved


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """A test module imported (its asserts rewritten) with its bytecode kept in :data:`_BYTECODE`."""
    if not isinstance(collector, pytest.Module):
        yield
        return
    with _bytecode_kept():
        yield


def pytest_collection_finish(session):
    """What importing and collecting left (numba, scipy, llvmlite, the test modules: most of the
    heap) moved out of the garbage collector's reach: every full collection during the run would
    scan it again, for objects that live to the end anyway."""
    gc.collect()
    gc.freeze()


# hypothesis is a pytest plugin's package, so pytest rewrites the asserts of each of its modules
# as they are imported: here, before any test module, in every process
try:
    with _bytecode_kept():
        from hypothesis import settings as _hypothesis_settings
except ImportError:  # pragma: no cover -- the property tests are skipped without hypothesis
    _hypothesis_settings = None
if _hypothesis_settings is not None:
    # no Hypothesis deadline anywhere: an example may compile a kernel (tens of seconds under load),
    # and the fast set asserts no wall time (timings live in benchmarks/)
    _hypothesis_settings.register_profile("hammerbit", deadline=None)
    _hypothesis_settings.load_profile("hammerbit")


def native_build(tmp_path_factory, key: str, name: str, build):
    """:func:`shared_build` of a native FMU or package; skips, saying why, where no C compiler is found."""
    from hammerbit.fmu.native import FrontBuildError, find_compiler
    try:
        find_compiler()
    except FrontBuildError as e:
        pytest.skip(str(e))
    return shared_build(tmp_path_factory, key, name, build)


@pytest.fixture(scope="session")
def built_fmu(tmp_path_factory):
    """``HammerBitRock.fmu`` built once per session (``hammerbit fmu build``) into a temporary directory."""
    from hammerbit.fmu.build import build_fmu
    return shared_build(tmp_path_factory, "fmu", "HammerBitRock.fmu", build_fmu)


@pytest.fixture(scope="session")
def built_ssp(tmp_path_factory):
    """``drilling.ssp`` built once per session, as the docs build it:
    ``hammerbit ssp build --string field-2200m --set frequency=22.5`` (2 s, H = 1 ms)."""
    from hammerbit.cosim.config import field_hammer
    from hammerbit.ssp.package import SSPOptions, build_ssp
    return shared_build(tmp_path_factory, "ssp", "drilling.ssp", lambda path: build_ssp(
        "field-2200m", path, SSPOptions(stop=2.0, step=1e-3, rig=field_hammer().replace(frequency=22.5))))

@pytest.fixture(scope="session")
def built_native_ssp(tmp_path_factory):
    """The package of :func:`built_ssp` (field-2200m, 22.5 Hz, H = 1 ms), native flavour, built once
    per session."""
    from hammerbit.cosim.config import field_hammer
    from hammerbit.ssp.package import SSPOptions, build_ssp
    return native_build(tmp_path_factory, "ssp_native", "drilling.ssp", lambda path: build_ssp(
        "field-2200m", path, SSPOptions(stop=2.0, step=1e-3, rig=field_hammer().replace(frequency=22.5),
                                        runtime="native")))


@pytest.fixture(scope="session")
def built_native_fmu(tmp_path_factory):
    """The native flavour (``hammerbit fmu build --runtime native``), built once per session."""
    from hammerbit.fmu.build import build_fmu
    return native_build(tmp_path_factory, "native", "HammerBitRock.fmu",
                        lambda path: build_fmu(path, runtime="native"))


@pytest.fixture(scope="session")
def built_native_fmu3(tmp_path_factory):
    """The native flavour in FMI 3.0 (``--runtime native --fmi-version 3``), built once per session."""
    from hammerbit.fmu.build import build_fmu
    return native_build(tmp_path_factory, "native3", "HammerBitRock.fmu",
                        lambda path: build_fmu(path, runtime="native", fmi_version=3))


@pytest.fixture
def built(request):
    """The session build whose fixture the test names in an indirect parameter
    (``@pytest.mark.parametrize("built", ["built_fmu", ...], indirect=True)``): requested in the
    set-up, so that the run that builds it times the build as set-up, not as the test's call."""
    return request.getfixturevalue(request.param)


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
        "tests/test_cli_interrupt.py::test_ctrl_c_early_and_in_a_cluster_map",
    "tests/test_studies.py::test_map_identical_on_a_dask_scheduler":
        "tests/test_studies.py::test_map_identical_on_every_executor",
    "tests/test_studies.py::test_map_identical_on_a_one_worker_dask_cluster":
        "tests/test_studies.py::test_map_identical_on_every_executor",
    "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[simulate_ssp-plain]":
        "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[simulate_ssp-front]",
    "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[user_loop-plain]":
        "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[simulate_ssp-front]",
    "tests/test_fmu.py::test_repeated_instantiation_and_exit_in_a_fresh_process":
        "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[simulate_ssp-front]",
    "tests/test_optimize_constrained.py::test_contact_force_limit_binding_on_the_lab_rig_with_a_gap":
        "tests/test_optimize_constrained.py::test_static_threshold_binding_over_amplitude_and_preload",
    "tests/test_docs.py::test_python_blocks_run[docs/continuation.md]":
        "tests/test_continuation.py::test_the_branch_reaches_the_end_of_its_range_through_points_that_are_orbits",
    "tests/test_docs.py::test_python_blocks_run[docs/fmu.md]":
        "tests/test_docs_commands.py::test_documented_command_runs",
    "tests/test_cpu_target.py::test_cosim_through_the_fmu_loads_the_kernels_it_ships":
        "tests/test_cpu_target.py::test_a_study_worker_of_an_fmu_master_compiles_nothing_at_start",
    "tests/test_fmu_build.py::test_two_builds_with_different_start_values_in_one_process":
        "tests/test_fmu_native_runtime.py::test_start_values_of_the_build_are_the_binaries_own",
    "tests/test_cosim_defects.py::test_default_run_with_a_ramp_reaches_the_tolerance":
        "tests/test_cosim_defects.py::test_a_claimed_tolerance_holds_against_the_reference",
    "tests/test_cosim_adaptive.py::test_tighter_tolerance_smaller_steps_smaller_error":
        "tests/test_cosim_adaptive.py::test_adaptive_meets_its_tolerance_on_a_drilling_case",
    "tests/test_figure_worker.py::test_simulate_plot_is_the_same_with_and_without_the_worker":
        "tests/test_figure_worker.py::test_a_worker_that_dies_without_an_answer_leaves_the_drawing_to_the_caller",
    "tests/test_reference.py::test_penetration_matches_independent_reference[rtol-1e-10-no_impact]":
        "tests/test_reference.py::test_penetration_matches_independent_reference[rtol-1e-10-impact]",
    "tests/test_system_fmu_safety.py::test_fuzzed_states_never_crash_or_hang_the_host":
        "tests/test_system_fmu_safety.py::test_a_few_fuzzed_states_never_crash_or_hang_the_host",
    "tests/test_fmu_fuzz.py::test_fuzzed_states_never_crash_or_hang_the_host[built_string_fmu]":
        "tests/test_fmu_fuzz.py::test_fuzzed_states_never_crash_or_hang_the_host[built_native_string_fmu]",
    "tests/test_fmu_fuzz.py::test_fuzzed_states_never_crash_or_hang_the_host[built_native_string_fmu3]":
        "tests/test_fmu_fuzz.py::test_fuzzed_states_never_crash_or_hang_the_host[built_native_string_fmu]",
    "tests/test_fmi3_system.py::test_system_reference_results_equal_its_run_in_fmpy[3]":
        "tests/test_fmi3_native.py::test_fmi3_reference_results_equal_its_run_in_fmpy",
    "tests/test_cosim.py::test_estimate_within_a_factor_3_of_the_true_error[drilling-0.002]":
        "tests/test_cosim.py::test_estimate_within_a_factor_3_of_the_true_error[drilling-0.005]",
    "tests/test_cosim.py::test_estimate_within_a_factor_3_of_the_true_error[stuck-0.005]":
        "tests/test_cosim.py::test_estimate_within_a_factor_3_of_the_true_error[stuck-0.01]",
    "tests/test_cosim_defects.py::test_a_claimed_tolerance_holds_against_the_reference[25.0-5000.0-1.0-0.0]":
        "tests/test_cosim_defects.py::test_a_claimed_tolerance_holds_against_the_reference[20.0-5000.0-0.3-0.0]",
    "tests/test_fmi3_platforms.py::test_windows_dll_under_wine_equals_x86_64_linux[1000]":
        "tests/test_fmu_native_runtime.py::test_windows_host_under_wine_equals_the_linux_run",
    "tests/test_string_fmu_native.py::test_windows_host_under_wine_equals_the_linux_run":
        "tests/test_fmu_native_runtime.py::test_windows_host_under_wine_equals_the_linux_run",
    "tests/test_fmu_native.py::test_ecos_runs_the_fmu_natively[pythonfmu]":
        "tests/test_fmu_native.py::test_c_host_steps_10_s_like_fmpy_and_exits_0",
    "tests/test_fmu_native_runtime.py::test_model_exchange_reproduces_the_library[paper-fig12-0.06]":
        "tests/test_fmu_native_runtime.py::test_model_exchange_reproduces_the_library[paper-fig9-0.083]",
    "tests/test_reference.py::test_paper_scenes_at_default_tolerance_agree_with_reference[paper-fig9-0.2]":
        "tests/test_reference.py::test_paper_scenes_at_default_tolerance_agree_with_reference[paper-fig9-0.083]",
    "tests/test_ssp_native.py::test_runners_give_the_pythonfmu_packages_penetration[libcosim]":
        "tests/test_ssp_native.py::test_runners_give_the_pythonfmu_packages_penetration[fmpy]",
    "tests/test_string_fmu.py::test_auto_driller_gain_parameter_equals_a_side_built_with_it[integral_gain]":
        "tests/test_string_fmu.py::test_auto_driller_gain_parameter_equals_a_side_built_with_it[proportional_gain]",
    # the error estimate of DrillingSystem.fmu against the fine-step truth: 2 s at H = 1 s (and the
    # grazing stick tried at 80 clocks) slow; 0.3 s with a corrected step fast
    "tests/test_system_fmu_estimate.py::test_estimate_within_three_times_the_truth[1.0]":
        "tests/test_system_fmu_estimate.py::test_estimate_within_three_times_the_truth_at_a_corrected_step",
    "tests/test_system_fmu_estimate.py::test_a_step_beyond_the_tolerance_goes_on_from_the_shadow":
        "tests/test_system_fmu_estimate.py::test_estimate_within_three_times_the_truth_at_a_corrected_step",
    "tests/test_fmi3_system.py::test_system_reference_results_equal_its_run_in_fmpy[2]":
        "tests/test_fmu_reference_results.py::test_native_hammer_reference_results_equal_its_run_in_fmpy",
    # three PNGs encoded (seconds of matplotlib): the drawing stays fast
    "tests/test_modal_check.py::test_plots":
        "tests/test_modal_check.py::test_campbell_and_receptance_draw_in_si_without_saving",
    # a new process with the front (fmpy, a C host): one of each kind stays fast
    "tests/test_fmu_native.py::test_python_host_with_front_matches_and_exits_0":
        "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[simulate_ssp-front]",
    "tests/test_string_fmu_front.py::test_a_native_c_host_runs_it_like_fmpy":
        "tests/test_fmu_native.py::test_c_host_steps_10_s_like_fmpy_and_exits_0",
    # 0.8 s of field string at 50 us with impacts; the fundamental's independence of the sampling
    # and of a contact spike is checked on a closed form
    "tests/test_cosim_defects.py::test_reference_wob_amplitude_does_not_depend_on_its_sampling_with_impacts":
        "tests/test_cosim_defects.py::test_fundamental_of_a_sinusoid_with_a_spike",
    # the tension onset checked by runs from rest either side (seconds of runs); its location by the
    # smallest drive's sign change stays fast
    "tests/test_continuation_touch.py::test_the_tension_curve_separates_settled_runs_from_rest":
        "tests/test_continuation_touch.py::test_tension_onset_is_located_where_the_smallest_drive_changes_sign",
    "tests/test_ssp.py::test_libcosim_runs_the_package_as_hammerbit_does":
        "tests/test_ssp.py::test_libcosim_runs_the_auto_driller_as_hammerbit_does",
    "tests/test_fmu_audit.py::test_a_fallback_cache_others_could_write_is_never_used[another-owner]":
        "tests/test_fmu_audit.py::test_a_fallback_cache_others_could_write_is_never_used[world-writable]",
    # 30 periods of solve_ivp's reference with impacts; an impacting scene against it stays fast
    "tests/test_reference.py::test_paper_scenes_at_default_tolerance_agree_with_reference[paper-fig12-0.11]":
        "tests/test_reference.py::test_penetration_matches_independent_reference[rtol-1e-10-impact]",
    # the optimizer against a brute-force oracle: 441 runs of a 2-D grid slow, a 1-D scan fast
    "tests/test_studies.py::test_optimizer_beats_every_feasible_cell_of_a_21x21_grid":
        "tests/test_studies.py::test_optimizer_known_optimum_on_the_threshold_not_the_papers_bounce_rule",
    # the lab string's DrillingSystem (its build computes 20 s of reference results on a stiff
    # string: seconds); the field string's FMI 3 build reaches the same refusals
    "tests/test_fmu_own_states.py::test_every_state_an_fmu_steps_to_can_be_restored[built_system_fmu]":
        "tests/test_fmu_own_states.py::test_every_state_an_fmu_steps_to_can_be_restored[built_field_system_fmu3]",
    # Ctrl-C in a map on local workers, in this process (a 240-cell map started on two worker
    # processes); the signal in a map on two local workers, in a new process, stays fast
    "tests/test_studies.py::test_ctrl_c_in_a_map_on_local_workers_exits_130_and_leaves_no_processes":
        "tests/test_cli_interrupt.py::test_ctrl_c_early_and_in_a_cluster_map",
    # DrillingSystem.fmu against the library over 3 s of a stall and its reference; the stall
    # verdict's rollback stays fast
    "tests/test_system_fmu_regime.py::test_stall_off_resonance_is_the_librarys_verdict_at_every_second":
        "tests/test_system_fmu_regime.py::test_stall_verdict_is_part_of_the_state",
    # docs/make_calibration.py's search on a 2 x 3 grid against simulate per cell; the calibration's
    # period sequences stay fast
    "tests/test_paper_figures.py::test_calibration_search_agrees_with_simulate_cell_by_cell":
        "tests/test_paper_figures.py::test_fig9_period_sequence_with_the_same_calibration",
    # two 10 s co-simulations of the field string; the closed loop's stability stays fast
    "tests/test_top.py::test_auto_driller_holds_the_wob_where_the_fixed_hook_unloads":
        "tests/test_top.py::test_closed_loop_is_stable_around_the_default_tuning",
    # a pythonfmu FMU run and then a build in a new process, the FMU's directory deleted; the
    # harder case, the directory kept, stays fast
    "tests/test_string_fmu.py::test_a_build_after_running_a_pythonfmu_fmu_in_this_process_carries_its_binaries[deleted]":
        "tests/test_string_fmu.py::test_a_build_after_running_a_pythonfmu_fmu_in_this_process_carries_its_binaries[kept]",
    # the grazing curves against a 5 x 9 map at 300 periods; each point of the curve an orbit that
    # grazes stays fast
    "tests/test_continuation_grazing.py::test_the_curves_separate_the_maps_impacting_cells":
        "tests/test_continuation_grazing.py::test_every_point_of_the_curve_is_an_orbit_that_grazes",
    # new processes over both FMUs of the package: FMPy's runner on the package as built stays fast
    "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[user_loop-front]":
        "tests/test_fmu_exit.py::test_a_few_process_runs_exit_0[simulate_ssp-front]",
    # a user's own Jacobi loop over the package, right and wrongly wired, against FMPy's runner;
    # FMPy's runner against hammerbit's stays fast
    "tests/test_ssp.py::test_a_users_own_jacobi_loop_is_fmpys_runner_and_the_wrong_wiring_is_not":
        "tests/test_ssp.py::test_fmpy_runs_the_package_as_hammerbit_does",
    # the continuation of a sliding onset, with corrected orbits either side of each point; the
    # tension onset's location stays fast
    "tests/test_continuation_touch.py::test_the_sliding_curve_separates_one_stick_phase_from_two":
        "tests/test_continuation_touch.py::test_tension_onset_is_located_where_the_smallest_drive_changes_sign",
    # FMPy's command line in a new process refusing a bad start value of the pythonfmu flavour;
    # every declared bound of both flavours, in this process, stays fast
    "tests/test_fmu_build.py::test_fmpy_simulate_with_a_bad_start_value_fails_naming_it":
        "tests/test_fmu_audit.py::test_every_declared_bound_is_accepted_and_nothing_beyond_it",
    # the fixed top's string FMU against the library step for step; the feed and auto-driller tops
    # stay fast
    "tests/test_string_fmu.py::test_string_fmu_equals_the_library_string_side_step_for_step[fixed]":
        "tests/test_string_fmu.py::test_string_fmu_equals_the_library_string_side_step_for_step[auto-driller]",
    # figures in every format matplotlib writes (seconds of rendering); the README's PNG stays fast
    "tests/test_cli.py::test_plot_formats_follow_the_extension":
        "tests/test_cli.py::test_readme_main_command",
    # a real native build with the compiler cache and one without it (seconds of compiles); one
    # compile through the cache against a fresh one in another directory stays fast
    "tests/test_compile_cache.py::test_a_native_fmu_from_a_warm_cache_is_the_fmu_built_without_it":
        "tests/test_compile_cache.py::test_a_hit_gives_the_bytes_of_a_fresh_compile_in_another_directory",
    # a branch followed to its fold and runs either side of it; the runaway check against long runs
    # at a located onset stays fast
    "tests/test_continuation_bounds.py::test_a_fold_that_runs_from_its_orbit_do_not_confirm_is_no_runaway_onset":
        "tests/test_continuation_bounds.py::test_the_located_runaway_onset_is_that_of_a_bisection_of_long_runs",
    # a new process loading the shipped kernels from two extraction directories; a new process with
    # a read-only home loading them stays fast
    "tests/test_fmu.py::test_a_new_process_loads_the_shipped_kernels":
        "tests/test_fmu_build.py::test_cold_start_loads_the_shipped_kernels_with_a_read_only_home",
    # the console's process boundary for `continue`; the same boundary for `simulate` stays fast
    # (and `continue`'s refusals in this process: tests/test_careless_input.py)
    "tests/test_continuation.py::test_bad_input_in_a_new_process_exits_2_without_a_traceback":
        "tests/test_cli.py::test_bad_input_through_the_console_script",
    # RK4 against solve_ivp on the impacting scene; the same comparison without impacts stays fast
    # (the impacting scene's reference: tests/test_reference.py)
    "tests/test_model.py::test_rk4_and_adaptive_agree_within_rk4_error[paper-fig12-0.06]":
        "tests/test_model.py::test_rk4_and_adaptive_agree_within_rk4_error[paper-fig9-0.11]",
    # one more C host in a new process, with python3 found on PATH; the C host that finds the
    # FMU's Python stays fast
    "tests/test_fmu_native.py::test_python3_on_path_is_found":
        "tests/test_fmu_native.py::test_c_host_steps_10_s_like_fmpy_and_exits_0",
    # 10,000 periods with impacts (the 100,000 are slow too); random scenes' invariants stay fast
    "tests/test_stress.py::test_ten_thousand_periods":
        "tests/test_stress.py::test_random_scenes_invariants_quick",
    # DrillingSystem.fmu in FMI 3.0 with early return allowed (it declares none); the same run
    # without it stays fast
    "tests/test_fmi3_system.py::test_system_fmi3_run_equals_fmi2[True]":
        "tests/test_fmi3_system.py::test_system_fmi3_run_equals_fmi2[False]",
    # the field string's matrix twice in a new process with the BLAS's own threads (eigenproblems);
    # the limit covering a BLAS loaded inside it, in a new process, stays fast
    "tests/test_blas_threads.py::test_the_first_string_side_of_a_process_has_the_bits_of_every_later_one":
        "tests/test_blas_threads.py::test_a_blas_loaded_inside_the_limit_runs_one_thread",
    # new processes that start interpreters of their own (about a second of imports and kernel
    # loads each), one fast check of each kind kept:
    # - fuzzing the pythonfmu flavour (an FMU instance per state); the native flavours' stay fast
    "tests/test_fmu_fuzz.py::test_fuzzed_states_never_crash_or_hang_the_host[built_fmu]":
        "tests/test_fmu_fuzz.py::test_fuzzed_states_never_crash_or_hang_the_host[built_native_fmu]",
    # - a C host's two threads starting the FMU's Python; the host's 10 s run stays fast
    "tests/test_fmu_native.py::test_c_host_threads_start_python_once_and_agree":
        "tests/test_fmu_native.py::test_c_host_steps_10_s_like_fmpy_and_exits_0",
    # - continuation's kernels loaded by a later process; the cache index read by a later process
    #   stays fast
    "tests/test_continuation_cache.py::test_a_later_process_loads_the_compiled_kernels":
        "tests/test_numba_internals.py::test_the_cache_index_says_cached_or_not",
    # - the FMU runtime's compile switch in a new process; the switch off, in this one, stays fast
    "tests/test_compile_ahead.py::test_the_fmu_runtime_starts_no_helper_and_leaves_the_switch_alone":
        "tests/test_compile_ahead.py::test_no_helper_when_disabled",
    # - the figure worker's process saving a figure; one that dies without an answer stays fast
    "tests/test_figure_worker.py::test_worker_saves_what_this_process_saves_and_raises_what_it_raises":
        "tests/test_figure_worker.py::test_a_worker_that_dies_without_an_answer_leaves_the_drawing_to_the_caller",
}


#: ``{node id: slow?}`` of every test this process collected, before ``-m`` deselects
#: (tests/test_slow_set.py checks :data:`SLOW_TESTS` against it)
COLLECTED = {}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark :data:`SLOW_TESTS` slow before ``-m`` selects (hence ``tryfirst``)."""
    for item in items:
        if item.nodeid in SLOW_TESTS or item.nodeid.split("[")[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
        COLLECTED[item.nodeid] = item.get_closest_marker("slow") is not None


@pytest.fixture(scope="session")
def built_string_fmu(tmp_path_factory):
    """``Drillstring.fmu`` of the lab string, pythonfmu flavour, built once per session."""
    from hammerbit.fmu.build_string import build_string_fmu
    return shared_build(tmp_path_factory, "string_py", "Drillstring.fmu", lambda path: build_string_fmu("lab", path))


@pytest.fixture(scope="session")
def built_native_string_fmu(tmp_path_factory):
    """``Drillstring.fmu`` of the lab string, native flavour, built once per session."""
    from hammerbit.fmu.native_string import build_native_string_fmu
    return native_build(tmp_path_factory, "string_native", "Drillstring.fmu",
                        lambda path: build_native_string_fmu("lab", path, log=lambda msg: None))


@pytest.fixture(scope="session")
def built_native_string_fmu3(tmp_path_factory):
    """``Drillstring.fmu`` of the lab string, native flavour in FMI 3.0, built once per session."""
    from hammerbit.fmu.native_string import build_native_string_fmu
    return native_build(tmp_path_factory, "string_native3", "Drillstring.fmu",
                        lambda path: build_native_string_fmu("lab", path, log=lambda msg: None, fmi_version=3))


@pytest.fixture(scope="session")
def built_system_fmu(tmp_path_factory):
    """``DrillingSystem.fmu`` (native) of :func:`lab_system`, built once per session."""
    from hammerbit.fmu.build_system import build_system_fmu
    lab, config = lab_system()
    return native_build(tmp_path_factory, "system", "DrillingSystem.fmu",
                        lambda path: build_system_fmu(lab, config, path, log=lambda msg: None))


def lab_system():
    """``(string, config)`` of :func:`built_system_fmu`: the lab string under the auto-driller at
    H = 1 ms.  (Its build takes seconds: the reference results of its 20 s default experiment,
    from the library's Stepper on the lab string; the fast set uses the field string's build.)"""
    from hammerbit.cosim.config import CosimConfig, default_hammer
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    lab = load_string("lab")
    return lab, CosimConfig(stop=1.0, step=1e-3, rig=default_hammer(lab), top=TopCondition.parse("auto-driller"))


def field_system():
    """``(string, config)`` of :func:`built_field_system_fmu`: field-2200m under the auto-driller,
    2 s at H = 10 ms."""
    from hammerbit.cosim.config import CosimConfig, default_hammer
    from hammerbit.drillstring import load_string
    from hammerbit.drillstring.top import TopCondition
    field = load_string("field-2200m")
    return field, CosimConfig(stop=2.0, step=0.01, rig=default_hammer(field), top=TopCondition.parse("auto-driller"))


def _field_system_build(version: int):
    """``build(path)`` of DrillingSystem.fmu (native, FMI ``version``) of field-2200m under the
    auto-driller, 2 s at H = 10 ms."""
    def build(path):
        from hammerbit.fmu.build_system import build_system_fmu
        field, config = field_system()
        return build_system_fmu(field, config, path, log=lambda msg: None, fmi_version=version)
    return build


@pytest.fixture(scope="session")
def built_field_system_fmu(tmp_path_factory):
    """``DrillingSystem.fmu`` (native, FMI 2.0) of field-2200m under the auto-driller (2 s, H = 10 ms),
    built once per session."""
    return native_build(tmp_path_factory, "field_system", "DrillingSystem.fmu", _field_system_build(2))


@pytest.fixture(scope="session")
def built_field_system_fmu3(tmp_path_factory):
    """The FMU of :func:`built_field_system_fmu` in FMI 3.0, built once per session."""
    return native_build(tmp_path_factory, "field_system3", "DrillingSystem.fmu", _field_system_build(3))
