"""The FMU behaviour suite of ``test_fmu.py`` run against the native runtime flavour.

The tests are the same functions (imported, so pytest collects them here too); this module
only overrides the ``built_fmu`` fixture with the native build.  Left out: the four tests about
the Python flavour's own machinery (the runtime and compiled kernels it carries, its JSON state
body, and two probes of a Python process loading it); the native flavour's counterparts are in
``test_fmu_native_runtime.py``.
"""
import pytest

from test_fmu import (  # noqa: F401  (collected here against the native build; a fixture too)
    bad_call_expected, test_bad_call_is_an_error_and_changes_nothing, test_bad_parameter_fails_initialisation,
    test_corrupt_serialized_state_is_an_error, test_fmu2slave_variable_steps_match_the_library,
    test_impact_scene_matches_the_library, test_libcosim_runs_the_fmu_like_fmpy_and_the_library,
    test_model_description_ranges_nominals_and_no_feedthrough, test_model_description_variables,
    test_output_forces_are_consistent, test_outputs_are_valid_in_initialization_mode,
    test_rollback_is_bit_identical, test_setup_experiment_with_a_non_finite_start_time_is_an_error,
    test_si_parameters_map_onto_the_rig, test_simulate_fmu_default_scene_drills_like_the_library,
    test_solver_failure_inside_a_step_restores_the_state, test_start_time_other_than_zero,
    test_stepper_snapshot_restores_the_integration_state_in_place,
    test_terminated_fmu_refuses_steps, test_tolerance_is_tunable,
    test_tolerance_set_after_initialisation_applies_from_the_next_step,
    test_two_instances_with_different_parameters_are_independent, test_validate_reports_nothing,
    test_wrong_type_and_unknown_references_in_get, test_zero_order_hold_of_the_inputs)


@pytest.fixture(scope="module")
def built_fmu(built_native_fmu):
    """The native flavour in place of the default build, for every imported test."""
    return built_native_fmu
