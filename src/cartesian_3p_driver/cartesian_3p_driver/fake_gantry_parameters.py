"""Parameters of fake_gantry, the Grbl 1.1 simulator."""

from stereo_fuzzy_parameters.spec import ParameterSpec

PARAMETERS = [
    # Wiring
    ParameterSpec('link_path', '', 'Symlink created to the pseudo-terminal device, for the '
                  "driver's port parameter ('' = none)", read_only=True),
    ParameterSpec('tcp_port', 23000, 'Also serve the controller on socket://127.0.0.1:<port> '
                  '(0 = off; if the port is taken, pty only)', minimum=0, maximum=65535,
                  read_only=True),
    ParameterSpec('received_lines_log', '', 'File the simulator appends every received line '
                  "to, in order ('' = off)", read_only=True),
    # Speed
    ParameterSpec('time_scale', 1.0, 'Simulated seconds per wall-clock second (motion, dwell, '
                  'homing); > 1 runs faster', minimum=0.01, maximum=1000.0),
    ParameterSpec('boot_delay_s', 0.05, 'Time from a host opening the port to the banner [s]',
                  minimum=0.0, maximum=5.0),
    # Grbl settings
    ParameterSpec('homing_enabled', True, '$22: $H available; boots in Alarm until $H or $X',
                  read_only=True),
    ParameterSpec('soft_limits', False, '$20: targets outside the travel raise ALARM:2',
                  read_only=True),
    ParameterSpec('max_travel_mm', [400.0, 300.0, 200.0], '$130-$132: travel per axis, '
                  'machine space [0, travel] after homing to 0,0,0 [mm]', read_only=True),
    ParameterSpec('max_rate_mm_min', [6000.0, 6000.0, 3000.0], '$110-$112: maximum rate per '
                  'axis [mm/min]', read_only=True),
    ParameterSpec('homing_rate_mm_min', 3000.0, '$25: homing rate [mm/min]', minimum=1.0,
                  maximum=100000.0, read_only=True),
    ParameterSpec('report_machine_position', True, '$10 bit 0: report MPos (true) or WPos '
                  'with an intermittent WCO (false)', read_only=True),
    ParameterSpec('work_offset_mm', [0.0, 0.0, 0.0], 'G54 work offset reported as WCO [mm]',
                  read_only=True),
    # Fault injection
    ParameterSpec('reply_delay_s', 0.0, 'Fault injection: delay before each reply [s]',
                  minimum=0.0, maximum=10.0),
    ParameterSpec('drop_reply_to_line', 0, 'Fault injection: never answer the n-th received '
                  'line, counted from start (it still runs; 0 = off)', minimum=0,
                  maximum=1000000),
    ParameterSpec('garble_reply_to_line', 0, 'Fault injection: answer the n-th received line '
                  'with a corrupt reply (0 = off)', minimum=0, maximum=1000000),
    ParameterSpec('drop_reply_every_lines', 0, 'Fault injection: never answer every n-th '
                  'received line (n, 2n, ...; 0 = off)', minimum=0, maximum=1000000),
    ParameterSpec('garble_reply_every_lines', 0, 'Fault injection: answer every n-th received '
                  'line with a corrupt reply (n, 2n, ...; 0 = off)', minimum=0,
                  maximum=1000000),
    ParameterSpec('refuse_line_pattern', '', 'Fault injection: answer lines matching this '
                  "regular expression with error:refuse_error_code ('' = off)"),
    ParameterSpec('refuse_error_code', 20, 'Fault injection: the error:N for refused lines',
                  minimum=1, maximum=255),
    ParameterSpec('alarm_axis', '', 'Fault injection: raise alarm_code once when this axis '
                  "crosses alarm_at_mm while moving ('' = off)", choices=('', 'x', 'y', 'z')),
    ParameterSpec('alarm_at_mm', 0.0, 'Fault injection: machine position of that trip point '
                  '[mm]', minimum=-10000.0, maximum=10000.0),
    ParameterSpec('alarm_code', 1, 'Fault injection: the ALARM:N raised (1 = hard limit)',
                  minimum=1, maximum=12),
    ParameterSpec('vanish_on_line', 0, 'Fault injection: close the pty right after receiving '
                  'the n-th line, before answering it (0 = never; once)', minimum=0,
                  maximum=1000000),
    ParameterSpec('vanish_every_lines', 0, 'Fault injection: vanish likewise after every n-th '
                  'received line (n, 2n, ...; 0 = never)', minimum=0, maximum=1000000),
    ParameterSpec('vanish_duration_s', 1.0, 'Fault injection: time until the pty comes back '
                  'at the same link_path [s]', minimum=0.0, maximum=60.0),
]
