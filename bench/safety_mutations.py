"""The curated mutations of safety-critical code that bench/mutation_bench.py runs.

Each replaces one exact text of one file (`original`, exactly once in it) by `replacement`,
says in domain words what it breaks, and names the tests that should catch it, fastest first.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Mutation:
    """One mutation: `original` (exactly once in `file`) becomes `replacement`."""

    id: str
    file: str
    original: str
    replacement: str
    what: str  # what it breaks, in domain words
    tests: tuple[str, ...]  # pytest node ids that should catch it, fastest first
    kernels: str = 'c'  # 'c' as installed, 'python' none, 'build' rebuilt from the copy
    dds: bool = False


M = Mutation
MUTATIONS: tuple[Mutation, ...] = (
    # -- E2E counter and CRC (agv_nodes/records/) --------------------------------------------
    M('crc-polynomial', 'agv_nodes/records/e2e.py', 'POLY = 0x1D', 'POLY = 0x1B',
      'the CRC-8 is no longer SAE J1850 (every port agrees, no outside ECU would)',
      ('test/test_records.py::test_crc8_sae_j1850_check_value',)),
    M('crc-without-data-id', 'agv_nodes/records/e2e.py',
      'crc = CRC_TABLE[INIT ^ data_id]  #', 'crc = CRC_TABLE[INIT]  #',
      "the general path's CRC leaves out the data_id: one record taken for another",
      ('test/test_records.py::test_e2e_crc_covers_data_id',
       'test/test_records.py::test_e2e_counter_and_crc_bytes')),
    M('crc-check-skipped', 'agv_nodes/records/schema.py',
      'if data[CRC_BYTE - 1] != crc:', 'if data[CRC_BYTE - 1] != data[CRC_BYTE - 1]:',
      'a record with a bad CRC is decoded and acted on (general path)',
      ('test/test_records.py::test_decode_errors_carry_their_reject_code',
       'test/test_records_properties.py::test_any_corruption_of_a_protected_record_is_caught')),
    M('crc-check-skipped-fast', 'agv_nodes/records/fast_paths.py',
      "check.append(f'    if d15 != c ^ {XOROUT}: return None')", 'pass',
      'the generated Python fast path takes a bad CRC (the C codec left out)',
      ('test/test_safety_mutants.py::test_a_port_rejects_any_single_byte_corruption_of_a_new_'
       'record_as_bad_crc',),
      kernels='python'),
    M('crc-check-skipped-c', 'agv_nodes/records/_codec.c',
      'if (d[15] != (c ^ self->xorout))', 'if (0)',
      'the C codec takes a bad CRC (rebuilt from the mutated C)',
      ('test/test_safety_mutants.py::test_a_port_rejects_any_single_byte_corruption_of_a_new_'
       'record_as_bad_crc',
       'test/test_record_codec_kernel.py::test_c_checks_as_the_generated_python_checks'),
      kernels='build'),
    M('counter-repeat-taken', 'agv_nodes/records/ports.py',
      'counter == (last + 1) & 0xFF and not sequence.runs',
      'counter in (last, (last + 1) & 0xFF) and not sequence.runs',
      'a repeated counter (a replay, no new data) is taken as a fresh record',
      ('test/test_records_properties.py::test_reader_rejects_replay_and_counts_reasons',)),
    M('counter-window-doubled', 'agv_nodes/records/e2e.py',
      'if delta <= self.max_delta:', 'if delta <= 2 * self.max_delta:',
      'a counter jump of up to twice max_delta is accepted as records lost',
      ('test/test_records_properties.py::test_reader_sequence_rules',
       'test/test_record_oracle.py::test_the_reader_follows_the_counter_rules_for_any_window')),
    M('counter-went-back-taken', 'agv_nodes/records/e2e.py',
      'if delta > 0xFF - self.max_delta:', 'if delta > 0xFF:',
      'a counter that went back (late or replayed) may start a run and resynchronise',
      ('test/test_records_properties.py::test_replaying_the_last_records_in_order_never_moves'
       '_the_reader_back',)),
    M('counter-sync-too-soon', 'agv_nodes/records/e2e.py',
      'if length >= self.sync_records:', 'if length >= self.sync_records - 1:',
      'a jump is followed after N-1 records, not N (a foreign writer takes over sooner)',
      ('test/test_records_properties.py::test_a_restarted_writer_is_followed_after_n_records'
       '_in_a_row',)),
    M('counter-jump-moves-reference', 'agv_nodes/records/e2e.py',
      '            self.runs[counter] = 1\n',
      '            self.runs[counter] = 1\n            self.last = counter\n',
      'a rejected jump moves the reference, so the next genuine record looks out of sequence',
      ('test/test_records_properties.py::test_a_rejected_jump_costs_no_genuine_record',)),
    M('corrupt-crc-not-corrupt', 'agv_nodes/records/ports.py',
      'CORRUPT = frozenset(r.value for r in (Reject.BAD_CRC, Reject.WRONG_LENGTH,',
      'CORRUPT = frozenset(r.value for r in (Reject.WRONG_LENGTH,',
      'a bad-CRC command no longer counts as corrupt: traction runs on instead of tripping',
      ('test/test_traction.py::test_corrupt_record_trips',)),
    # -- writer identity and duplicates ---------------------------------------------------
    M('foreign-writer-genuine', 'agv_nodes/records/writer_check.py',
      '        if gid not in self.genuine:\n            return data, gid, FOREIGN_WRITER',
      '        if gid not in self.nodes:\n            return data, gid, FOREIGN_WRITER',
      "any endpoint the graph names is taken as the writer, not only the schema's writer node",
      ('test/test_records_writer_check.py::test_the_named_writer_is_genuine_and_every_other_'
       'endpoint_foreign',)),
    M('unnamed-writer-taken-early', 'agv_nodes/records/writer_check.py',
      'return self._clock() - first >= self._patience_s',
      'return self._clock() - first >= 0.0',
      'a sample whose writer the graph has not named yet is judged at once, not held',
      ('test/test_records_writer_check.py::test_a_writer_the_graph_names_late_is_held_then_'
       'released_in_order_not_rejected',)),
    M('writer-restart-unseen', 'agv_nodes/records/writer_check.py',
      'if (current is not None and gid != current) or self._resume:',
      'if self._resume:',
      'the genuine writer under a new GID (restarted) is not reported as a restart',
      ('test/test_records_writer_check.py::test_a_restarted_writer_is_followed_at_once_and_its_'
       'old_gid_is_not_current',)),
    M('duplicate-writer-unseen', 'agv_nodes/records/writer_check.py',
      'if self.duplicates or (gid in self._replaced and current is not None',
      'if self.duplicates or (False and current is not None',
      'two live processes writing as the named writer at once are not a duplicate',
      ('test/test_records_writer_check.py::test_two_live_endpoints_of_the_writer_are_a_'
       'duplicate_not_restarts',)),
    M('foreign-switch-releases', 'agv_nodes/records/writer_check.py',
      "            if verdict in ('genuine', 'restart'):\n                self.accepted += 1\n"
      '                if not value',
      "            if verdict != 'duplicate_writer':\n                self.accepted += 1\n"
      '                if not value',
      'a radio-stop or bumper release from a foreign endpoint releases the stop',
      ('test/test_records_writer_check.py::test_a_foreign_stop_is_taken_and_counted_but_a_'
       'foreign_release_is_refused',)),
    M('foreign-writer-acted-on', 'agv_nodes/ros_ports.py',
      'if verdict == FOREIGN_WRITER:', "if verdict == 'no verdict':",
      "a node acts on records from an endpoint that is not the topic's writer (forged commands)",
      ('test/test_foreign_writer_dds.py::test_forged_valid_traction_commands_are_foreign_and_'
       'never_acted_on',), dds=True),
    # -- traction timeouts and trips --------------------------------------------------------
    M('traction-command-timeout-doubled', 'agv_nodes/traction/core.py',
      'now - self.command_time, self.p.command_timeout)',
      'now - self.command_time, 2 * self.p.command_timeout)',
      'traction trips on a silent executive after twice its command_timeout',
      ('test/test_traction.py::test_stale_command_trips_within_command_timeout',)),
    M('traction-stale-margin', 'agv_nodes/traction/core.py',
      'return age > timeout and (since >= self.p.stale_confirm or age > 2 * timeout)',
      'return age > timeout + 0.1 and (since >= self.p.stale_confirm or age > 2 * timeout)',
      'a silent input trips traction 100 ms after its timeout, not on the next pass',
      ('test/test_timeouts.py::test_stale_command_trips_one_pass_after_command_timeout',
       'test/test_traction.py::test_stale_command_trips_within_command_timeout')),
    M('traction-duplicate-ignored', 'agv_nodes/traction/core.py',
      '            self._trip(DUPLICATE_WRITER)\n'
      "            return {'traction_drive': self.drive()}", '            pass',
      'two live executives writing its command do not trip traction (it goes stale later)',
      ('test/test_safety_mutants.py::test_a_duplicate_writer_of_the_command_opens_tractions_'
       'relay_at_once',)),
    M('traction-stale-link-ignored', 'agv_nodes/traction/core.py',
      "self._trip('stale_link')", 'pass',
      'a silent navigation link does not trip traction while Position has priority',
      ('test/test_traction.py::test_stale_link_trips_only_when_position_has_priority',)),
    M('traction-stall-unnoticed', 'agv_nodes/traction/core.py',
      'now - self._last_tick > self.p.stall_limit',
      'now - self._last_tick > 10 * self.p.stall_limit',
      "traction's own stalled loop (300 ms) does not trip the relay",
      ('test/test_traction.py::test_stalled_loop_trips',)),
    M('traction-corrupt-ignored', 'agv_nodes/traction/core.py',
      "if record in ('traction_command', 'traction_link') and reason in CORRUPT:",
      "if record in ('traction_link',) and reason in CORRUPT:",
      'a corrupt executive command is ignored instead of tripping the relay',
      ('test/test_traction.py::test_corrupt_record_trips',)),
    M('traction-trip-unlatched', 'agv_nodes/traction/core.py',
      'elif self._reset_stage == 1:', 'else:',
      'a tripped relay closes on any non-zero command, without the 00H first',
      ('test/test_traction.py::test_trip_latches_until_estop_then_nonzero',
       'test/test_traction.py::test_starts_tripped_and_needs_estop_then_nonzero')),
    M('traction-trip-keeps-contactor', 'agv_nodes/traction/core.py',
      "'field_forward': int(self.field_forward), 'contactor': int(on),",
      "'field_forward': int(self.field_forward), 'contactor': 1,",
      'the main contactor stays closed while the trip relay is open',
      ('test/test_traction.py::test_stale_command_trips_within_command_timeout',)),
    M('traction-radio-stop-ignored', 'agv_nodes/traction/core.py',
      'elif self.radio or self.bumper:', 'elif self.bumper:',
      "traction's program ignores the radio-control stop input",
      ('test/test_traction.py::test_radio_stop_checked_after_estop_before_source',)),
    M('traction-bumper-ignored', 'agv_nodes/traction/core.py',
      'elif self.radio or self.bumper:', 'elif self.radio:',
      "traction's program ignores the bumper (pressed by another truck)",
      ('test/test_safety_mutants.py::test_a_pressed_bumper_cuts_tractions_armature_in_auto_'
       'mode',)),
    M('traction-clock-jump-ignored', 'agv_nodes/traction/core.py',
      "        self._trip('clock_jumped')\n", '',
      'a jump of the genuine /clock leaves the trip relay closed',
      ('test/test_clock_jump.py::test_a_jump_while_cruising_fails_the_task_as_clock_jumped_and_'
       'stops_the_truck',)),
    # -- the executive's fault handling ----------------------------------------------------
    M('executive-estop-not-sent', 'agv_nodes/executive/faults.py',
      'self.demand = 0  # EMERGENCY STOP', 'self.demand = self.demand  # EMERGENCY STOP',
      "a failed task does not send traction's 00H (emergency stop)",
      ('test/test_executive_comms_load.py::test_faults_give_an_emergency_stop_and_a_named_'
       'failure',)),
    M('executive-stale-status-late', 'agv_nodes/executive/faults.py',
      'if age > timeout and (', 'if age > 4 * timeout and (',
      'a silent sub-system is noticed after four times status_timeout',
      ('test/test_executive_comms_load.py::test_stale_status_names_the_silent_subsystem',
       'test/test_executive_comms_load.py::test_a_silent_subsystem_is_noticed_between_ticks_'
       'when_others_report')),
    M('executive-reject-burst-ignored', 'agv_nodes/executive/faults.py',
      'if len(self.rejects) > p.reject_limit:', 'if len(self.rejects) > 10 * p.reject_limit:',
      'a burst of rejected status records is not a fault',
      ('test/test_executive_comms_load.py::test_reject_burst_is_a_fault_naming_the_writer',)),
    M('executive-duplicate-ignored', 'agv_nodes/executive/faults.py',
      'if self.duplicate is not None and now - self.duplicate[0] <= 1.0:',
      'if False:',
      "two live writers of a sub-system's status do not fail the task",
      ('test/test_safety_mutants.py::test_a_duplicate_writer_of_a_status_fails_the_task_naming_'
       'it_and_stops_the_truck',)),
    M('executive-stale-backstop-late', 'agv_nodes/executive/faults.py',
      'or age > 2 * timeout):', 'or age > 20 * timeout):',
      'a silent sub-system while no other status arrives is noticed after 20 status_timeouts',
      ('test/test_executive_comms_load.py::test_a_silent_subsystem_on_the_common_grid_is_noticed'
       '_by_the_supervision_timer',
       'test/test_safety_mutants.py::test_a_whole_silent_truck_is_a_stale_status_at_twice_status_'
       'timeout')),
    M('executive-sensor-lost-ignored', 'agv_nodes/executive/faults.py',
      "if nav.get('sensor_lost'):", "if nav.get('sensor_lost') and False:",
      "navigation's lost marker sensor does not stop the truck",
      ('test/test_executive_comms_load.py::test_faults_give_an_emergency_stop_and_a_named_'
       'failure',)),
    M('executive-radio-stop-ignored', 'agv_nodes/executive/faults.py',
      "if traction.get('radio_stop'):", "if traction.get('radio_stop') and False:",
      "traction's radio stop does not fail the task",
      ('test/test_executive_comms_load.py::test_faults_give_an_emergency_stop_and_a_named_'
       'failure',)),
    M('executive-collision-ignored', 'agv_nodes/executive/faults.py',
      "if traction.get('bumper'):", "if traction.get('bumper') and False:",
      'a pressed bumper (collision) does not fail the task',
      ('test/test_fleet_lockstep.py::test_two_trucks_sent_to_one_stop_marker_collide_and_both_'
       'stop_reported',)),
    M('executive-trip-ignored', 'agv_nodes/executive/faults.py',
      "if traction.get('tripped') and now", "if traction.get('tripped') and False and now",
      "traction's open trip relay does not fail the task",
      ('test/test_executive_comms_load.py::test_faults_give_an_emergency_stop_and_a_named_'
       'failure',)),
    M('executive-restart-ignored', 'agv_nodes/executive/core.py',
      "self._fail(now, 'restarted', SUBSYSTEM_OF[record], f'{record} from a new writer')\n"
      '        return self._commands(now)', 'return None',
      'a sub-system restarted during a task does not fail it',
      ('test/test_executive_comms_load.py::test_a_subsystem_restarted_during_a_task_fails_it_'
       'at_once',)),
    M('executive-clock-jump-ignored', 'agv_nodes/executive/faults.py',
      "        self._fail(now, 'clock_jumped', 'world', text)\n        return self._commands(now)",
      '        return None',
      'a jump of the genuine /clock does not fail the task',
      ('test/test_safety_mutants.py::test_a_clock_jump_told_to_the_executive_alone_fails_the_'
       'task_and_stops_the_truck',
       'test/test_clock_jump.py::test_a_jump_while_cruising_fails_the_task_as_clock_jumped_and_'
       'stops_the_truck',)),
    M('clock-back-unseen', 'agv_nodes/clock_jump.py',
      'if step < 0 or step > self.limit_ns * sent:', 'if step > self.limit_ns * sent:',
      '/clock going back is not a jump (every timeout held off until time catches up)',
      ('test/test_clock_jump.py::test_back_is_a_jump_however_small',)),
    M('clock-forward-late', 'agv_nodes/clock_jump.py',
      'if step < 0 or step > self.limit_ns * sent:',
      'if step < 0 or step > 4 * self.limit_ns * sent:',
      '/clock jumping forward by up to four times clock_jump_limit is not a jump',
      ('test/test_clock_jump.py::test_forward_past_the_limit_is_a_jump_and_the_node_time_runs_'
       'on',)),
    # -- navigation's positioning limit ------------------------------------------------------
    M('positioning-limit-quadrupled', 'agv_nodes/executive/faults.py',
      'self.positioning_distance > self.p.positioning_limit',
      'self.positioning_distance > 4 * self.p.positioning_limit',
      'a missing stop marker is overrun by four times the positioning limit',
      ('test/test_executive_comms_load.py::test_missing_stop_marker_stops_at_the_positioning_'
       'limit',)),
    M('positioning-limit-half-again', 'agv_nodes/executive/faults.py',
      'self.positioning_distance > self.p.positioning_limit',
      'self.positioning_distance > 1.5 * self.p.positioning_limit',
      'a missing stop marker is overrun by half the positioning limit again',
      ('test/test_executive_comms_load.py::test_missing_stop_marker_stops_at_the_positioning_'
       'limit',
       'test/test_safety_mutants.py::test_a_missing_stop_marker_fails_the_task_at_the_'
       'positioning_limit_not_later')),
    # -- the world's radio-stop, bumper and watchdog cuts -----------------------------------
    M('world-radio-stop-no-cut', 'agv_nodes/world/core.py',
      'v.radio_stop = self.radio_stop or self.bumper', 'v.radio_stop = self.bumper',
      "the radio-control stop input does not cut the Electruk's drive",
      ('test/test_hardware_cuts.py::test_radio_stop_cuts_the_electruk_drive_in_the_world',)),
    M('world-bumper-no-cut', 'agv_nodes/world/core.py',
      'v.radio_stop = self.radio_stop or self.bumper', 'v.radio_stop = self.radio_stop',
      "a pressed bumper does not cut the Electruk's drive",
      ('test/test_hardware_cuts.py::test_bumper_cuts_the_electruk_drive_until_the_reset',
       'test/test_fleet_lockstep.py::test_two_trucks_sent_to_one_stop_marker_collide_and_both_'
       'stop_reported')),
    M('electruk-radio-stop-powered', 'agv_nodes/world/vehicles.py',
      'powered = self.contactor and self.relay_closed and not self.radio_stop\n        # Field',
      'powered = self.contactor and self.relay_closed\n        # Field',
      "the Electruk's motor keeps its power through the radio-stop circuit",
      ('test/test_hardware_cuts.py::test_radio_stop_cuts_the_electruk_drive_in_the_world',
       'test/test_world.py::test_contactor_open_or_radio_stop_means_no_drive_torque')),
    M('concic2-radio-stop-powered', 'agv_nodes/world/vehicles.py',
      '        if self.enable and not self.radio_stop:\n            a = p.acceleration * dt',
      '        if self.enable:\n            a = p.acceleration * dt',
      "the CONCIC-II's wheel servos keep driving through the radio stop",
      ('test/test_hardware_cuts.py::test_radio_stop_cuts_the_concic2_drive_in_the_world',)),
    M('world-pal-no-cut', 'agv_nodes/world/core.py',
      '            if not self.pal.powered:\n                v.enable = False',
      '            if False:\n                v.enable = False',
      "the CONCIC-II's safety PAL in fault does not cut the amplifiers",
      ('test/test_hardware_cuts.py::test_concic2_watchdog_cuts_the_motors_60_ms_after_the_last_'
       'command',)),
    M('world-watchdog-no-cut', 'agv_nodes/world/core.py',
      'v.relay_closed = now - self._watchdog_time <= self.p.drive_watchdog',
      'v.relay_closed = True',
      'a stalled traction watchdog does not release the trip relay',
      ('test/test_world.py::test_watchdog_stall_opens_the_contactor',)),
    M('world-watchdog-doubled', 'agv_nodes/world/core.py',
      'v.relay_closed = now - self._watchdog_time <= self.p.drive_watchdog',
      'v.relay_closed = now - self._watchdog_time <= 2 * self.p.drive_watchdog',
      "the trip relay's monostable releases after twice its 200 ms (Baker 1983, B.2.1)",
      ('test/test_timeouts.py::test_the_trip_relay_opens_200_ms_after_the_watchdog_count_stops',
       'test/test_world.py::test_watchdog_stall_opens_the_contactor')),
    M('world-steering-timeout-late', 'agv_nodes/world/core.py',
      'if now - self._steer_time > self.p.steering_timeout:',
      'if now - self._steer_time > 10 * self.p.steering_timeout:',
      "the tug's steering stays enabled ten times its steering_timeout after commands stop",
      ('test/test_timeouts.py::test_the_tug_holds_its_steering_angle_after_steering_timeout',)),
    M('pal-watchdog-late', 'agv_nodes/world/safety_pal.py',
      'now - self._retriggered > p.watchdog:', 'now - self._retriggered > 10 * p.watchdog:',
      "the camera truck's safety PAL trips on its computer watchdog ten times late",
      ('test/test_drive_safety.py::test_pal_watchdog_is_armed_by_the_first_command_and_latches',
       'test/test_hardware_cuts.py::test_concic2_watchdog_cuts_the_motors_60_ms_after_the_last_'
       'command')),
    # -- the VDA 5050 bridge's order checks (agv_nodes/vda5050/) -----------------------------
    M('vda-edge-count', 'agv_nodes/vda5050/order_tasks.py',
      'if len(edges) != len(nodes) - 1:', 'if len(edges) > len(nodes) - 1:',
      'an order with too few edges for its nodes is taken',
      ('test/test_vda5050_order_flow.py::test_order_errors_name_the_offending_fields',
       'test/test_safety_mutants.py::test_an_order_missing_its_last_edge_is_an_order_error_and_no'
       '_task')),
    M('vda-node-sequence', 'agv_nodes/vda5050/order_tasks.py',
      'if node.sequence_id != first + 2 * i:', 'if node.sequence_id < first + 2 * i:',
      "nodes' sequenceIds may skip ahead (6.6.2)",
      ('test/test_vda5050_order_flow.py::test_order_errors_name_the_offending_fields',
       'test/test_safety_mutants.py::test_a_node_sequence_id_out_of_step_either_way_is_an_order_'
       'error')),
    M('vda-unknown-node', 'agv_nodes/vda5050/order_tasks.py',
      'if node.node_id not in graph.nodes:', 'if not node.node_id:',
      'an order through a node the track graph does not have is taken',
      ('test/test_vda5050_order_flow.py::test_order_errors_name_the_offending_fields',)),
    M('vda-lower-update', 'agv_nodes/vda5050/order_flow.py',
      'if order.order_update_id < self.order_update_id:',
      'if order.order_update_id < 0:',
      'a deprecated order update (lower orderUpdateId) is acted on',
      ('test/test_vda5050_order_flow.py::test_a_lower_update_is_an_error_and_the_same_update_is'
       '_ignored',)),
    M('vda-new-order-while-active', 'agv_nodes/vda5050/order_flow.py',
      'if self._active():  # figure 8 (3)', 'if False:  # figure 8 (3)',
      'a new orderId is taken while the current order is still active',
      ('test/test_vda5050_order_flow.py::test_a_new_order_id_while_the_order_is_active_is_'
       'rejected',)),
    # -- task bounds (agv_nodes/communications/) -------------------------------------------
    M('task-number-unbounded', 'agv_nodes/communications/task_language.py',
      'if not lo <= value <= hi:', 'if not lo <= value:',
      "a task's number above its range (a dwell over 255 s) is taken",
      ('test/test_executive_comms_load.py::test_bad_tasks_name_the_column_and_reason',
       'test/test_safety_mutants.py::test_a_dwell_past_its_record_byte_is_refused_naming_the_'
       'column')),
    M('task-unknown-location', 'agv_nodes/communications/task_language.py',
      'if n not in locations:', 'if n < 0:',
      'a task to a location marker the layout does not have is queued',
      ('test/test_executive_comms_load.py::test_bad_tasks_name_the_column_and_reason',)),
    M('task-too-long-taken', 'agv_nodes/communications/core.py',
      'if len(text) > self.p.max_task_length:', 'if len(text) > 64 * self.p.max_task_length:',
      'a task past max_task_length characters is parsed and queued',
      ('test/test_task_bounds.py::test_a_task_longer_than_the_limit_is_refused_without_its_text',
       )),
    M('task-queue-one-over', 'agv_nodes/communications/core.py',
      'len(self.queue) >= self.p.max_queue:', 'len(self.queue) > self.p.max_queue:',
      'the queue takes one task more than max_queue',
      ('test/test_task_bounds.py::test_a_full_queue_refuses_each_task_with_a_line_but_never_an_'
       'abort',)),
    M('task-abort-refused-when-full', 'agv_nodes/communications/core.py',
      "if task.op != 'abort' and len(self.queue) >= self.p.max_queue:",
      'if len(self.queue) >= self.p.max_queue:',
      'an abort is refused while the queue is full: the truck is not stopped',
      ('test/test_task_bounds.py::test_a_full_queue_refuses_each_task_with_a_line_but_never_an_'
       'abort',)),
    M('task-id-zero', 'agv_nodes/communications/core.py',
      'return (number - 1) % RECORD_IDS + 1', 'return number & 0xFF',
      'task 256 goes out with record id 0, which the executive reads as no task',
      ('test/test_task_bounds.py::test_task_numbers_go_on_past_255_and_the_record_ids_of_'
       'successive_heads_differ',)),
)
