"""Which kind of reference each test function checks against (issue 52).

Every test function in ``tests/`` (a parametrized test counts once; a method as
``module::Class::name``) has one kind: the strongest among its assertions that can fail.

- ``hand``: an expected value worked out by hand or taken from a spec, paper or article and
  written in the test (a distance, a path, a count, an exact byte string).
- ``formula``: a physics or closed-form formula, or an independent second algorithm (brute
  force, a reference implementation written in the test), computed in the test.
- ``library``: another library's implementation as the reference (SciPy, Shapely, PettingZoo's
  and Gymnasium's/SB3's checkers, Minari's readers, rosbags, mcap readers, a real browser).
- ``golden``: compared with data recorded before a change (tests/golden/, committed result rows,
  snapshot files).
- ``contract``: a stated rule with no numeric reference: an error raised with a message naming
  file/field, an exit code, a file left whole, an API shape.
- ``self``: self-consistency only: two runs of the same code agree, a round trip through the
  code's own writer and reader, the code under test against another call of the same code.
- ``smoke``: runs with no reference value (no exception, output exists, keys present).

``hand``, ``formula``, ``library`` and ``golden`` are the independent references. The table is
kept true by tests/test_reference_kinds.py, which collects every test function by its source and
fails on one missing here, one named here that no longer exists, or an unknown kind.

``python tests/reference_kinds.py`` prints the counts by kind, overall and per module, as the
Markdown tables of docs/testing.md. A note on an entry says why where the call is not obvious;
one longer than ruff's 135 columns goes on comment lines above its entry.
"""

from __future__ import annotations

import ast
import sys
from collections import Counter
from pathlib import Path

TESTS = Path(__file__).resolve().parent

ORDER = ("hand", "formula", "library", "golden", "contract", "self", "smoke")
"""The kinds, strongest first."""

INDEPENDENT = frozenset(("hand", "formula", "library", "golden"))
"""The kinds that compare against a reference that is not the code under test."""

KINDS: dict[str, str] = {
    # ---- test_aisles.py
    "test_aisles.py::test_layout_meets_the_geometric_spec": "formula",  # spec ranges measured with raster geometry written in the test
    "test_aisles.py::test_clutter_narrows_aisles_without_closing_them": "formula",
    "test_aisles.py::test_generator_is_seeded_and_registered": "library",  # footprints on the floor and never overlapping, by Shapely
    "test_aisles.py::test_sampler_defaults_draw_exactly_as_before": "contract",
    "test_aisles.py::test_episodes_need_planning": "formula",  # segment-rectangle test written in the test
    "test_aisles.py::test_segment_box_test_is_right": "hand",
    "test_aisles.py::test_env_is_registered_with_its_settings": "contract",
    "test_aisles.py::test_check_env_passes": "library",
    # goal distances = hypot(goal - pose); path length = sum of pose segments
    "test_aisles.py::test_env_is_deterministic_for_a_seed": "formula",
    # ends clear of the walls by Shapely; distance = hypot
    "test_aisles.py::test_aisle_env_on_a_world_without_racks_draws_plain_episodes": "library",
    # ---- test_architecture.py
    "test_architecture.py::test_private_access_checker_flags_what_it_should": "hand",
    "test_architecture.py::test_consumers_use_only_obs_info_and_the_scene_view": "contract",
    "test_architecture.py::test_import_checker_resolves_relative_and_nested_imports": "hand",
    "test_architecture.py::test_sim_does_not_import_sensors": "contract",
    "test_architecture.py::test_planning_is_pure_algorithms": "contract",
    "test_architecture.py::test_robot_geometry_is_what_pybullet_loads": "library",  # PyBullet's loaded collision shapes
    "test_architecture.py::test_literal_checker_reads_code_not_comments_or_strings": "hand",
    "test_architecture.py::test_geometry_users_carry_no_outline_numbers": "contract",
    "test_architecture.py::test_function_length_checker_measures_what_it_should": "hand",
    "test_architecture.py::test_no_function_is_over_80_lines_but_the_listed_kernels": "contract",
    "test_architecture.py::test_circle_finder_finds_circles_and_only_circles": "hand",
    "test_architecture.py::test_package_imports_follow_the_package_rule": "hand",
    "test_architecture.py::test_the_package_import_graph_has_no_circles": "contract",
    "test_architecture.py::test_every_module_has_a_layer_and_layers_are_disjoint": "contract",
    "test_architecture.py::test_no_module_imports_a_higher_layer": "contract",
    "test_architecture.py::test_the_unit_graph_has_no_circles_and_siblings_stay_apart": "contract",
    "test_architecture.py::test_every_module_imports_in_a_fresh_process_in_layer_order": "contract",
    "test_architecture.py::test_tasks_see_the_scene_through_the_protocol": "contract",
    "test_architecture.py::test_temp_file_checker_flags_what_it_should": "hand",
    "test_architecture.py::test_only_the_files_module_makes_temp_files_and_renames": "contract",
    "test_architecture.py::test_a_write_that_fails_midway_leaves_the_old_file_whole_and_no_temp_file": "hand",
    "test_architecture.py::test_a_failed_rename_removes_the_temp_file": "contract",
    # the standard library's json.dumps and Pillow reading the PNG back
    "test_architecture.py::test_the_writers_write_what_they_are_given": "library",
    # ---- test_barn_controllers.py
    "test_barn_controllers.py::test_navigator_settings_come_from_the_envs_robot": "hand",  # control.yaml 2.0 m/s, 4.0 rad/s
    "test_barn_controllers.py::test_outline_reach_and_braking_speed_by_hand": "hand",  # spec-sheet outline, v = sqrt(2 a d)
    "test_barn_controllers.py::test_turn_guard_swings_the_jackals_corners_by_hand": "hand",  # a corner's swing worked by hand
    "test_barn_controllers.py::test_a_turn_made_while_rolling_is_checked_along_the_roll": "hand",
    "test_barn_controllers.py::test_pid_astar_no_longer_turns_into_a_cylinder_while_rolling": "golden",
    # scans by ray-circle and ray-line intersection
    "test_barn_controllers.py::test_the_avoidance_blend_turns_away_from_the_cylinder_in_the_way_not_toward_the_far_side": "formula",
    # the corner's swing worked out for the cylinder
    "test_barn_controllers.py::test_a_guarded_turn_sent_the_long_way_round_goes_on_until_the_robot_faces_the_target": "hand",
    "test_barn_controllers.py::test_shield_stops_the_jackal_by_its_own_sweep": "formula",  # stop sweep and ray-circle scan
    "test_barn_controllers.py::test_shielded_jackal_at_full_speed_keeps_its_outline_off_a_wall": "formula",  # corners vs wall
    "test_barn_controllers.py::test_navigate_world_idx_drives_a_barn_training_world": "hand",  # 4 t_opt of BARN's score
    "test_barn_controllers.py::test_world_idx_needs_barn_and_a_valid_index": "contract",
    "test_barn_controllers.py::test_world_idx_several_worlds_run_in_turn_as_each_would_alone": "self",
    "test_barn_controllers.py::test_navigator_reset_fits_each_episodes_robot": "hand",
    # ---- test_raycast.py
    "test_raycast.py::test_hits_on_hand_geometry": "hand",  # distances worked out by hand
    "test_raycast.py::test_box_plane_and_the_nearest_of_several": "hand",
    "test_raycast.py::test_agrees_with_pybullet_to_its_convex_cast_tolerance": "library",  # PyBullet's rayTestBatch
    "test_raycast.py::test_barn_lidar_matches_pybullet_and_the_caster_is_checked": "library",
    # ---- test_bench_barn.py
    "test_bench_barn.py::test_bench_env_barn_times_seeded_resets_and_the_bare_floor": "hand",  # 209 cylinders in world_0.world
    "test_bench_barn.py::test_bare_rebuild_holds_the_envs_world": "library",  # PyBullet's ray casts in a bare client
    # ---- test_barn_data.py
    # cylinder poses by a regex written in the test on BARN's own world files; paths against BARN's .npy
    "test_barn_data.py::test_shipped_worlds_match_the_world_files_text": "formula",
    "test_barn_data.py::test_counts_path_endpoints_and_cylinder_size": "hand",  # counts from a regex scan of BARN's files
    "test_barn_data.py::test_reference_paths_avoid_the_cylinders": "formula",  # distances by numpy in the test
    "test_barn_data.py::test_path_cells_convert_to_metres_as_barn_does": "hand",  # run.py's conversion worked by hand
    "test_barn_data.py::test_bad_world_index_is_named": "contract",
    "test_barn_data.py::test_converter_refuses_what_it_cannot_convert": "contract",
    # ---- test_barn_benchmark.py
    "test_barn_benchmark.py::test_published_anchors_lics_ki_rows_scored_as_report_test_py_and_inventec_as_reported": "formula",
    "test_barn_benchmark.py::test_agreement_of_a_dwa_here_with_barns_rows_by_hand": "formula",
    "test_barn_benchmark.py::test_barn_worlds_expand_to_one_world_per_index_with_its_runs": "hand",
    "test_barn_benchmark.py::test_bad_barn_world_selections_name_file_field_and_value": "contract",
    # the DWA row's line against the one BARN's own report_test.py printed on the same rows (run by hand)
    "test_barn_benchmark.py::test_dwa_row_is_report_test_pys_summary_of_barns_rows": "library",
    "test_barn_benchmark.py::test_per_world_and_overall_figures_by_hand": "hand",
    "test_barn_benchmark.py::test_the_barn_tab_shows_each_dwa_runs_success_beside_barns_rows": "contract",
    "test_barn_benchmark.py::test_the_plot_is_written": "hand",  # DWA rows of the same worlds, [0, 6]; the PNG read by Pillow
    "test_barn_benchmark.py::test_barn_score_is_barns_score_with_the_2_t_opt_clip": "hand",
    "test_barn_benchmark.py::test_a_barn_run_scores_its_rows_as_barn_and_reports_them": "formula",  # run.py's score of the row
    "test_barn_benchmark.py::test_a_worker_keeps_at_most_max_cells_envs_open": "hand",  # which envs close, by hand
    # ---- test_barn_env.py
    # positions read back from PyBullet against the world file's text (the test's regex); a ray's hit 0.075 m off the centre
    "test_barn_env.py::test_cylinders_stand_where_the_world_file_puts_them": "formula",
    # run.py's start, goal, 0.1 m clock, 1 m goal and score written in the test; t_opt from BARN's .npy
    "test_barn_env.py::test_start_goal_clock_success_and_score_follow_run_py": "formula",
    "test_barn_env.py::test_any_contact_ends_in_a_collision_with_no_score": "library",  # PyBullet's contact points
    "test_barn_env.py::test_time_limit_counts_from_the_first_tenth_of_a_metre": "hand",  # 100 s, 0.1 m / 0.2 m/s
    "test_barn_env.py::test_world_index_by_make_and_by_reset_and_bad_ones_named": "formula",  # counts and t_opt from BARN's files
    "test_barn_env.py::test_check_env_passes": "library",
    # test worlds idx * 6 by hand (report_test.py); built worlds' cylinder counts from BARN's world files
    "test_barn_env.py::test_world_pools_draw_their_own_worlds_and_repeat_with_the_seed": "hand",
    # ---- test_barn_jackal.py
    # Clearpath's numbers written in the test against what PyBullet loads (track, wheel radius) and the outline
    "test_barn_jackal.py::test_geometry_wheels_and_rest_height_are_the_jackals": "hand",
    "test_barn_jackal.py::test_top_speed_turn_rate_and_straight_driving": "hand",  # 2.0 m/s, 4.0 rad/s; speed from poses
    "test_barn_jackal.py::test_lidar_is_the_ust10s_270_degrees_and_30_m": "hand",
    "test_barn_jackal.py::test_robot_keyword_on_every_id_and_bad_names": "formula",  # the outline's corner by hypot
    # ---- test_barn_metric.py
    "test_barn_metric.py::test_dwa_rows_summary_matches_barns_report_script": "hand",  # BARN's report_test.py run once by hand
    "test_barn_metric.py::test_reference_lengths_agree_with_barns_2022_sixth_column": "golden",  # BARN's own 2022 numbers
    "test_barn_metric.py::test_barn_metric_by_hand": "hand",
    "test_barn_metric.py::test_reference_path_length_by_hand": "hand",
    "test_barn_metric.py::test_bad_out_line_is_named": "contract",
    # ---- test_barn_policy.py
    "test_barn_policy.py::test_barn_policy_loads_and_acts_deterministically_on_barn": "hand",  # Jackal front face 0.254 - 0.055 m
    # ---- test_bench_against.py
    "test_bench_against.py::test_a_bogus_commit_is_refused_in_one_line": "contract",
    "test_bench_against.py::test_an_option_is_not_taken_for_a_commit": "contract",
    "test_bench_against.py::test_a_commit_whose_bulletnav_does_not_import_is_refused": "contract",
    "test_bench_against.py::test_a_commit_without_the_id_is_refused": "contract",
    "test_bench_against.py::test_the_probe_imports_nothing_of_the_tree_but_the_package": "contract",
    "test_bench_against.py::test_against_head_measures_both_sides": "smoke",  # every figure positive, none compared
    # ---- test_benchmark.py
    "test_benchmark.py::test_bad_suites_name_file_and_field": "contract",
    "test_benchmark.py::test_suite_names_and_counts": "hand",
    "test_benchmark.py::test_drive_time_is_the_trapezoid_or_the_triangle": "hand",
    "test_benchmark.py::test_straight_drive_metrics_against_hand_values": "hand",
    "test_benchmark.py::test_turning_and_a_slow_drive": "hand",
    "test_benchmark.py::test_person_zones_are_counted_both_ways_and_collisions_by_kind": "hand",
    "test_benchmark.py::test_tiny_results_are_the_committed_ones_at_1_and_2_workers": "golden",
    # the resumed rows against the committed tiny-suite rows
    "test_benchmark.py::test_an_interrupted_run_resumes_without_rerunning": "golden",
    # rows resumed at a stubbed second commit: the committed rows, and each commit's rows counted by hand
    "test_benchmark.py::test_a_run_resumed_at_another_commit_names_both_in_results_and_report": "golden",
    # the printed rows against the committed tiny-suite rows
    "test_benchmark.py::test_cli_prints_the_headline_and_writes_the_report": "golden",
    "test_benchmark.py::test_an_out_folder_with_results_is_refused_and_force_starts_afresh": "golden",
    "test_benchmark.py::test_compare_puts_a_rerun_beside_the_committed_rows": "golden",
    "test_benchmark.py::test_compare_counts_and_intervals_by_hand": "hand",
    "test_benchmark.py::test_compare_refuses_a_file_that_is_not_results_in_one_line": "contract",
    "test_benchmark.py::test_build_results_orders_rows_and_keeps_one_per_episode": "hand",
    "test_benchmark.py::test_tiny_suite_through_a_ray_cluster_gives_the_committed_rows": "golden",
    "test_benchmark.py::test_an_address_with_no_cluster_is_one_clear_error": "contract",
    "test_benchmark.py::test_pool_raises_a_jobs_error_without_starting_the_queued_jobs": "contract",
    # SciPy's percentile bootstrap; two cases by hand (was reproducibility only)
    "test_benchmark.py::test_bootstrap_interval_matches_scipys_percentile_bootstrap": "library",
    # the report's re-created movers against the live simulation's after 600 steps with yielding (the same kinematics code)
    "test_benchmark.py::test_report_movers_are_where_the_simulation_put_them": "self",
    # the drawn artists' colours against the legend's samples and the palette written in the module; movers at the kinematics' poses
    "test_benchmark.py::test_report_maps_draw_in_the_legend_colours_and_movers_in_dynamic_worlds": "hand",
    "test_benchmark.py::test_report_replay_commands_break_only_between_arguments": "library",  # shlex splits the words back
    # ---- test_cli_env.py
    "test_cli_env.py::test_every_env_subcommand_defaults_to_warehouse_v0_and_takes_env": "contract",
    # start and goal clear of every rack footprint and inside the floor by Shapely
    "test_cli_env.py::test_env_option_reaches_the_env": "library",
    "test_cli_env.py::test_navigate_json_on_the_aisles_env": "formula",  # sim time = steps / 24 Hz, SPL by its formula from the row
    "test_cli_env.py::test_navigate_default_env_report_is_unchanged_but_for_the_safety_line": "contract",
    # the reported size against the world file as PyYAML reads it; distances bounded by its diagonal
    "test_cli_env.py::test_world_file_with_the_aisles_env": "library",
    "test_cli_env.py::test_unknown_env_id_is_a_clear_error": "contract",
    "test_cli_env.py::test_tracker_in_a_static_world": "hand",
    "test_cli_env.py::test_tracker_with_movers": "hand",
    "test_cli_env.py::test_summarize_safety_metrics_known_answers": "hand",
    "test_cli_env.py::test_summarize_safety_metrics_without_movers_or_episodes": "hand",
    # each id's entry as PyYAML reads the packaged file (RL Zoo's format)
    "test_cli_env.py::test_train_reads_the_env_ids_own_hyperparameters_and_records_it": "library",
    # ---- test_cli_help.py
    "test_cli_help.py::test_every_command_has_a_snapshot_and_every_snapshot_a_command": "contract",
    "test_cli_help.py::test_help_is_the_snapshot_byte_for_byte": "golden",  # snapshots taken before cli.py was split
    "test_cli_help.py::test_the_console_script_prints_the_snapshot": "golden",
    # ---- test_cli_inputs.py
    "test_cli_inputs.py::test_counts_and_numbers_out_of_range_are_one_line": "contract",
    "test_cli_inputs.py::test_output_suffixes_are_checked_when_parsing": "contract",
    "test_cli_inputs.py::test_zero_timesteps_stay_allowed_and_defaults_parse": "contract",
    # every note written out by hand (the SAC one was `sac is None or ...` at 052a810)
    "test_cli_inputs.py::test_rollout_note_says_how_many_steps_will_be_trained": "hand",
    "test_cli_inputs.py::test_train_prints_the_note_and_refuses_a_folder_holding_a_run": "contract",
    "test_cli_inputs.py::test_evaluate_without_env_uses_the_models_own_env": "contract",
    "test_cli_inputs.py::test_a_model_that_does_not_fit_the_env_is_one_line_before_any_episode": "contract",
    "test_cli_inputs.py::test_demo_refuses_a_model_of_another_env_before_making_its_folder": "contract",
    "test_cli_inputs.py::test_check_model_fits_names_shapes_and_bounds": "contract",
    "test_cli_inputs.py::test_demo_folders_are_per_run_by_default": "contract",
    "test_cli_inputs.py::test_demo_refuses_an_explicit_folder_holding_a_run": "contract",
    "test_cli_inputs.py::test_a_second_demo_writes_its_own_folder": "contract",
    "test_cli_inputs.py::test_navigate_refuses_to_replace_a_video_or_plot_without_overwrite": "contract",
    "test_cli_inputs.py::test_recorder_writes_beside_the_target_and_renames": "contract",
    "test_cli_inputs.py::test_learning_curve_is_written_whole": "contract",
    "test_cli_inputs.py::test_rollout_note_reads_train_freq_from_the_hyperparameter_file": "hand",
    # ---- test_control.py
    "test_control.py::test_pid_drives_a_first_order_plant_to_the_setpoint": "formula",  # the plant dx/dt = u integrated in the test
    "test_control.py::test_pid_output_is_clamped_and_integral_does_not_wind_up": "hand",
    "test_control.py::test_pid_integral_limit_derivative_and_reset": "hand",
    "test_control.py::test_lidar_map_matches_the_layout": "formula",  # truth: the layout's footprints rasterised, not the mapper
    # ---- test_costmap.py
    "test_costmap.py::test_barn_footprint_padded_and_its_radii_by_hand": "hand",  # 0.31 x 0.265 m; inscribed 0.265, hypot
    # InflationLayer::computeCost written in the test per cell; 177 at 6 cells by hand
    "test_costmap.py::test_inflation_costs_follow_costmap_2ds_formula": "formula",
    "test_costmap.py::test_obstacle_layer_marks_hits_and_clears_rays_by_hand": "hand",  # cells cleared and marked, drawn by hand
    "test_costmap.py::test_footprint_clearing_and_rolling_window_by_hand": "hand",
    "test_costmap.py::test_clear_costmap_recovery_clears_outside_a_square_of_named_layers": "hand",  # 59 x 59 cells kept
    "test_costmap.py::test_footprint_fill_cells_by_hand": "hand",
    "test_costmap.py::test_navfn_straight_corridor_by_hand": "hand",  # 98 cells x COST_NEUTRAL; half-cell steps
    # SciPy's Dijkstra (4-connected and octile) on navfn's costs: the bounds navfn's potential must keep
    "test_costmap.py::test_navfn_path_cost_against_scipys_dijkstra": "library",
    # ---- test_curriculum.py
    "test_curriculum.py::test_promotion_waits_for_min_episodes_and_the_window_rate": "hand",
    "test_curriculum.py::test_demotion_below_the_threshold_and_no_move_past_the_ends": "hand",
    "test_curriculum.py::test_state_round_trips": "hand",  # stage 1, 3 episodes, window [1, 0, 1]; promotes on the 6th
    "test_curriculum.py::test_bad_curricula_are_refused_by_field": "contract",
    # initial distance = hypot; heavy mass 1.5
    "test_curriculum.py::test_set_episode_config_changes_the_next_episodes_and_restores": "formula",
    "test_curriculum.py::test_stages_reach_subprocess_envs_during_training": "contract",
    "test_curriculum.py::test_training_checkpoints_the_stage_and_resumes_in_it": "contract",
    # ---- test_datasets.py
    "test_datasets.py::test_navigate_dataset_round_trip": "library",  # minari.load_dataset, recover_environment, both check_envs
    # accepted and refused ids worked out from Minari's documented id form; Minari reads back 5 steps
    "test_datasets.py::test_names_are_checked_before_running": "hand",
    "test_datasets.py::test_behaviour_cloning_from_a_dataset": "contract",
    "test_datasets.py::test_image_observations_are_refused": "contract",
    "test_datasets.py::test_shielded_episodes_store_the_executed_actions": "formula",  # the action-box mapping written in the test
    # ---- test_demo.py
    "test_demo.py::test_view_runs_under_xvfb": "smoke",
    "test_demo.py::test_demo_with_gui_runs_under_xvfb": "smoke",
    "test_demo.py::test_demo_prints_the_report_and_leaves_video_and_plot": "contract",
    "test_demo.py::test_demo_without_a_model_says_so": "contract",
    # the committed model card's first episode
    "test_demo.py::test_demo_runs_the_shipped_dynamic_policy_and_reproduces_its_card": "golden",
    # ---- test_dwa.py
    # forward Euler and the arc v/w written in the test; the ramp from rest by hand
    "test_dwa.py::test_rollout_follows_the_closed_form_arc": "formula",
    "test_dwa.py::test_dynamic_window_samples_match_the_formula": "formula",  # the window and np.linspace written in the test
    "test_dwa.py::test_footprint_cost_follows_costmap_model_by_hand": "hand",  # outline costs 253, -1, 177, 0, -3 by hand
    "test_dwa.py::test_a_wall_ahead_turns_the_robot_toward_the_gap_on_its_left": "hand",
    "test_dwa.py::test_in_place_rotations_mark_the_stuck_side_and_moving_clears_it": "hand",
    "test_dwa.py::test_escape_backs_up_when_nothing_else_is_legal_and_only_where_the_env_allows_it": "hand",  # escape_vel -0.5
    "test_dwa.py::test_goal_tolerance_stop_then_rotate_by_hand": "hand",  # stopWithAccLimits and rotateToGoal worked by hand
    # move_base.cpp's default recovery list and abort message; two full turns
    "test_dwa.py::test_move_base_runs_its_default_recoveries_then_aborts_and_stands_still": "hand",
    "test_dwa.py::test_a_new_goal_preempts_and_a_mission_sends_one_goal_at_a_time": "hand",  # nearest / first goal by hand
    "test_dwa.py::test_barns_files_give_the_documented_values": "hand",  # BARN's files (commit bf5a226) and ROS's defaults
    "test_dwa.py::test_a_users_yaml_overrides_and_bad_keys_name_file_key_and_nearest": "contract",
    "test_dwa.py::test_suites_parse_dwa_controllers_with_params_and_env": "contract",
    "test_dwa.py::test_min_speed_lets_the_robot_back_up_and_changes_nothing_else": "hand",  # -0.3 m/s x 2 s, v / 0.5
    # never shorter than the evaluation's shortest path to the success disc
    "test_dwa.py::test_dwa_reaches_the_goal_in_warehouse_v0": "formula",
    "test_dwa.py::test_dwa_reaches_the_goal_in_barn_training_worlds": "formula",  # BARN's metric > 0: within 8 t_opt
    # ---- test_env.py
    "test_env.py::test_spaces_match_the_article": "hand",
    "test_env.py::test_checkers_pass_without_warnings_with_normalized_actions": "library",
    "test_env.py::test_checkers_pass_in_human_mode": "library",
    "test_env.py::test_physical_action_space_draws_only_the_normalisation_advice": "library",
    "test_env.py::test_rgb_array_render": "contract",
    "test_env.py::test_human_mode_without_display_raises_clearly": "contract",
    "test_env.py::test_human_mode_on_a_display_that_refuses_the_connection_raises_clearly": "contract",
    "test_env.py::test_gui_connect_holds_its_own_x_connection_until_pybullet_has_opened_one": "contract",
    "test_env.py::test_a_held_x_connection_keeps_a_resetting_server_from_refusing_clients": "library",  # a real Xvfb server
    # path length = sum of pose segments; initial distance = hypot
    "test_env.py::test_same_seed_is_bit_identical_across_resets": "formula",
    "test_env.py::test_seeded_reset_is_independent_of_history": "library",  # the reset scan against a Shapely ray cast
    "test_env.py::test_reward_terms_sum_to_the_reward": "formula",  # each term from the article's weights and formulas
    "test_env.py::test_every_observation_lies_in_the_observation_space": "formula",  # goal distance and bearing from the true pose
    "test_env.py::test_same_seed_gives_the_same_trajectory_in_two_processes": "self",
    "test_env.py::test_scripted_drive_to_a_nearby_goal_terminates_with_the_goal_term": "hand",
    "test_env.py::test_driving_into_a_wall_truncates_with_the_collision_term": "hand",
    "test_env.py::test_driving_into_a_wall_terminates_with_collision_terminates": "hand",  # stops with its front face at the wall
    "test_env.py::test_top_speed_into_a_wall_never_passes_through": "hand",
    "test_env.py::test_bad_actions_and_options": "hand",  # the clipped commands; the rest are errors
    "test_env.py::test_normalized_actions_map_onto_the_physical_range": "hand",
    "test_env.py::test_options_place_start_and_goal_exactly": "library",  # the placed pose's scan against Shapely
    "test_env.py::test_kwargs_reach_the_configs": "hand",
    "test_env.py::test_camera_observations": "library",
    "test_env.py::test_disabled_camera_changes_no_observation": "library",  # first scan = Shapely ray cast + N(0, 0.02) noise
    "test_env.py::test_lidar_rate_holds_each_scan_for_its_period": "hand",  # the every-second-step pattern
    "test_env.py::test_navigation_task_refuses_a_missing_sensor": "contract",
    "test_env.py::test_unknown_task_and_world_style_list_the_registered_ones": "contract",
    "test_env.py::test_yaml_world_uses_its_start_and_goal": "hand",
    "test_env.py::test_bench_env_cli_prints_the_ratio_with_its_provenance": "contract",
    # ---- test_episode_rules.py
    "test_episode_rules.py::test_the_hand_table_covers_every_registered_id": "hand",
    "test_episode_rules.py::test_the_evaluation_env_has_the_ids_own_rules_and_reward": "hand",
    "test_episode_rules.py::test_evaluate_model_builds_the_env_with_the_ids_rules": "hand",
    # the end flag from the hand table; the episode against gym.make(id)
    "test_episode_rules.py::test_driving_into_a_wall_ends_by_the_ids_rule": "hand",
    "test_episode_rules.py::test_the_published_metrics_do_not_depend_on_the_collision_flag": "self",
    # ---- test_features.py
    "test_features.py::test_footprint_matches_the_robots_collision_outline": "library",  # PyBullet ray casts against the robot body
    "test_features.py::test_closeness_is_one_at_contact_and_fades_with_clearance": "hand",
    "test_features.py::test_extractor_rejects_an_observation_shorter_than_the_scan": "contract",
    "test_features.py::test_point_clearance_matches_pybullet_closest_distance": "library",
    "test_features.py::test_point_metric_sees_an_edge_between_rays": "hand",
    "test_features.py::test_jackal_outline_by_hand_and_the_article_robots_unchanged": "hand",  # Jackal spec 0.508 x 0.430 m
    "test_features.py::test_jackal_footprint_matches_its_collision_outline_in_pybullet": "library",  # PyBullet ray casts
    # ---- test_fleet.py
    "test_fleet.py::test_parallel_api": "library",  # PettingZoo's parallel_api_test
    "test_fleet.py::test_aec_api": "library",  # PettingZoo's api_test
    "test_fleet.py::test_agents_and_truncation_together": "hand",
    # shape by hand from the documented table; heading and distance entries from pose and goal
    "test_fleet.py::test_spaces_equal_single_robot": "formula",
    # (v, w) of each action worked out from the documented ranges
    "test_fleet.py::test_each_robot_maps_actions_as_the_single_robot_env_does": "hand",
    "test_fleet.py::test_same_seed_same_episode_here_and_in_a_fresh_process": "self",
    "test_fleet.py::test_lidar_sees_other_robot_not_itself": "formula",  # range = robot face from its geometry
    "test_fleet.py::test_robot_robot_collision_stops_both_and_episode_goes_on": "hand",
    "test_fleet.py::test_errand_completes_pick_then_drop_and_next_is_assigned": "hand",
    # station clearance by Shapely from the obstacle footprints
    "test_fleet.py::test_stations_derived_from_an_aisle_warehouse": "library",
    "test_fleet.py::test_dock_moves_in_where_racks_line_every_wall": "hand",
    # dock stations clear of racks and walls by Shapely
    "test_fleet.py::test_procedural_floor_with_racks_on_every_wall_gets_a_dock": "library",
    "test_fleet.py::test_num_robots_out_of_range": "contract",
    "test_fleet.py::test_more_robots_than_fit": "contract",
    "test_fleet.py::test_world_without_stations": "contract",
    # path_length against the sum of step lengths of the true poses
    "test_fleet.py::test_shipped_dynamic_policy_runs_on_every_robot": "formula",
    # the planner's A* as a second algorithm
    "test_fleet.py::test_route_distance_follows_the_floor_plan_like_an_independent_a_star": "formula",
    # ---- test_fleet_bench.py
    # a fake clock with hand-set env and controller costs: every figure known by hand (was the benchmark's own sums)
    "test_fleet_bench.py::test_bench_fleet_rows_and_ratios_on_a_fake_clock": "hand",
    # ---- test_fleet_compare.py
    "test_fleet_compare.py::test_parse_entries_names_and_errors": "hand",
    # throughput per row by its formula; cells recomputed from the rows (statistics.stdev for the SE)
    "test_fleet_compare.py::test_every_entry_meets_the_same_episodes_and_workers_do_not_change_rows": "formula",
    # the (entry, episode, seed) rows by hand; cells recomputed from the rows
    "test_fleet_compare.py::test_an_interrupted_run_resumes_to_the_same_rows": "hand",
    "test_fleet_compare.py::test_rows_of_different_episodes_are_refused": "contract",
    "test_fleet_compare.py::test_bad_settings_name_the_argument": "contract",
    "test_fleet_compare.py::test_chunks_cover_every_entry_block_by_block": "hand",
    # the per-cell counts; the rows against the full run
    "test_fleet_compare.py::test_tables_of_a_stopped_run_cover_the_episodes_every_entry_has": "hand",
    # ---- test_fleet_controllers.py
    "test_fleet_controllers.py::test_reservation_table_refuses_vertex_and_swap_conflicts": "hand",
    "test_fleet_controllers.py::test_robust_reservations_keep_a_cell_after_it_is_left": "hand",
    # dynamic-programming brute force in the test
    "test_fleet_controllers.py::test_space_time_planner_passes_in_a_corridor_and_matches_brute_force": "formula",
    "test_fleet_controllers.py::test_two_robots_pressed_together_can_both_plan_out": "hand",
    "test_fleet_controllers.py::test_space_time_planner_equals_brute_force_on_random_grids": "formula",
    "test_fleet_controllers.py::test_free_grid_cost_is_the_static_distance": "hand",
    "test_fleet_controllers.py::test_plan_dependencies_order_each_cell_as_planned": "hand",
    # an executor at random speeds written in the test
    "test_fleet_controllers.py::test_dependency_execution_keeps_the_plans_collision_free_at_any_speed": "formula",
    "test_fleet_controllers.py::test_largest_component_drops_pockets_and_closed_moves": "hand",
    "test_fleet_controllers.py::test_priorities_rotate_round_robin": "hand",
    "test_fleet_controllers.py::test_coordinated_two_robots_no_robot_collision": "contract",
    "test_fleet_controllers.py::test_coordinated_crowded_dynamic_episode_keeps_the_plan_order": "contract",
    "test_fleet_controllers.py::test_restarts_plan_the_boxed_in_robots_first": "contract",
    "test_fleet_controllers.py::test_errand_navigator_replans_for_a_new_goal": "hand",
    "test_fleet_controllers.py::test_shield_sees_other_robots_as_movers_and_stops_short": "hand",
    "test_fleet_controllers.py::test_shields_of_two_robots_at_rest_do_not_both_take_the_gap": "contract",
    "test_fleet_controllers.py::test_shields_see_a_turning_robot_as_the_circle_its_corners_sweep": "contract",
    "test_fleet_controllers.py::test_make_controller_refuses_bad_names": "contract",
    "test_fleet_controllers.py::test_deadlock_detector": "hand",
    "test_fleet_controllers.py::test_throughput_arithmetic_and_errand_times": "hand",
    "test_fleet_controllers.py::test_near_miss_entries": "hand",
    "test_fleet_controllers.py::test_cli_fleet_json": "contract",
    "test_fleet_controllers.py::test_cli_fleet_bad_arguments": "contract",
    # SciPy ndimage components of the fine grid
    "test_fleet_controllers.py::test_cell_points_keep_a_passage_off_the_cell_centres_open": "library",
    "test_fleet_controllers.py::test_drive_cone_turns_a_robot_toward_a_point_behind_it_instead_of_driving_on": "hand",
    "test_fleet_controllers.py::test_unknot_commits_a_swapping_turn_to_one_side": "hand",
    "test_fleet_controllers.py::test_a_holding_robot_boxed_in_stands_rather_than_turn_in_place": "hand",
    "test_fleet_controllers.py::test_a_replan_keeps_the_next_move_of_a_robot_already_heading_into_it": "hand",
    "test_fleet_controllers.py::test_the_action_map_against_hand_values": "hand",
    # ---- test_fleet_golden.py
    "test_fleet_golden.py::test_fleet_rollout_is_bit_identical_to_the_reference": "golden",
    "test_fleet_golden.py::test_the_references_exercise_what_they_claim": "contract",  # a check on the golden file itself
    # ---- test_fleet_learning.py
    # SB3's VecMonitor: episode length 12 by hand, return summed in the test
    "test_fleet_learning.py::test_adapter_follows_the_vecenv_api": "library",
    # the autoreset written out in the test on a plain fleet
    "test_fleet_learning.py::test_autoreset_matches_a_fleet_stepped_by_hand": "formula",
    # episodes end together on step 12 (0.5 s at 24 Hz) and only there, 4 terminal observations
    "test_fleet_learning.py::test_seeded_runs_are_equal_step_for_step": "hand",
    "test_fleet_learning.py::test_batched_actions_match_per_robot_predict": "library",  # SB3's own predict per robot
    "test_fleet_learning.py::test_fleet_train_writes_a_safe_model_and_resumes": "hand",
    # ---- test_fleet_viz.py
    "test_fleet_viz.py::test_pictures_leave_the_episodes_unchanged": "self",
    "test_fleet_viz.py::test_video_of_episode_0_decodes_with_one_frame_per_step": "library",  # decoded by imageio/ffmpeg
    # disc centres by the world->pixel transform written in the test
    "test_fleet_viz.py::test_each_robot_is_drawn_in_its_colour_where_it_is": "hand",
    # each robot's disc in its colour at the pixel of its 1 s pose, transform written in the test
    "test_fleet_viz.py::test_still_frame_and_plot": "hand",
    # min pairwise distance of the drawn paths, brute force, against the row's min_separation_m
    "test_fleet_viz.py::test_plot_draws_every_robot_path_in_its_colour": "formula",
    "test_fleet_viz.py::test_cli_pictures_do_not_change_the_json": "library",  # video decoded by imageio: 1 + 24 frames by hand
    "test_fleet_viz.py::test_fleet_takes_the_world_arguments": "contract",
    "test_fleet_viz.py::test_view_robots_opens_the_gui_and_tints_every_robot": "contract",
    "test_fleet_viz.py::test_marks_are_told_apart_and_the_legend_shows_each": "hand",  # a 3 px gap between words
    "test_fleet_viz.py::test_fleet_table_leaves_out_the_rate_of_a_run_too_short": "hand",  # 4 errands in 120 s: 120.0/h
    "test_fleet_viz.py::test_comparison_table_leaves_out_the_rate_of_a_run_too_short": "hand",
    # ---- test_kinematic_kernels.py
    # every ray against every shape by the numpy ExactCaster (no culling, no shared arithmetic code)
    # the grid walk against the culled caster (bits) and the numpy caster that tests every shape
    "test_kinematic_kernels.py::test_grid_casts_are_the_culled_casts_to_the_bit_and_every_ray_against_every_shape": "formula",
    # the grid's cells against shapely's predicates, its leap distances against scipy's transform
    "test_kinematic_kernels.py::test_grid_lists_each_shape_where_it_lies_and_its_empty_distance_is_scipys": "library",
    "test_kinematic_kernels.py::test_culled_level_casts_equal_every_ray_against_every_shape": "formula",
    "test_kinematic_kernels.py::test_level_caster_refuses_uneven_fans_and_unknown_shapes": "contract",
    "test_kinematic_kernels.py::test_contact_test_agrees_with_shapely_distances": "library",
    # the closed-form arc written in the test; math.remainder
    "test_kinematic_kernels.py::test_drive_follows_exact_arcs_and_wraps_as_remainder": "formula",
    "test_kinematic_kernels.py::test_drive_stops_before_a_wall_and_marks_it": "hand",  # the wall 0.5 m ahead, 1/240 s substeps
    # ---- test_kinematic.py (PyBullet's full physics, physics="default", is the reference)
    # the outcome table against the suite's rows counted in the test
    "test_kinematic.py::test_bench_outcomes_pairs_each_world_with_its_kinematic_twin": "formula",
    "test_kinematic.py::test_a_model_trained_kinematic_is_evaluated_in_full_physics_unless_asked": "contract",
    "test_kinematic.py::test_scans_match_pybullet_in_every_world_source": "library",
    "test_kinematic.py::test_straight_drive_and_turn_in_place_end_where_pybullet_ends": "library",
    "test_kinematic.py::test_full_speed_contact_is_reported_at_pybullets_step": "library",
    "test_kinematic.py::test_env_checkers_pass": "library",
    # the default profile's set-up drawn by the same sampler code: agreement, not an independent value
    "test_kinematic.py::test_seeded_resets_give_pybullets_world_start_goal_and_movers": "self",
    "test_kinematic.py::test_step_parts_time_the_scenes_own_drive_and_lidar": "contract",
    "test_kinematic.py::test_refusals_are_one_line_naming_the_profile_that_serves": "contract",
    "test_kinematic.py::test_cli_refuses_the_gui_in_one_line": "contract",
    "test_kinematic.py::test_the_kinematic_trained_policy_scores_its_cards_episodes_in_full_physics": "golden",
    # ---- test_barn_passage.py
    "test_barn_passage.py::test_one_gap_in_a_row_of_touching_cylinders": "hand",
    "test_barn_passage.py::test_closed_row_and_open_room": "hand",
    # the hole's width from the kept centres, computed in the test
    "test_barn_passage.py::test_the_wider_of_two_ways_counts": "formula",
    # ---- test_live.py
    # read by tests/foxglove_client.py (websockets + mcap_ros2's decoder): the env's own lidar and odometry at each step
    "test_live.py::test_live_stream_is_the_env_step_by_step": "library",
    "test_live.py::test_unwatched_topics_are_not_built": "contract",
    "test_live.py::test_subscriptions_count_each_client": "hand",
    # sleeps on a fake clock against simulated-time deltas worked out in the test
    "test_live.py::test_pacing_follows_simulated_time": "hand",
    "test_live.py::test_parse_address": "hand",
    "test_live.py::test_parse_address_refuses": "contract",
    "test_live.py::test_cli_port_in_use_and_speed_alone": "contract",
    "test_live.py::test_cli_navigate_live_announces_and_finishes": "smoke",
    "test_live.py::test_grid_shortcut_is_the_serializer_byte_for_byte": "library",
    "test_live.py::test_fleet_stream_one_namespace_per_robot": "library",
    # ---- test_foxglove_client.py
    # against a real foxglove-sdk server, payloads encoded by mcap_ros2's encoder with values written in the test
    "test_foxglove_client.py::test_the_client_receives_and_decodes_what_the_server_logs": "library",
    "test_foxglove_client.py::test_a_late_subscriber_gets_what_is_logged_after_it_subscribes_and_a_closed_channel_goes": "library",
    "test_foxglove_client.py::test_two_clients_both_receive_everything_and_one_leaving_breaks_nothing": "library",
    # frames written byte by byte from the protocol spec (LE ids and stamps, CDR of 2.0)
    "test_foxglove_client.py::test_the_client_decodes_a_hand_made_frame_and_records_every_frame_the_protocol_forbids": "hand",
    # the foxglove-sdk server's own listener receives the client's advertisements and messages as sent
    "test_foxglove_client.py::test_the_client_publishes_what_a_foxglove_sdk_server_receives": "library",
    # ---- test_live_control.py
    # bulletnav's CDR decoder against mcap_ros2's serializer (and a big-endian Twist packed by hand)
    "test_live_control.py::test_cdr_decoder_reads_what_mcap_ros2_writes": "library",
    "test_live_control.py::test_cdr_decoder_refuses_malformed_twists": "contract",
    "test_live_control.py::test_cdr_decoder_refuses_malformed_strings_and_lengths": "contract",
    "test_live_control.py::test_goal_and_twist_readers_take_both_encodings_and_refuse_bad_ones": "hand",
    "test_live_control.py::test_origin_policy": "hand",
    "test_live_control.py::test_allow_origin_refuses_what_is_not_an_origin": "contract",
    # the robot read back from /tf by the test client (mcap_ros2 decodes, the test composes); the recording by MCAP's reader
    "test_live_control.py::test_a_client_publishes_goals_in_both_encodings_and_the_robot_gets_there": "library",
    # one message holds for 0.5 s at 24 Hz: 12 steps of the command on the stream's /cmd_vel
    "test_live_control.py::test_teleop_in_both_encodings_drives_the_robot_for_half_a_second_a_message": "hand",
    # PyBullet's closest points between robot and wall; the same commands without the shield hit it
    "test_live_control.py::test_a_teleop_burst_at_a_wall_passes_the_shield_without_touching_it": "library",
    "test_live_control.py::test_a_bad_goal_gets_a_status_error_and_changes_nothing": "contract",
    # refused by the websockets client's own handshake (HTTP 403); the robot read back from /tf
    "test_live_control.py::test_a_client_with_a_foreign_origin_cannot_drive": "contract",
    "test_live_control.py::test_cli_view_live_control_announces_drives_and_records": "contract",
    "test_live_control.py::test_cli_view_live_control_refuses": "contract",
    # ---- test_live_browser.py
    # a real Chromium (Playwright) sends the pages' Origin itself; the session's goal is the verdict
    "test_live_browser.py::test_a_page_of_another_site_cannot_drive_a_loopback_page_can": "library",
    # ---- test_fuzz.py
    "test_fuzz.py::test_layout_files": "contract",
    "test_fuzz.py::test_sweep_files": "contract",
    "test_fuzz.py::test_hyperparameter_files": "contract",
    "test_fuzz.py::test_benchmark_suite_files": "contract",
    "test_fuzz.py::test_env_kwargs_config": "contract",
    "test_fuzz.py::test_env_kwargs_make_reset_step": "contract",
    "test_fuzz.py::test_actions": "contract",
    "test_fuzz.py::test_reset_options": "contract",
    "test_fuzz.py::test_cli_arguments": "contract",
    "test_fuzz.py::test_hostile_documents_are_refused_by_every_loader": "contract",
    # ---- test_fuzz_models.py
    "test_fuzz_models.py::test_mutated_sidecars_load_or_give_a_model_error": "contract",
    "test_fuzz_models.py::test_mutated_sb3_data_loads_or_gives_a_model_error_and_never_runs_a_payload": "contract",
    "test_fuzz_models.py::test_random_bytes_as_statistics_or_weights_give_a_model_error": "contract",
    # ---- test_golden.py
    "test_golden.py::test_seeded_traces_are_bit_identical_to_the_references": "golden",
    "test_golden.py::test_shipped_policy_reproduces_its_episodes_bit_for_bit": "golden",
    "test_golden.py::test_pid_astar_reproduces_its_episodes_bit_for_bit": "golden",
    "test_golden.py::test_importing_bulletnav_pins_mkl_to_its_avx_kernels_unless_the_user_chose": "contract",
    # ---- test_golden_ids.py
    "test_golden_ids.py::test_rollouts_are_bit_identical": "golden",
    "test_golden_ids.py::test_reset_traces_are_bit_identical": "golden",
    # ---- test_guidance.py
    "test_guidance.py::test_in_open_floor_the_path_cost_is_the_straight_distance": "formula",
    "test_guidance.py::test_behind_a_rack_the_path_goes_around_it": "formula",  # a geometric lower bound and an unweighted Dijkstra
    # the start's path cost against the two-leg bound around the rack's ends; end cost >= straight line
    "test_guidance.py::test_progress_term_telescopes_to_the_drop_in_path_cost": "formula",
    # Shapely: the robot outline at every true pose keeps off the rack footprints
    "test_guidance.py::test_a_blind_guide_follower_completes_aisle_missions": "library",
    "test_guidance.py::test_guided_free_missions_follow_the_exact_tour_on_the_path_costs": "formula",  # brute force over every order
    "test_guidance.py::test_guidance_off_keeps_the_observation_and_checkers_pass_with_it_on": "library",
    "test_guidance.py::test_an_unknown_guidance_is_refused_by_name": "contract",
    # ---- test_hang.py
    "test_hang.py::test_a_child_past_its_limit_fails_the_test_as_a_suspected_hang_with_its_output": "contract",
    "test_hang.py::test_a_child_within_its_limit_gives_its_own_result": "hand",
    # ---- test_input_holes.py
    "test_input_holes.py::test_a_suite_policy_outside_the_allow_list_is_refused_naming_file_entry_and_value": "contract",
    "test_input_holes.py::test_the_runner_imports_no_class_outside_the_allow_list_even_from_a_hand_made_suite": "contract",
    "test_input_holes.py::test_the_cli_refuses_the_suite_in_one_line_with_status_2": "contract",
    "test_input_holes.py::test_trust_code_lets_the_cli_import_the_named_module": "contract",
    "test_input_holes.py::test_suite_names_are_slugs": "contract",
    "test_input_holes.py::test_sweep_names_are_slugs": "contract",
    "test_input_holes.py::test_default_names_from_the_file_are_slugs_too": "contract",
    "test_input_holes.py::test_output_folders_resolve_inside_their_base": "contract",
    "test_input_holes.py::test_a_run_never_writes_through_a_link_out_of_its_folder": "contract",
    "test_input_holes.py::test_a_bag_spanning_kilometres_is_refused_before_the_grid_is_allocated": "hand",
    "test_input_holes.py::test_map_cells_are_bounded_and_raisable": "hand",
    # NumPy's interpolation over the good poses alone
    "test_input_holes.py::test_nan_and_infinite_poses_are_dropped_and_counted": "library",
    "test_input_holes.py::test_a_lidar_mapper_refuses_bounds_that_are_not_numbers": "contract",
    "test_input_holes.py::test_map_resolution_is_read_as_metres": "contract",
    "test_input_holes.py::test_a_sidecar_asking_for_huge_networks_or_buffers_is_refused_before_building": "contract",
    "test_input_holes.py::test_a_sidecar_of_the_shipped_sizes_still_loads": "contract",
    "test_input_holes.py::test_buffer_size_and_n_envs_are_bounded": "contract",
    "test_input_holes.py::test_fleet_duration_and_robots_are_limits": "contract",
    "test_input_holes.py::test_the_suite_limits_are_in_the_one_table_and_raisable": "contract",
    "test_input_holes.py::test_dataset_ids_follow_minaris_rule": "library",  # Minari's own id parser
    "test_input_holes.py::test_a_bad_dataset_id_stops_navigate_before_any_episode": "contract",
    # the parsed argv against the paths by hand; the replayed row against the report's
    "test_input_holes.py::test_a_replay_command_from_a_report_replays_its_episode": "hand",
    # ---- test_interrupts.py
    "test_interrupts.py::test_benchmark_ctrl_c_says_how_to_resume_and_the_resume_reports_the_whole_run": "contract",
    "test_interrupts.py::test_benchmark_sigterm_with_two_workers_stops_them_and_keeps_whole_rows": "contract",
    "test_interrupts.py::test_benchmark_ctrl_c_with_two_workers_prints_nothing_from_them": "contract",
    "test_interrupts.py::test_train_ctrl_c_keeps_the_checkpoint_and_resumes_from_it": "contract",
    "test_interrupts.py::test_fleet_compare_ctrl_c_says_how_to_resume_and_resumes": "contract",
    "test_interrupts.py::test_navigate_ctrl_c_says_what_ran_and_that_nothing_resumes": "contract",
    "test_interrupts.py::test_dataset_recording_sigterm_writes_no_half_dataset": "contract",
    # ---- test_json_output.py
    "test_json_output.py::test_every_command_with_json_is_run_here": "contract",
    "test_json_output.py::test_json_is_the_whole_of_stdout": "contract",
    "test_json_output.py::test_the_gui_keeps_off_stdout_with_json": "contract",
    # ---- test_layout.py
    "test_layout.py::test_sample_layouts_load_and_admit_start_goal_pairs": "library",  # Shapely clearance, SciPy components, hypot
    "test_layout.py::test_bad_layout_files_name_file_and_field": "contract",
    "test_layout.py::test_unreadable_and_non_yaml_files": "contract",
    "test_layout.py::test_layout_round_trips_through_dict": "library",  # clearance against Shapely from the dict
    "test_layout.py::test_same_seed_same_layout_and_different_seed_different_layout": "hand",  # the article's 31 obstacles
    "test_layout.py::test_obstacle_count_is_configurable_and_gaps_hold": "formula",
    "test_layout.py::test_too_many_obstacles_raise_a_clear_error": "contract",
    "test_layout.py::test_sampler_respects_distance_clearance_and_reachability": "library",  # SciPy connected components
    # Shapely: no 2 m pair in either clear piece; a 1.5 m pair lies in one
    "test_layout.py::test_layout_without_valid_pair_raises": "library",
    "test_layout.py::test_disconnected_halves_are_not_reachable": "hand",
    # ---- test_limits.py
    # docs/limits.md defaults and variables written in the test
    "test_limits.py::test_every_limit_has_a_case_and_a_documented_row": "hand",
    "test_limits.py::test_accepted_at_the_limit": "hand",  # the documented default, by hand
    # value, hand limit and variable ending the line
    "test_limits.py::test_refused_just_above_with_field_value_limit_and_variable": "hand",
    "test_limits.py::test_raised_by_its_environment_variable": "hand",  # the variable named by hand
    "test_limits.py::test_lowered_by_its_environment_variable": "hand",  # 36 passes, 37 refused with the exact line
    "test_limits.py::test_a_bad_variable_is_named": "contract",
    "test_limits.py::test_env_kwargs_are_checked_before_a_world_is_built": "contract",
    "test_limits.py::test_max_episode_steps_through_make_env": "hand",  # 100,000 builds, 100,001 refused, exact line
    "test_limits.py::test_layout_files_name_file_field_and_limit": "hand",  # the whole line, one above each documented limit
    "test_limits.py::test_layout_at_the_limits_loads": "hand",  # the documented limits written out
    "test_limits.py::test_benchmark_suite_world_kwargs": "hand",  # 1000 / 8 pass, 1001 / 9 refused
    "test_limits.py::test_sweep_grid_is_refused_before_it_is_expanded": "hand",  # 10,000 trials pass, 10,001 refused
    "test_limits.py::test_mission_goals_option": "contract",
    "test_limits.py::test_tour_follows_the_goals_limit": "hand",
    # ---- test_messages.py
    # pybullet's own first import, run in the test, is the reference that the banner exists
    "test_messages.py::test_pybullet_banner_never_reaches_the_terminal": "library",
    "test_messages.py::test_yaml_errors_name_file_line_and_column": "hand",  # line 3, column 4 counted by hand
    "test_messages.py::test_yaml_error_positions": "hand",  # positions counted by hand in each text
    "test_messages.py::test_navigate_says_its_shortest_path_runs_to_the_goal_centre": "formula",  # the straight line
    "test_messages.py::test_frame_at_means_simulated_seconds_in_every_command": "contract",
    "test_messages.py::test_the_command_recorded_is_the_one_typed": "hand",
    # ---- test_map_frame.py
    "test_map_frame.py::test_a_map_far_off_the_origin_drives_and_records_in_its_own_frame": "hand",
    "test_map_frame.py::test_a_gazebo_world_off_the_origin_keeps_its_coordinates": "hand",
    "test_map_frame.py::test_a_layout_with_a_corner_round_trips_and_a_far_corner_is_refused": "hand",
    # ---- test_mission.py
    "test_mission.py::test_a_drive_through_three_goals_earns_two_subgoals_then_the_goal": "hand",
    "test_mission.py::test_free_order_heads_for_the_nearest_goal_and_fixed_for_the_first": "hand",
    "test_mission.py::test_the_navigator_visits_free_goals_in_the_optimal_order": "hand",
    "test_mission.py::test_observation_mission_block_matches_geometry": "formula",
    "test_mission.py::test_mission_step_limit_scales_with_the_goals": "hand",
    # SciPy components join start and goals; Shapely clearance
    "test_mission.py::test_sampled_missions_are_connected_and_apart": "library",
    # refused points inside a footprint / off the floor by Shapely; clear goals taken
    "test_mission.py::test_bad_mission_input_is_refused_with_the_value": "library",
    "test_mission.py::test_mission_env_passes_the_checkers": "library",
    "test_mission.py::test_yaml_goals_are_the_missions_goals_and_bad_ones_are_refused": "hand",
    # ---- test_mission_policy.py
    # sim time = steps / 24 Hz, SPL = S l / max(p, l) from each row
    "test_mission_policy.py::test_the_shipped_mission_policy_completes_unseen_missions": "formula",
    # hashlib SHA-256 of each safe file = its sidecar's digest
    "test_mission_policy.py::test_every_shipped_model_is_in_the_checkout": "library",
    # ---- test_movers.py
    "test_movers.py::test_forklift_body_follows_constant_speed_kinematics_back_and_forth": "formula",
    "test_movers.py::test_forward_lidar_ray_sees_a_crossing_forklift_at_the_analytic_range_and_window": "formula",
    "test_movers.py::test_forklift_stops_while_the_robot_is_in_its_safety_field": "hand",
    "test_movers.py::test_worker_stops_near_the_robot_and_yield_off_walks_on": "hand",
    "test_movers.py::test_collisions_are_classified_static_or_dynamic": "hand",
    "test_movers.py::test_nearest_mover_distance_is_the_outline_gap": "formula",
    "test_movers.py::test_pallet_events_never_disconnect_the_robot_from_its_goal": "formula",  # BFS written in the test
    "test_movers.py::test_same_seed_same_mover_trajectories_in_two_processes": "self",
    "test_movers.py::test_resets_on_one_layout_create_no_bodies": "contract",
    "test_movers.py::test_yaml_dynamic_errors_name_file_entry_and_field": "contract",
    "test_movers.py::test_scripted_events_add_and_remove_on_time_and_are_reported": "hand",
    "test_movers.py::test_lidar_map_forgets_cells_a_mover_left": "hand",
    "test_movers.py::test_dynamic_env_api_and_hash_of_its_first_steps_differs_by_seed": "library",
    "test_movers.py::test_dynamic_and_events_round_trip_through_yaml": "self",
    "test_movers.py::test_lidar_history_stacks_the_earlier_scans_newest_first": "self",
    "test_movers.py::test_a_forklift_reversing_beside_the_robot_does_not_sweep_it": "hand",
    "test_movers.py::test_mover_proximity_term_prices_the_outline_gap_and_is_off_by_default": "formula",
    # Shapely's polygon distance (was polygon_gap from the module under test)
    "test_movers.py::test_mover_gap_matches_shapelys_distance": "library",
    # growth of the Python heap (tracemalloc) and resident memory after warm-up, measured in one state; a 1 MiB per 100 resets leak
    # fails it (was ru_maxrss)
    "test_movers.py::test_memory_does_not_grow_over_200_resets": "contract",
    # ---- test_navigation.py
    "test_navigation.py::test_shortest_path_matches_geometry": "formula",
    # driven length as the sum of true step lengths; SPL by S*l/max(p,l) from the rows
    "test_navigation.py::test_pid_astar_navigates_procedural_warehouses": "formula",
    # driven length as the sum of true step lengths; SPL by its formula; A* episodes
    "test_navigation.py::test_other_planners_run_episodes": "formula",
    # true last pose inside the goal disc; straight-line shortest path; step lengths summed
    "test_navigation.py::test_odometry_pose_source_navigates_an_empty_room": "formula",
    "test_navigation.py::test_navigate_cli_json": "formula",  # success rate, SPL and mean length recomputed from the per-episode rows
    "test_navigation.py::test_navigate_cli_bad_world": "contract",
    # each run's driven length against the sum of its true step lengths; SPL by its formula
    "test_navigation.py::test_navigator_drives_an_env_with_normalized_actions_the_same_way": "formula",
    # ---- test_nothing_lost.py
    "test_nothing_lost.py::test_a_killed_training_leaves_whole_files_and_resumes": "contract",
    # the tiny suite's committed rows
    "test_nothing_lost.py::test_a_killed_benchmark_leaves_whole_files_and_resumes_to_the_same_rows": "golden",
    # the set read by zipfile, json and torch: hand-set step and mean, the second set's weights
    "test_nothing_lost.py::test_a_checkpoint_interrupted_after_its_commit_is_completed_whole": "library",
    # the set read by zipfile, json and torch: the first set's step, mean and weights
    "test_nothing_lost.py::test_a_checkpoint_interrupted_before_its_commit_leaves_the_previous_set": "library",
    "test_nothing_lost.py::test_a_checkpoint_without_statistics_removes_the_older_sets": "contract",
    "test_nothing_lost.py::test_a_checkpoint_commit_naming_other_files_is_refused": "contract",
    # ---- test_physics_profile.py
    # the 120 Hz row's errors, policy points and verdict recomputed from the raw rows
    "test_physics_profile.py::test_rate_table_structure": "formula",
    "test_physics_profile.py::test_reference_against_itself_is_exact": "self",
    "test_physics_profile.py::test_driving_is_physical": "formula",  # distance = v t, heading = w t, less the start-up
    "test_physics_profile.py::test_plate_collision_registers": "hand",
    "test_physics_profile.py::test_rates_are_checked": "contract",
    "test_physics_profile.py::test_fast_profile_keyword": "hand",  # the documented 96 Hz / 24 Hz, 4 substeps, else the default
    "test_physics_profile.py::test_unknown_profile_is_named": "contract",
    "test_physics_profile.py::test_cli_physics_flag": "contract",
    # ---- test_planning.py
    "test_planning.py::test_grid_rejects_bad_input": "contract",
    "test_planning.py::test_grid_coordinates_and_immutability": "hand",
    "test_planning.py::test_segment_free_matches_dense_sampling": "formula",
    "test_planning.py::test_inflate_matches_brute_force": "formula",
    "test_planning.py::test_astar_cost_matches_dijkstra": "library",  # SciPy's Dijkstra on an explicit graph
    "test_planning.py::test_astar_none_cases": "hand",
    "test_planning.py::test_astar_on_inflated_grid_avoids_inflated_cells": "library",
    "test_planning.py::test_rrt_paths_are_valid": "formula",  # dense sampling of every segment
    "test_planning.py::test_rrt_shortcut_never_lengthens": "formula",  # the shortcut paths free by dense sampling
    "test_planning.py::test_rrt_deterministic_per_seed": "self",
    # the paths by dense sampling; below the bisected smallest budget None, from it on the full path (was `path is None or path ==
    # full`)
    "test_planning.py::test_rrt_budget_only_truncates": "formula",
    "test_planning.py::test_rrt_none_cases": "hand",
    "test_planning.py::test_rrt_none_when_iterations_run_out": "hand",
    "test_planning.py::test_connected_matches_astar": "formula",
    "test_planning.py::test_narrow_cells_match_brute_force": "formula",
    "test_planning.py::test_narrow_problems_are_narrow": "library",  # SciPy's components once the narrow cells are closed
    # a fake clock with hand-set costs per call; the solve rates recounted with dense sampling (was keys only)
    "test_planning.py::test_bench_planners_times_each_call_and_counts_only_valid_paths": "hand",
    # ---- test_randomization.py
    "test_randomization.py::test_draws_stay_inside_the_declared_ranges_and_cover_them": "hand",
    # moments of 20,000 draws against closed forms (SciPy for the clipped normal)
    "test_randomization.py::test_draws_are_reproducible_under_the_seed_and_keep_the_episode": "formula",
    # one step of latency: still at the start after step 1
    "test_randomization.py::test_a_drawn_value_drives_the_same_physics_as_the_shift_itself": "hand",
    "test_randomization.py::test_world_parameters_reach_the_layout_and_mover_speeds_the_movers": "hand",
    "test_randomization.py::test_bad_specifications_are_refused_by_name": "contract",
    "test_randomization.py::test_every_shift_field_and_world_parameter_is_randomizable": "contract",
    "test_randomization.py::test_a_hyperparameter_file_with_a_bad_randomize_block_names_file_and_key": "contract",
    "test_randomization.py::test_the_ablation_files_differ_from_the_shipped_settings_only_in_their_arm": "contract",
    # ---- test_readme.py
    "test_readme.py::test_the_block_reader_on_a_made_up_page": "hand",
    # the output README shows under a block is the reference (recorded when the block was written)
    "test_readme.py::test_every_readme_python_block_runs_alone_and_prints_what_readme_shows": "golden",
    # ---- test_reference_kinds.py
    "test_reference_kinds.py::test_every_test_function_has_a_kind_and_every_kind_a_test_function": "contract",
    "test_reference_kinds.py::test_every_kind_is_one_of_the_documented_ones": "contract",
    "test_reference_kinds.py::test_the_collector_and_the_tables_on_a_made_up_folder": "hand",
    "test_reference_kinds.py::test_the_table_keeps_within_ruffs_line_length": "contract",
    # ---- test_report_browser.py
    "test_report_browser.py::test_report_in_chromium": "library",  # a real Chromium through Playwright
    # Chromium's layout boxes against the window's width (1,400 and 390 px)
    "test_report_browser.py::test_report_fits_the_window_with_every_controller_visible": "library",
    # the colours Chromium paints the legend in against the palette written in the module
    "test_report_browser.py::test_report_legend_shows_the_colours_the_maps_are_drawn_in": "library",
    "test_report_browser.py::test_report_replay_command_wraps_between_arguments_and_copies_as_one_line": "library",
    # ---- test_reset_kernels.py
    # the array code the kernels replaced
    # the compiled placement against the plain NumPy loop it replaced, kept in the test
    "test_reset_kernels.py::test_compiled_warehouse_placement_is_the_python_loops_to_the_bit": "formula",
    "test_reset_kernels.py::test_compiled_footprint_distance_is_the_array_codes_to_the_bit": "formula",
    "test_reset_kernels.py::test_occupancy_and_levels_equal_the_full_clearance_grid": "formula",
    "test_reset_kernels.py::test_compiled_line_of_sight_is_the_array_codes": "formula",
    # ---- test_rl.py
    # the final evaluation recomputed from episodes stepped in the test (_check_final_evaluation)
    "test_rl.py::test_short_training_of_each_algorithm_then_evaluate": "formula",
    # the recorded figures also recomputed from episodes stepped in the test, no evaluation code shared
    "test_rl.py::test_ppo_final_evaluation_is_the_saved_models": "formula",
    "test_rl.py::test_ppo_run_and_evaluate_report": "contract",
    "test_rl.py::test_save_load_predict_gives_identical_actions": "self",
    "test_rl.py::test_two_seeded_ppo_runs_give_identical_parameters": "self",
    # the wall-time bookkeeping to its 0.1 s rounding (the 2 s timing tolerances of 052a810 removed)
    "test_rl.py::test_resume_continues_from_the_checkpoint": "contract",
    "test_rl.py::test_init_from_starts_a_new_run_from_a_models_weights": "contract",
    "test_rl.py::test_the_evaluation_period_is_a_fifth_of_a_short_run_and_25000_steps_of_a_long_one": "hand",
    "test_rl.py::test_a_run_shorter_than_the_evaluation_period_draws_a_curve_of_five_points": "hand",
    "test_rl.py::test_stop_at_success_stops_when_an_evaluation_reaches_the_rate": "hand",
    "test_rl.py::test_bad_model_files_give_clear_errors": "contract",
    "test_rl.py::test_interrupted_checkpoint_write_leaves_the_old_model_intact": "contract",
    "test_rl.py::test_compare_plots_runs_and_tabulates": "contract",
    "test_rl.py::test_hyperparams_file_replaces_the_packaged_one": "hand",
    "test_rl.py::test_sb3_policy_and_navigator_run_the_same_episodes": "formula",  # initial distance against the straight line
    "test_rl.py::test_collision_terminates_reaches_the_training_envs_and_evaluation_drops_it": "hand",
    "test_rl.py::test_old_collision_terminal_key_is_upgraded": "contract",
    "test_rl.py::test_compare_groups_runs_by_hyperparameter_file": "hand",
    # the shares add to 1 and the rate is steps over seconds (the bound on the learning time removed)
    "test_rl.py::test_run_record_says_where_the_time_went": "self",
    "test_rl.py::test_vec_env_choice": "contract",
    # ---- test_rl_zoo.py
    # SB3's MlpPolicy with the extractor
    "test_rl_zoo.py::test_the_rl_zoo_form_builds_the_network_of_the_old_form_to_the_bit": "library",
    "test_rl_zoo.py::test_rl_zoo_trains_ppo_with_the_projects_hyperparameter_file": "library",  # rl_zoo3 and PPO.load
    # ---- test_robot.py
    "test_robot.py::test_geometry_is_read_from_the_urdf": "hand",
    "test_robot.py::test_straight_line_covers_the_commanded_distance_without_drift": "formula",
    "test_robot.py::test_turn_in_place_reaches_the_commanded_yaw_rate": "formula",
    "test_robot.py::test_arc_matches_kinematics": "formula",
    "test_robot.py::test_non_finite_command_is_refused": "hand",  # the exact line; the robot still at (0, 0, 0) a second later
    "test_robot.py::test_obstacles_meet_the_wheels_true_width": "hand",
    "test_robot.py::test_a_stopped_robot_stands_still_with_the_park_brake": "hand",
    "test_robot.py::test_the_park_brake_waits_for_the_wheels_to_slow_and_lets_go_on_the_next_command": "formula",
    "test_robot.py::test_park_brake_rate_must_not_be_negative": "hand",  # 0 allowed, -1e-9 and NaN refused with the exact line
    # ---- test_ros_bagmap.py
    "test_ros_bagmap.py::test_independent_bag_maps_the_known_room": "library",  # bag written by rosbags; walls by exact ray casts
    "test_ros_bagmap.py::test_bulletnav_bag_maps_onto_the_true_map": "formula",
    "test_ros_bagmap.py::test_bad_bags_are_refused": "contract",
    "test_ros_bagmap.py::test_map_png_has_a_legend_and_start_end_marks": "formula",  # start from the odometry, by hand
    "test_ros_bagmap.py::test_scans_take_the_poses_a_linear_search_gives": "formula",  # pose_at's rule by a linear search
    # ---- test_ros_bags.py
    "test_ros_bags.py::test_rosbags_bags_map_the_known_room": "library",  # .bag and .db3 written by rosbags; walls by exact casts
    "test_ros_bags.py::test_a_lone_db3_and_a_bag_directory_read_alike": "self",
    "test_ros_bags.py::test_bad_rosbags_are_refused_naming_the_file": "contract",
    "test_ros_bags.py::test_format_ros_is_what_map_server_reads": "library",  # read back by PyYAML and Pillow, cell by cell
    "test_ros_bags.py::test_format_ros_round_trips_through_the_world_reader": "self",
    "test_ros_bags.py::test_format_ros_needs_an_out_stem_and_keeps_existing_files": "contract",
    # ---- test_ros_record.py
    "test_ros_record.py::test_types_counts_and_stamps": "library",  # read back with mcap_ros2
    "test_ros_record.py::test_scan_equals_the_env_lidar": "library",
    "test_ros_record.py::test_tf_chain_reaches_the_true_pose": "library",
    "test_ros_record.py::test_maps_movers_and_metadata": "library",
    "test_ros_record.py::test_the_encoder_writes_mcap_ros2_supports_bytes_for_every_type": "library",  # its serializer
    "test_ros_record.py::test_message_definitions_parse_as_ros2_types": "library",
    "test_ros_record.py::test_refusals_and_abort_leave_nothing": "contract",
    "test_ros_record.py::test_cli_navigate_records": "library",
    "test_ros_record.py::test_camera_topics": "library",
    "test_ros_record.py::test_fleet_recording_one_namespace_per_robot": "library",
    "test_ros_record.py::test_cli_fleet_and_evaluate_record": "library",
    # ---- test_ros_replay.py
    "test_ros_replay.py::test_replay_draws_the_live_frames": "hand",  # the frame count; the pictures against the live video
    # 200 steps of 1/24 s per episode, counted and timed with mcap's reader
    "test_ros_replay.py::test_recording_holds_what_replay_needs": "hand",
    "test_ros_replay.py::test_replay_refuses_what_is_no_recording": "contract",
    # every topic the layout names is a channel of the recording, as mcap's reader lists them
    "test_ros_replay.py::test_foxglove_layout_and_panel": "library",
    "test_ros_replay.py::test_replay_frame_has_no_depth_bar_and_frame_at_is_checked": "hand",  # 200 / 24 = 8.33 s
    # ---- test_rrt_fresh_process.py
    # every path clear of the occupied cells by Shapely
    "test_rrt_fresh_process.py::test_first_call_in_fresh_process_solves_narrow_passage": "library",
    "test_rrt_fresh_process.py::test_same_paths_in_this_process": "self",
    "test_rrt_fresh_process.py::test_compiling_inside_the_first_call_changes_nothing": "self",
    # ---- test_safe_models.py
    "test_safe_models.py::test_a_crafted_zip_entry_is_refused_and_never_runs": "contract",
    "test_safe_models.py::test_a_payload_in_any_entry_never_runs": "contract",
    "test_safe_models.py::test_a_crafted_vecnormalize_pickle_is_refused_and_never_runs": "contract",
    # actions against a NumPy forward pass from the safetensors arrays
    "test_safe_models.py::test_a_pickle_beside_safe_files_is_never_opened": "formula",
    "test_safe_models.py::test_a_crafted_tensor_file_is_refused": "contract",
    # the recorded digest is hashlib's SHA-256 of the file
    "test_safe_models.py::test_safe_files_that_were_tampered_with_are_refused": "library",
    "test_safe_models.py::test_pickle_globals_reads_names_without_importing": "hand",
    "test_safe_models.py::test_shipped_models_load_from_the_safe_format_and_act_as_the_zip": "library",  # SB3's own zip loader
    "test_safe_models.py::test_normalizer_matches_vecnormalize_arithmetic": "library",  # SB3's VecNormalize
    # the shipped files' bytes
    "test_safe_models.py::test_convert_model_needs_trust_for_a_pickle_and_reproduces_the_shipped_files": "golden",
    "test_safe_models.py::test_broken_statistics_and_sidecars_are_clear_errors": "contract",
    "test_safe_models.py::test_hyperparameter_files_name_only_allowed_classes": "contract",
    # actions against a NumPy forward pass from the shipped arrays
    "test_safe_models.py::test_a_pickled_schedule_function_is_not_run_and_the_model_still_acts": "formula",
    # ---- test_sensors.py
    "test_sensors.py::test_lidar_reads_a_wall_at_a_known_distance": "formula",
    "test_sensors.py::test_lidar_never_sees_the_robot_and_reads_max_range_in_the_open": "hand",
    "test_sensors.py::test_lidar_noise_has_the_configured_std": "formula",
    "test_sensors.py::test_sensor_reads_are_idempotent_within_a_step": "hand",  # the room's wall distances, reads within 5 sigma
    # ray ahead = 2 m - x - lidar offset while driving at the wall
    "test_sensors.py::test_every_sensor_reading_lies_in_its_space": "formula",
    "test_sensors.py::test_depth_camera_centre_pixel_reads_the_wall_distance": "formula",
    "test_sensors.py::test_imu_noise_statistics_and_gravity_at_rest": "formula",
    "test_sensors.py::test_imu_bias_and_rotation_rate": "formula",
    "test_sensors.py::test_odometry_tracks_ground_truth": "formula",  # against PyBullet's true pose
    # ---- test_shield_memory.py
    "test_shield_memory.py::test_the_blind_sector_is_the_270_degree_lidars_back_and_a_full_circle_has_none": "hand",
    "test_shield_memory.py::test_a_point_leaving_the_view_is_remembered_where_odometry_puts_it_and_dropped_when_seen": "formula",
    "test_shield_memory.py::test_remembered_points_beyond_the_radius_or_on_the_robot_are_forgotten": "hand",
    "test_shield_memory.py::test_a_remembered_cylinder_in_the_blind_sector_stops_a_turn_the_scan_alone_lets_through": "hand",
    "test_shield_memory.py::test_backing_up_sweeps_the_forward_sweep_mirrored_and_stays_within_the_room_behind": "formula",
    "test_shield_memory.py::test_the_wheel_sweep_brakes_by_the_closed_form_and_turns_late_while_the_wheels_speed_up": "formula",
    "test_shield_memory.py::test_the_jackal_gets_the_wheel_sweep_and_the_gyro_and_the_article_robot_keeps_its_shield": "contract",
    "test_shield_memory.py::test_a_command_against_the_roll_waits_for_the_robot_to_stop": "contract",
    "test_shield_memory.py::test_random_commands_behind_the_shield_never_touch_a_cylinder_in_barn_worlds": "contract",
    # ---- test_shield.py
    # reach = v dt + v^2 / 2a past the front face
    "test_shield.py::test_a_wall_inside_the_stopping_sweep_stops_a_forward_command_and_one_just_beyond_does_not": "formula",
    "test_shield.py::test_the_same_command_passes_unchanged_with_the_wall_3_m_away": "hand",
    # scan of the box ray-cast in the test
    "test_shield.py::test_a_turn_that_sweeps_a_box_corner_is_vetoed_and_one_that_clears_it_is_not": "formula",
    "test_shield.py::test_the_wrapper_reports_its_decision_and_passes_actions_bit_for_bit_when_clear": "self",
    "test_shield.py::test_the_sweep_ends_where_the_closed_form_stop_does": "formula",
    "test_shield.py::test_turning_in_place_inside_the_margin_may_turn_away_from_a_wall_but_never_into_it": "formula",
    # Shapely's clearance after every step, beside PyBullet's contact report
    "test_shield.py::test_fuzz_random_and_ramming_drivers_never_touch_anything_behind_the_shield": "library",
    # the unshielded ram's collision rate 1.0; the rest: one wrapper against the other
    "test_shield.py::test_the_policy_wrapper_and_the_env_wrapper_run_the_same_episodes_and_evaluation_counts_them": "hand",
    "test_shield.py::test_navigate_and_evaluate_take_shield_and_report_it": "contract",
    "test_shield.py::test_video_tints_the_robot_on_shielded_steps": "contract",
    "test_shield.py::test_bench_shield_drives_with_a_trained_model_and_times_its_creeps_apart": "contract",
    "test_shield.py::test_dashboard_shows_the_shields_share_of_steps_in_a_static_world": "contract",
    "test_shield.py::test_a_stop_always_passes_and_a_blocked_command_held_for_long_gets_turns_not_a_deadlock": "hand",
    "test_shield.py::test_stuck_beside_a_waiting_worker_it_creeps_through_the_gap_without_coming_closer": "formula",
    "test_shield.py::test_it_never_creeps_toward_a_waiting_worker_dead_ahead": "hand",
    "test_shield.py::test_the_veto_becomes_stuck_after_patience_steps_and_forgets_at_reset": "contract",
    "test_shield.py::test_a_box_corner_between_two_rays_is_rebuilt": "formula",
    "test_shield.py::test_a_shielded_episode_among_movers_reproduces_the_committed_result_to_the_bit": "golden",
    "test_shield.py::test_with_a_creep_floor_it_does_not_creep_along_a_gap_narrower_than_the_floor": "formula",
    "test_shield.py::test_nearer_than_the_floor_it_still_creeps_away_from_what_it_is_near": "formula",
    # 512 training steps by hand (one rollout), each a ShieldWrapper decision (was the recorded flag only)
    "test_shield.py::test_train_with_the_shield_in_the_loop_steps_every_training_step_through_it": "hand",
    # Shapely's clearance after every step; a fake clock with hand-set costs for the timings (was plausibility only)
    "test_shield.py::test_bench_shield_times_each_decision_and_its_drive_keeps_clear_by_shapely": "library",
    # ---- test_shifts.py
    "test_shifts.py::test_a_slippery_floor_brakes_no_harder_than_coulomb_friction_allows": "formula",
    "test_shifts.py::test_mass_and_motor_force_change_the_acceleration_as_newton_says": "formula",
    "test_shifts.py::test_a_miscalibrated_odometry_model_drifts_by_its_error": "formula",
    "test_shifts.py::test_latency_delays_the_motion_by_whole_control_steps": "hand",
    "test_shifts.py::test_lidar_dropout_and_imu_noise_scale_as_declared": "formula",
    "test_shifts.py::test_a_shift_keeps_the_episode_and_reports_itself": "hand",
    "test_shifts.py::test_unknown_names_and_bad_values_are_refused_clearly": "contract",
    # driven length as the sum of true step lengths, sim time = steps / 24
    "test_shifts.py::test_every_named_shift_runs_a_controller": "formula",
    # ---- test_simulation.py
    # the obstacle counts; the poses against a third client
    "test_simulation.py::test_two_worlds_in_one_process_stay_independent": "hand",
    # no sideways slide, v = r (wl + wr) / 2
    "test_simulation.py::test_robot_snapshot_equals_live_state_after_every_step_and_reset": "formula",
    "test_simulation.py::test_same_layout_reset_teleports_without_rebuilding": "hand",
    "test_simulation.py::test_seeded_rollouts_are_bit_identical": "formula",  # path = v t less start-up; no sideways step
    "test_simulation.py::test_thousand_resets_do_not_grow_memory": "contract",
    # ---- test_sweep.py
    "test_sweep.py::test_sweep_file_errors_name_the_file_and_field": "contract",
    "test_sweep.py::test_sweep_cli_reports_a_malformed_file_without_a_traceback": "contract",
    "test_sweep.py::test_sweep_file_defaults_and_grid_expansion": "hand",
    "test_sweep.py::test_sweep_shipped_files_are_valid": "contract",
    # an independent resampling loop, and [0, 1]'s quantiles by hand (the self-equality of 052a810 removed)
    "test_sweep.py::test_sweep_bootstrap_interval_matches_an_independent_resampling": "formula",
    "test_sweep.py::test_sweep_summary_groups_seeds_and_ranks_by_the_metric": "hand",
    # the trials' scores recomputed from episode rows a loop in the test collects (was evaluate_model, the sweep's own scorer)
    "test_sweep.py::test_sweep_two_trials_run_on_the_two_worker_nodes": "formula",
    "test_sweep.py::test_sweep_a_failing_trial_is_reported_and_the_others_finish": "contract",
    "test_sweep.py::test_sweep_optimize_writes_a_hyperparameter_file_train_accepts": "contract",
    "test_sweep.py::test_sweep_interrupted_with_ctrl_c_resumes_without_rerunning_finished_trials": "contract",
    # ---- test_tour.py
    "test_tour.py::test_tour_matches_brute_force_on_random_matrices": "formula",
    "test_tour.py::test_free_order_beats_the_given_order_where_they_differ": "hand",
    "test_tour.py::test_tour_rejects_bad_input": "contract",
    # ---- test_user_maps.py
    "test_user_maps.py::test_thresholds_are_nav2s_on_hand_values": "hand",  # Nav2's formula worked by hand per pixel
    "test_user_maps.py::test_image_rows_run_from_the_top": "hand",
    "test_user_maps.py::test_merged_boxes_cover_exactly_the_occupied_cells": "formula",  # boxes rasterised in the test
    "test_user_maps.py::test_walls_merge_into_few_boxes": "hand",
    # walls from the pixel values in the test
    "test_user_maps.py::test_a_map_lives_in_its_own_frame_its_boxes_on_its_wall_cells": "hand",
    "test_user_maps.py::test_a_turned_map_is_resampled_in_the_map_frame": "formula",
    "test_user_maps.py::test_hand_made_map_driven_by_pid_astar": "hand",  # a PGM and YAML written by hand; the goal by hand
    "test_user_maps.py::test_sdf_poses_compose": "hand",
    "test_user_maps.py::test_sdf_state_is_applied_as_gazebo_loads_it": "hand",
    "test_user_maps.py::test_hand_written_world_driven_by_pid_astar": "hand",  # SDF text written by hand; start and goal by hand
    "test_user_maps.py::test_fleet_runs_in_a_hand_made_map_with_stations_in_its_frame": "hand",  # map origin worked by hand
    "test_user_maps.py::test_sdf_refusals_name_the_file_and_model": "contract",
    "test_user_maps.py::test_map_server_refusals_name_the_file_and_field": "contract",
    "test_user_maps.py::test_navigate_cli_refuses_a_mesh_world_in_one_line": "contract",
    "test_user_maps.py::test_mutated_maps_and_worlds_load_or_fail_with_a_layout_error": "contract",
    # ---- test_vector.py
    # batched goal distances = hypot(goal - pose); autoreset reward 0
    "test_vector.py::test_make_vec_sync_is_seeded_autoresets_and_batches_info": "formula",
    "test_vector.py::test_make_vec_async_gives_the_sync_batch": "formula",  # the async batch's goal distances = hypot(goal - pose)
    # ---- test_viz.py
    "test_viz.py::test_video_frames_are_composed_and_counted": "library",  # decoded by imageio; the documented frame count
    # the side video decoded by imageio: the documented frame count of each traced episode
    "test_viz.py::test_recording_leaves_the_episode_unchanged": "library",
    "test_viz.py::test_dashboard_needs_the_gui": "contract",
    "test_viz.py::test_simplify_path_keeps_corners_and_caps_segments": "hand",
    "test_viz.py::test_dashboard_throttles_and_replaces_in_place": "hand",
    "test_viz.py::test_trajectory_log_and_plots": "hand",
    "test_viz.py::test_bench_gui_reports_frame_rates": "hand",  # the documented render count
    "test_viz.py::test_the_legend_names_the_robots_own_parts_the_camera_sees": "hand",  # diff_drive.urdf's materials
    # ---- test_viz_mission.py
    "test_viz_mission.py::test_visit_order_ranks_by_step": "hand",
    "test_viz_mission.py::test_mission_plot_numbers_goals_and_visit_order": "hand",
    "test_viz_mission.py::test_mission_plot_marks_unvisited_goals": "hand",
    "test_viz_mission.py::test_single_goal_plot_has_no_mission_artists": "hand",
    "test_viz_mission.py::test_mission_video_numbers_goals_and_shows_progress": "contract",
    "test_viz_mission.py::test_dashboard_marks_every_goal_and_progress": "hand",
    # ---- test_viz_movers.py
    # each final footprint against its Shapely shape from the mover's last pose
    "test_viz_movers.py::test_plot_draws_one_route_per_mover_with_trail_and_footprint": "library",
    "test_viz_movers.py::test_scripted_events_are_marked_on_the_plot": "hand",
    "test_viz_movers.py::test_static_world_logs_and_plots_no_movers_or_events": "hand",
    # pixels at positions from the map transform written in the test
    "test_viz_movers.py::test_video_map_shows_movers_events_and_a_text_line": "hand",
    "test_viz_movers.py::test_recording_and_logging_leave_a_dynamic_episode_unchanged": "self",
    "test_viz_movers.py::test_dashboard_draws_routes_once_and_event_messages": "hand",
    # the session of 2026-11-29 (07:09): hostile inputs round 3, the Jackal shield's gyro memory, BARN figures
    "test_barn_controllers.py::test_navigate_on_barn_reports_barns_figures_per_episode_and_in_total": "formula",
    "test_barn_env.py::test_barn_refuses_keywords_that_change_its_rules_and_defaults_to_a_training_world": "contract",
    "test_benchmark_docs.py::test_the_docs_example_suite_runs_as_written": "smoke",
    "test_demo.py::test_model_takes_the_run_directory_train_wrote_and_says_which_file_it_loaded": "contract",
    "test_interrupts.py::test_a_second_ctrl_c_during_a_slow_cleanup_ends_the_command_at_once": "contract",
    "test_interrupts.py::test_a_signal_inside_a_c_call_that_never_returns_ends_the_command_at_once": "contract",
    "test_interrupts.py::test_a_signal_while_the_interrupted_line_is_printed_waits_for_it_then_ends_the_process": "contract",
    "test_messages.py::test_output_of_another_thread_while_pybullet_loads_is_delayed_not_lost": "hand",
    "test_raycast.py::test_vertical_rays_hit_only_the_cylinders_they_start_over": "hand",
    "test_ros_bags.py::test_a_db3_is_read_for_the_topics_the_map_needs_only": "self",
    "test_ros_bags.py::test_a_db3_whose_tables_are_views_is_refused_at_once": "contract",
    # the corner's point is placed from the wheel sweep (the code's), and checked by hand against the plain sweep
    "test_shield_memory.py::test_close_to_a_wall_a_back_up_out_of_a_turn_is_checked_along_the_turn_the_wheels_keep": "hand",
    "test_shield_memory.py::test_the_jackal_stopping_out_of_a_fast_turn_brakes_at_its_rims_and_keeps_turning": "formula",
    "test_shield_memory.py::test_a_remembered_cylinder_whose_near_side_was_never_seen_still_stops_a_turn": "hand",
    "test_shield_memory.py::test_driving_away_from_a_remembered_wall_is_not_refused_for_the_memory_margin": "hand",
    "test_shield_memory.py::test_random_commands_backing_up_in_barn_world_68_stay_off_the_cylinder_their_memory_half_saw": "golden",
    "test_shield_memory.py::test_a_fast_turn_is_refused_where_only_the_turn_held_through_a_hard_stop_comes_close": "hand",
    "test_shield_memory.py::test_the_jackal_shield_carries_its_memory_by_the_gyro_where_the_wheels_drift": "library",
    "test_user_maps.py::test_a_map_yamls_typos_are_map_typos_and_an_image_or_model_as_a_world_says_what_belongs": "contract",
    "test_user_maps.py::test_hostile_map_server_maps_are_refused_in_one_line_before_the_work_grows": "contract",
    "test_file_typos.py::test_a_file_given_where_another_kind_belongs_is_named_for_what_it_is": "contract",
    "test_file_typos.py::test_each_kind_is_told_by_its_bytes_and_a_misspelt_file_of_a_kind_stays_its_kind": "hand",
    "test_file_typos.py::test_a_misspelt_key_or_a_wrong_type_is_one_line_and_exit_2": "contract",
    "test_file_typos.py::test_an_env_that_a_worker_cannot_build_is_one_line_not_a_connection_reset": "contract",
    "test_ros_bagmap.py::test_scans_without_a_ray_direction_are_dropped_and_counted_and_careless_map_options_refused":
        "contract",
    "test_interrupts.py::test_a_forked_child_and_a_library_that_takes_ctrl_c_do_not_end_the_command": "contract",
}


def collect(folder: Path = TESTS) -> list[str]:
    """Every test function in ``folder``'s ``test_*.py`` files, read from their source: functions
    named ``test*`` at module level or in a ``Test*`` class (``module::Class::name``)."""
    names = []
    for path in sorted(folder.glob("test_*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith("test"):
                names.append(f"{path.name}::{node.name}")
            elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
                names += [f"{path.name}::{node.name}::{sub.name}" for sub in node.body
                          if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)) and sub.name.startswith("test")]
    return names


def counts(kinds: dict[str, str] = KINDS) -> tuple[Counter, dict[str, Counter]]:
    """The number of test functions of each kind, overall and per module."""
    per_module: dict[str, Counter] = {}
    for name, kind in kinds.items():
        per_module.setdefault(name.split("::")[0], Counter())[kind] += 1
    return sum(per_module.values(), Counter()), dict(sorted(per_module.items()))


def _row(label: str, c: Counter) -> str:
    total = sum(c.values())
    independent = sum(c[k] for k in INDEPENDENT)
    cells = " | ".join(str(c[k]) if c[k] else "" for k in ORDER)
    return f"| {label} | {total} | {cells} | {independent} ({100 * independent / total:.0f} %) |"


def markdown(kinds: dict[str, str] = KINDS) -> str:
    """The overall and per-module counts by kind as two Markdown tables."""
    overall, per_module = counts(kinds)
    head = "| | tests | " + " | ".join(ORDER) + " | independent |\n|---|--:|" + "--:|" * len(ORDER) + "--:|"
    lines = ["Overall:", "", head, _row("all", overall), "", "Per module:", "", head]
    lines += [_row(f"`{module}`", c) for module, c in per_module.items()]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.stdout.write(markdown())
