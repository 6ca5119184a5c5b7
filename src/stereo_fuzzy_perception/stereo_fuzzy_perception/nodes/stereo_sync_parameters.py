"""Settings of stereo_sync_node: its parameters' names, defaults, ranges and docs, once."""

from __future__ import annotations

from dataclasses import dataclass

from stereo_fuzzy_parameters.spec import parameter, parameter_specs


@dataclass(frozen=True)
class StereoSyncSettings:
    """Parameters of stereo_sync_node, typed."""

    slop_s: float = parameter(
        0.0, 'Largest stamp span of a paired left/right image + camera_info set [s]; 0 pairs '
        'exact stamps only', 0.0, 1.0)
    queue_size: int = parameter(
        10, 'Unpaired messages kept per input topic; the oldest is dropped beyond it', 1, 1000)
    input_reliability: str = parameter(
        'best_effort', 'Reliability of the four input subscriptions; best_effort also receives '
        'reliable publishers', choices=('best_effort', 'reliable'), read_only=True)
    max_image_pixels: int = parameter(
        4096 * 3072, 'Largest image accepted [px, width x height]; larger sets are dropped as '
        'image_too_large before they are decoded', 1, 32767 * 32767)
    # --- diagnostics
    diagnostics_period_s: float = parameter(
        1.0, 'Period of the /diagnostics report [s]', 0.05, 60.0, read_only=True)
    drop_warn_window_s: float = parameter(
        5.0, 'Diagnostics level is WARN while a pair was dropped within this window [s]',
        0.0, 3600.0)


PARAMETERS = parameter_specs(StereoSyncSettings)
