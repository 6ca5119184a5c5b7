"""Parameters of fake_gantry, the Grbl 1.1 simulator."""

from .parameter_spec import ParameterSpec

PARAMETERS = [
    ParameterSpec('reply_delay_s', 0.0, 'Fault injection: delay before each reply [s]',
                  minimum=0.0, maximum=10.0),
]
