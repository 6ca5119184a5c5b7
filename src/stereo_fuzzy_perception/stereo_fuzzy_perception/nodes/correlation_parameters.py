"""Parameters of correlation_node: the one place their names, defaults, ranges and docs live.

The matcher parameters mirror correlation.MatcherConfig (whose defaults they take) and can be
changed at run time; `matcher_config` builds the config and `config_problem` is the node's
validate hook, so an invalid combination (an even window, say) is refused with the reason.
"""

from __future__ import annotations

from stereo_fuzzy_parameters.spec import ParameterSpec, ParameterValue

from stereo_fuzzy_perception.core.matching.window_matcher import (
    METHODS,
    PREPROCESS_MODES,
    MatcherConfig,
    MatcherConfigError,
)

_DEFAULT = MatcherConfig()

PARAMETERS = [
    ParameterSpec('method', _DEFAULT.method,
                  'Correlation measure: Eq. 8 correlation coefficient (zncc) or Eq. 7 divided by '
                  'the window energies (plain)', choices=METHODS),
    ParameterSpec('window_size', _DEFAULT.window_size,
                  'Side of the square correlation window [px], odd', minimum=3, maximum=31),
    ParameterSpec('min_disparity', _DEFAULT.min_disparity,
                  'Smallest disparity searched [px] (left x minus right x)',
                  minimum=-512, maximum=512),
    ParameterSpec('disparity_range', _DEFAULT.disparity_range,
                  'Number of disparities searched [px]; the largest is min_disparity + '
                  'disparity_range - 1', minimum=1, maximum=512),
    ParameterSpec('min_score', _DEFAULT.min_score,
                  'Lowest accepted correlation score at the best disparity [-]',
                  minimum=-1.0, maximum=1.0),
    ParameterSpec('texture_threshold', _DEFAULT.texture_threshold,
                  'Lowest accepted standard deviation of the left window [grey levels]',
                  minimum=0.0, maximum=255.0),
    ParameterSpec('uniqueness_ratio', _DEFAULT.uniqueness_ratio,
                  'Margin by which the best cost (1 - score) must beat every cost more than 1 px '
                  'away [-]; 0 disables', minimum=0.0, maximum=10.0),
    ParameterSpec('lr_check_max_diff', _DEFAULT.lr_check_max_diff,
                  'Largest left-right disparity difference accepted [px]; negative disables',
                  minimum=-1, maximum=64),
    ParameterSpec('subpixel', _DEFAULT.subpixel,
                  'Refine disparities by a parabola through the scores around the peak'),
    ParameterSpec('preprocess', _DEFAULT.preprocess,
                  'Preprocessing before correlation (chapter Fig. 8): none, edges (Sobel '
                  'magnitude) or binary (Otsu threshold)', choices=PREPROCESS_MODES),
    ParameterSpec('roi.x', 0, 'Correlation area (Fig. 2): left column [px]',
                  minimum=0, maximum=65535),
    ParameterSpec('roi.y', 0, 'Correlation area: top row [px]', minimum=0, maximum=65535),
    ParameterSpec('roi.width', 0, 'Correlation area: width [px]; 0 matches the whole image',
                  minimum=0, maximum=65535),
    ParameterSpec('roi.height', 0, 'Correlation area: height [px]; 0 matches the whole image',
                  minimum=0, maximum=65535),
    ParameterSpec('point_stride', 1,
                  'Publish every n-th row and column of valid matches (1 = all); only those '
                  'rows are matched unless stereo/disparity has a subscriber',
                  minimum=1, maximum=16),
    ParameterSpec('max_rate_hz', 0.0,
                  'Most pairs matched per second [Hz]; 0 matches every pair it can (the newest '
                  'pair always wins)', minimum=0.0, maximum=1000.0),
    ParameterSpec('input_queue_depth', 1,
                  'Pairs waiting while one is matched; when full the oldest is dropped. 1 = the '
                  'newest pair always wins (bounded latency); more tolerates bursts in replays',
                  minimum=1, maximum=30),
    ParameterSpec('max_image_pixels', 4096 * 3072,
                  'Largest image accepted [px, width x height]; larger pairs are dropped as '
                  'image_too_large before they are decoded', minimum=1, maximum=32767 * 32767),
    ParameterSpec('input_reliability', 'reliable',
                  'Reliability of the stereo/pair subscription', choices=('reliable',
                                                                          'best_effort'),
                  read_only=True),
    ParameterSpec('diagnostics_period_s', 1.0, 'Period of /diagnostics messages [s]',
                  minimum=0.1, maximum=60.0, read_only=True),
    ParameterSpec('error_log_period_s', 5.0,
                  'Shortest interval between two error logs of the same kind [s]',
                  minimum=0.0, maximum=3600.0, read_only=True),
]

MATCHER_PARAMETERS = ('method', 'window_size', 'min_disparity', 'disparity_range', 'min_score',
                      'texture_threshold', 'uniqueness_ratio', 'lr_check_max_diff', 'subpixel',
                      'preprocess', 'roi.x', 'roi.y', 'roi.width', 'roi.height')


def matcher_config(values: dict[str, ParameterValue]) -> MatcherConfig:
    """Build the MatcherConfig from parameter values by name.

    Raises:
        MatcherConfigError: When the values do not make a valid configuration.
    """
    return MatcherConfig(
        method=str(values['method']),
        window_size=int(values['window_size']),  # type: ignore[arg-type]
        min_disparity=int(values['min_disparity']),  # type: ignore[arg-type]
        disparity_range=int(values['disparity_range']),  # type: ignore[arg-type]
        min_score=float(values['min_score']),  # type: ignore[arg-type]
        texture_threshold=float(values['texture_threshold']),  # type: ignore[arg-type]
        uniqueness_ratio=float(values['uniqueness_ratio']),  # type: ignore[arg-type]
        lr_check_max_diff=int(values['lr_check_max_diff']),  # type: ignore[arg-type]
        subpixel=bool(values['subpixel']),
        preprocess=str(values['preprocess']),
        roi=(int(values['roi.x']), int(values['roi.y']),  # type: ignore[arg-type]
             int(values['roi.width']), int(values['roi.height'])),  # type: ignore[arg-type]
    )


def config_problem(values: dict[str, ParameterValue]) -> str | None:
    """Return why these parameter values make no valid matcher configuration, or None."""
    try:
        matcher_config(values)
    except MatcherConfigError as error:
        return str(error)
    except (TypeError, ValueError, OverflowError) as error:  # never raise out of on-set
        return f'cannot build the matcher configuration ({type(error).__name__}: {error})'
    return None
