"""Parameters of fuzzy_best_point_node."""

from .parameter_spec import ParameterSpec

PARAMETERS = [
    ParameterSpec('selector', 'fuzzy_fitted', 'How the best point is chosen',
                  choices=('fuzzy_fitted', 'fuzzy_chapter', 'centroid', 'max_score',
                           'neural_network')),
]
