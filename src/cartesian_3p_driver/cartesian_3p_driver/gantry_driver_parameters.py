"""Parameters of gantry_driver_node."""

from .parameter_spec import ParameterSpec

PARAMETERS = [
    ParameterSpec('port', 'socket://127.0.0.1:23000', 'Serial device path or pyserial URL',
                  read_only=True),
    ParameterSpec('baud', 115200, 'Serial baud rate [bit/s]', minimum=1200, maximum=2000000,
                  read_only=True),
]
PARAMETERS.append(
    ParameterSpec('poll_rate_hz', 5.0, 'Status report (?) polling rate [Hz]', minimum=0.5,
                  maximum=5.0))
