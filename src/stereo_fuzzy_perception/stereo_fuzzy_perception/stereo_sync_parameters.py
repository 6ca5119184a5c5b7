"""Parameters of stereo_sync_node."""

from .parameter_spec import ParameterSpec

PARAMETERS = [
    ParameterSpec('source', 'topics', 'Where pairs come from', choices=('topics', 'devices'),
                  read_only=True),
    ParameterSpec('slop', 0.0, 'Largest stamp difference paired [s]; 0 pairs exact stamps only',
                  minimum=0.0, maximum=1.0),
]
