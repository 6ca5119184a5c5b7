"""Parameters of correlation_node."""

from .parameter_spec import ParameterSpec

PARAMETERS = [
    ParameterSpec('method', 'zncc', 'Correlation measure: Eq. 8 (zncc) or Eq. 7 (plain)',
                  choices=('zncc', 'plain')),
    ParameterSpec('window_size', 9, 'Side of the square correlation window [px], odd',
                  minimum=3, maximum=31),
]
