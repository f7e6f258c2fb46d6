"""The tests ``make test-fast`` leaves out: measured slow, marked ``slow`` at collection by ``conftest.py``.

Measured with ``pytest -n 2 --durations=0 -m "not slow and not integration and not realtime"`` on the shared
2-core machine under load (issue 13.8; the seconds below are those of that run, several times an idle machine's):
every test whose slowest case, fixture set-up included, took 2 s or more, and the tests sharing such a test's
module fixture. ``make test`` runs them all; ``make test-fast`` (the inner loop, < 1 min) does not.

An entry is ``file::test`` (every parametrised case of it). A test marked ``@pytest.mark.slow`` in its file needs
no entry here. A new test that takes seconds belongs here (or gets the decorator); ``tests/project/test_slow_tests.py``
checks that every entry still names a test.
"""

SLOW_TESTS: frozenset[str] = frozenset({
    "test_bad_inputs.py::test_a_closed_pipe_is_quiet",  # 4 s
    "test_bad_inputs.py::test_bad_input_is_one_clear_line",  # 3 s
    "test_bad_inputs_newer_life_health.py::test_bad_input_is_one_clear_line_and_touches_nothing",  # 6 s (first case)
    "test_bad_inputs_newer_life_health.py::test_mutated_life_files_never_give_an_internal_error",  # 4 s
    "test_bad_inputs_newer_workbench.py::test_bad_input_is_one_clear_line_and_touches_nothing",  # 17 s (NaN probe)
    "test_board_cli.py::test_shipped_short_scenarios_reach_their_expected_verdict",  # 167 s
    "test_health_change_point.py::test_linear_lives_rarely_get_a_sudden_change",  # 8 s (quiet machine)
    "test_board_cli.py::test_shm_run_bad_input_exits_2",  # 52 s
    "test_board_cli.py::test_shm_run_catches_a_degraded_laminate",  # 20 s
    "test_board_cli.py::test_shm_run_end_to_end",  # 24 s
    "test_board_cli.py::test_whole_run_replays_identically_from_a_seed",  # 14 s
    "test_board_edges.py::test_a_finished_verdict_stands_through_a_later_outage",  # 6 s
    "test_board_edges.py::test_every_exit_commands_zero_before_the_link_closes",  # 7 s
    "test_board_golden_timeline.py::test_timeline_matches_golden",  # 212 s
    "test_board_link_delay.py::test_a_degraded_laminate_is_still_caught_with_the_delay_model",  # 3 s
    "test_board_link_delay.py::test_the_monitor_models_a_real_time_rigs_one_tick_delay",  # 18 s
    "test_board_log.py::test_log_show_and_export",  # 13 s
    "test_board_regimes.py::test_random_sequences_obey_the_table",  # 16 s
    "test_board_regimes.py::test_replay_is_deterministic",  # 8 s
    "test_board_regimes.py::test_standby_shortcut_equals_the_full_evaluation",  # 14 s
    "test_board_rig.py::test_actuation_only_with_hv_equipment_and_terminal_switch",  # 4 s
    "test_board_rig.py::test_bad_rig_inputs_are_clear_errors",  # 3 s
    "test_board_rig.py::test_lookahead_blocks_match_tick_by_tick_stepping",  # 3 s
    "test_board_rig.py::test_rig_is_a_rig_endpoint_and_time_advances_one_tick_per_exchange",  # 2 s
    "test_board_rig.py::test_same_seed_same_run_and_a_different_seed_differs",  # 6 s
    "test_board_rig.py::test_sim_urls",  # 6 s
    "test_board_safety.py::test_random_event_sequences_are_safe_and_replay_identically",  # 8 s
    "test_board_usage.py::test_streaming_cycles_equal_rainflow_on_the_full_series",  # 2 s
    "test_calibrate.py::test_cli_calibrate_saves_a_loadable_set",  # 10 s
    "test_campaign.py::test_cli_runs_writes_the_fig11_files_and_roc",  # 21 s
    "test_campaign_dask.py::test_dask_local_cluster_gives_identical_numbers",  # 27 s
    "test_campaign_orphans.py::test_pool_workers_die_with_a_sigkilled_campaign",  # 11 s
    "test_cli_exit_codes.py::test_a_failing_figure_keeps_the_campaign_results",  # 6 s
    "test_cli_model.py::test_frf_step_loop_write_plots_and_csv",  # 9 s
    "test_cli_model.py::test_help_lists_commands",  # 3 s
    "test_cli_model.py::test_model_info_json_reports_modes",  # 10 s
    "test_cli_model.py::test_unknown_parameter_set_is_exit_2_with_message",  # 3 s
    "test_cli_properties.py::test_calibrate_any_valid_free_set",  # 8 s
    "test_cli_properties.py::test_diagnose_ranking_figure_when_everything_sits_at_the_noise_floor",  # 4 s
    "test_cli_properties.py::test_harvest_any_valid_options",  # 79 s
    "test_cli_properties.py::test_hil_serve_any_valid_endpoints_and_faults",  # 4 s
    "test_cli_properties.py::test_model_commands",  # 42 s
    "test_cli_properties.py::test_run_and_log_any_valid_scenario",  # 29 s
    "test_cli_properties.py::test_synth_compare_diagnose_fit",  # 354 s
    "test_cli_properties.py::test_synth_frf_and_compare",  # 10 s
    "test_cli_properties_campaign.py::test_campaign_any_valid_options",  # 31 s
    "test_cli_properties_campaign.py::test_campaign_works_for_every_n_up_to_500",  # 26 s
    "test_cli_properties_json.py::test_json_is_one_document_on_stdout",  # 132 s
    "test_cli_properties_json.py::test_log_export_prints_one_json_document_by_default",  # its fixture 'ws'
    "test_diagnose.py::test_clean_record_is_nothing_missing",  # 11 s
    "test_diagnose.py::test_cli_diagnose_report_and_bad_input",  # 15 s
    "test_diagnose.py::test_effect_outside_the_candidates_is_not_explained_and_localised",  # 4 s
    "test_diagnose.py::test_hidden_creep_is_named_with_signature_and_estimates",  # 19 s
    "test_diagnose.py::test_unstable_and_flat_candidates_are_rejected",  # 128 s
    "test_diagnose_hidden.py::test_confusion_matrix_and_summary",  # its fixture 'results'
    "test_diagnose_hidden.py::test_effect_free_records_are_nothing_missing",  # its fixture 'results'
    "test_diagnose_hidden.py::test_effect_size_is_zero_at_neutral_and_grows_with_strength",  # 3 s
    "test_diagnose_hidden.py::test_hidden_effects_are_ranked_first_and_fitted_to_the_noise_floor",  # 133 s
    "test_diagnose_hidden.py::test_wrong_parameters_are_named_first_as_re_estimations",  # its fixture 'results'
    "test_diagnose_parameters.py::test_a_candidate_at_its_own_bound_loses_its_claim",  # 54 s
    "test_diagnose_parameters.py::test_cli_mass_change_gets_a_re_estimate_m3_verdict",  # 31 s
    "test_diagnose_parameters.py::test_two_missing_effects_are_found_by_forward_selection",  # 189 s
    "test_discover.py::test_challenge_subset_drifting_laser_gain_on_mbit_b",  # 60 s
    "test_discover.py::test_done_when_chain_foreign_friction",  # 141 s
    "test_discover.py::test_not_found_on_a_clean_record",  # 2 s
    "test_discover.py::test_synth_names_the_effect_whose_hook_produced_nan",  # 60 s
    "test_discover_noise_free.py::test_a_noise_free_nominal_record_has_nothing_to_find",  # 5 s
    "test_effect_seam.py::test_docs_worked_example_loads_by_dotted_path_and_acts",  # 119 s
    "test_effect_seam.py::test_effect_defined_in_a_function_compiles_in_memory",  # 69 s
    "test_effect_seam.py::test_hook_that_numba_cannot_compile_names_the_effect",  # 43 s
    "test_effect_seam.py::test_neutral_user_effect_equals_nominal_bit_for_bit",  # 76 s
    "test_effect_slots.py::test_a_new_library_effect_is_one_file",  # 2 s
    "test_effect_slots.py::test_named_and_offsets_hooks_give_the_same_model",  # 3 s
    "test_effect_slots.py::test_signals_are_allocated_from_b_user_and_read_by_name",  # 3 s
    "test_effect_slots.py::test_two_instances_of_one_effect_coexist_and_round_trip_a_parameter_file",  # 67 s
    "test_fit.py::test_cli_fit_user_effect_from_a_file",  # 98 s
    "test_fit.py::test_fit_bad_input",  # 111 s
    "test_fit.py::test_fit_library_effect_error_falls_and_set_loads",  # 3 s
    "test_fit.py::test_fitted_set_removes_a_monitor_false_alarm",  # 3 s
    "test_fit.py::test_free_parameter_unit_box_round_trip",  # 2 s
    "test_fit.py::test_user_effect_defined_here_is_fitted_and_error_falls",  # 64 s
    "test_framing_properties.py::test_any_split_of_good_frames_gives_them_all_and_no_errors",  # 5 s
    "test_framing_properties.py::test_fuzz_decoder_never_raises_and_stays_bounded",  # 3 s
    "test_harvest_audit.py::test_coupled_books_close_within_1_percent",  # 68 s
    "test_harvest_audit.py::test_paper_mode_creates_energy_and_the_audit_shows_how_much",  # 77 s
    "test_harvest_audit.py::test_paper_mode_does_not_load_the_beam_but_coupled_mode_damps_it",  # 3 s
    "test_harvest_audit.py::test_projection_agrees_with_a_run_to_full",  # 6 s
    "test_harvest_battery.py::test_discharged_capacity_inverts_ocv",  # 2 s
    "test_harvest_cli.py::test_coupled_coupling_table2_text_report",  # 8 s
    "test_harvest_cli.py::test_paper_coupling_end_to_end",  # 9 s
    "test_harvest_rectifier.py::test_closed_form_satisfies_the_circuit",  # 3 s
    "test_health.py::test_a_life_is_reproducible_by_seed_whatever_the_workers",  # 32 s
    "test_health.py::test_every_completed_mbit_leaves_a_record_linked_in_the_log",  # 30 s
    "test_health.py::test_health_bad_input_is_one_line_and_exit_2",  # 56 s
    "test_health.py::test_prognosis_challenge_fast_subset",  # 21 s (without the effect life; was 79 s with it)
    "test_health.py::test_prognosis_challenge_fast_subset_follows_a_growing_leakage_to_its_cause",  # 53 s
    "test_health.py::test_stable_laminate_gets_no_trend_and_a_lower_bound_not_a_date",  # 84 s
    "test_health_locate.py::test_a_k2_loss_is_not_placed_in_section_3",  # 145 s
    "test_health_locate.py::test_a_k3_loss_is_placed_in_section_3",  # 59 s
    "test_health_locate.py::test_ticked_flights_run_the_board_through_the_flight_phases_before_each_visit",  # 7 s
    "test_integrator.py::test_deviated_member_matches_solve_ivp_rtol_1e9",  # 61 s
    "test_integrator.py::test_error_falls_with_the_tolerance",  # 6 s
    "test_integrator.py::test_failures_are_reported_as_integration_failed",  # 136 s
    "test_monitor_counter.py::test_always_a_fault_after_enough_consecutive_exceedances",  # 3 s
    "test_monitor_counter.py::test_counter_never_negative_and_steps_are_up_down_or_floor",  # 3 s
    "test_monitor_counter.py::test_fault_latches",  # 6 s
    "test_monitor_counter.py::test_invariant_to_chunking",  # 8 s
    "test_monitor_counter.py::test_latency_bounds",  # 3 s
    "test_monitor_counter.py::test_never_a_fault_while_error_at_or_below_threshold",  # 3 s
    "test_monitor_counter.py::test_streaming_equals_vectorised_equals_flow_chart",  # 8 s
    "test_monitor_counter.py::test_table3_steps_are_exactly_plus2_minus1_or_zero_at_floor",  # 2 s
    "test_monitor_properties.py::test_chunked_and_streamed_end_in_the_flow_charts_state",  # 3 s
    "test_no_silence.py::test_diagnose_reports_its_stages_and_compiles_on_a_short_record",  # cold compiles: minutes
    "test_no_silence.py::test_hil_serve_says_what_it_builds_before_its_port_opens",  # cold compiles: ~1 min
    "test_no_silence.py::test_model_info_announces_its_cold_compile_and_is_never_silent",  # cold compiles: ~1 min
    "test_parameter.py::test_a_freed_parameter_stays_inside_its_range",  # 2 s
    "test_parameter.py::test_deviation_round_trip_and_bounds",  # 4 s
    "test_plant_model.py::test_accuracy_against_solve_ivp_rtol_1e9",  # 68 s
    "test_plant_model.py::test_unforced_reciprocal_core_never_gains_energy",  # 68 s
    "test_power_mc_dc.py::test_random_voltage_sequences_follow_the_rules",  # 4 s
    "test_run_outdir.py::test_a_finished_run_is_kept_unless_force_and_append_adds_a_run",  # 22 s
    "test_run_outdir.py::test_a_signal_ends_a_run_cleanly_and_the_out_dir_is_locked_meanwhile",  # 41 s
    "test_run_outdir.py::test_a_verdict_other_than_the_expected_one_exits_1",  # 8 s
    "test_run_outdir.py::test_append_keeps_the_earlier_runs_visit_records",  # 41 s
    "test_workbench_cli.py::test_synth_tdms_and_frf_compare",  # 26 s
    "test_workbench_cli.py::test_synth_then_compare_with_a_missing_effect",  # 30 s
    "test_workbench_missing_effect.py::test_missing_cubic_stiffening_mbit_a",  # 2 s
    "test_workbench_missing_effect.py::test_missing_sensor_offset_is_a_bias_only",  # 2 s
    "test_workbench_missing_effect.py::test_truth_equals_model_plus_white_noise_passes",  # 2 s
    "test_workbench_residual_tests.py::test_false_rejection_rate_under_white_noise",  # 8 s
})
