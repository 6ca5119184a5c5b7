"""The window-correlation matcher (Eqs. 7-8) on synthetic pairs with known disparities."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stereo_fuzzy_perception.core.matching import _window_matcher_kernel as _kernel
from stereo_fuzzy_perception.core.matching.window_matcher import (
    MatcherConfig,
    MatcherConfigError,
    MatcherInputError,
    MatchStatus,
    match,
    preprocess_image,
)
from stereo_fuzzy_perception.core.matching.window_matcher_reference import reference_match


def texture(height: int, width: int, seed: int = 0, blur: float = 1.2) -> np.ndarray:
    """Random texture, smoothed so that fractional shifts interpolate well, 0..255 float."""
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, size=(height, width)).astype(np.float32)
    smooth = cv2.GaussianBlur(noise, (0, 0), blur)
    smooth = (smooth - smooth.mean()) / smooth.std()
    return np.clip(128 + 45 * smooth, 0, 255).astype(np.float32)


def shifted_pair(scene: np.ndarray,
                 disparity: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Left = scene, right(x_r, y) = scene(x_r + d(y), y): left x matches right x - d."""
    height, width = scene.shape
    d = np.broadcast_to(np.asarray(disparity, dtype=np.float32), (height, width))
    map_x = np.arange(width, dtype=np.float32)[None, :] + d
    map_y = np.repeat(np.arange(height, dtype=np.float32)[:, None], width, axis=1)
    right = cv2.remap(scene, map_x, map_y, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT_101)
    return to_uint8(scene), to_uint8(right)


def to_uint8(image: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def interior(result, margin: int) -> tuple[slice, slice]:
    height, width = result.disparity.shape
    return slice(margin, height - margin), slice(margin, width - margin)


def test_constant_shift_is_recovered_everywhere_it_can_be():
    left, right = shifted_pair(texture(60, 120), 7.0)
    config = MatcherConfig(window_size=9, disparity_range=24)
    result = match(left, right, config)
    rows, columns = slice(0, 60), slice(7 + 4 + 1, 120 - 4)  # partner inside the image
    disparity, valid = result.disparity[rows, columns], result.valid[rows, columns]
    assert valid.mean() > 0.97, result.status_counts()
    error = np.abs(disparity[valid] - 7.0)
    assert error.max() < 0.35 and np.median(error) < 0.05  # parabola fit on an exact peak
    assert np.nanmin(result.score[rows, columns][valid]) > 0.9


def test_ramp_in_disparity_is_followed():
    scene = texture(80, 120, seed=1)
    truth = 3.0 + 0.1 * np.arange(80, dtype=np.float32)[:, None]  # 3 .. 10.9 px down the rows
    left, right = shifted_pair(scene, truth)
    result = match(left, right, MatcherConfig(window_size=7, disparity_range=16))
    rows, columns = slice(4, 76), slice(16, 116)
    valid = result.valid[rows, columns]
    expected = np.broadcast_to(truth, (80, 120))[rows, columns]
    error = np.abs(result.disparity[rows, columns] - expected)
    assert valid.mean() > 0.9, result.status_counts()
    assert np.median(error[valid]) < 0.15
    assert np.percentile(error[valid], 95) < 0.5


def step_scene(lr_check: int) -> tuple:
    """Background at disparity 4, a foreground square at 12 in front of it (x 50..89)."""
    background, foreground = texture(60, 160, seed=2), texture(60, 160, seed=3)
    left = background.copy()
    left[:, 50:90] = foreground[:, 50:90]
    x_right = np.arange(160)
    right = background[:, np.clip(x_right + 4, 0, 159)]
    covered = (x_right + 12 >= 50) & (x_right + 12 < 90)
    right[:, covered] = foreground[:, x_right[covered] + 12]
    config = MatcherConfig(window_size=7, disparity_range=20, lr_check_max_diff=lr_check)
    return match(to_uint8(left), to_uint8(right), config)


def test_step_edge_keeps_both_depths():
    result = step_scene(lr_check=1)
    valid = result.valid
    foreground = result.disparity[:, 55:85][valid[:, 55:85]]
    background = result.disparity[:, 100:150][valid[:, 100:150]]
    assert foreground.size > 0.9 * 60 * 30 and background.size > 0.9 * 60 * 50
    assert np.all(np.abs(foreground - 12) < 0.5)
    assert np.all(np.abs(background - 4) < 0.5)


def test_left_right_check_rejects_the_occluded_strip():
    # Background left of the square, x 42..49 in the left image: its right partner (x - 4) is
    # hidden behind the foreground (which moved 12 px), so no correct match exists there.
    occluded = (slice(4, 56), slice(42, 50))
    checked, unchecked = step_scene(lr_check=1), step_scene(lr_check=-1)
    wrong_unchecked = unchecked.valid[occluded].mean()
    assert wrong_unchecked > 0.8, 'without the check the occluded pixels get (wrong) matches'
    assert checked.valid[occluded].mean() < 0.25
    assert np.mean(checked.status[occluded] == MatchStatus.LR_INCONSISTENT) > 0.6


def test_gain_and_offset_leave_eq8_unchanged_but_change_eq7():
    scene = texture(50, 100, seed=4) * 0.6 + 20  # 20..173: no clipping after the change below
    left, right = shifted_pair(scene, 6.0)
    brighter = (1.3 * right.astype(np.float32) + 20).astype(np.float32)
    assert brighter.max() < 255
    brighter = np.rint(brighter).astype(np.uint8)
    changes = {}
    for method in ('zncc', 'plain'):
        config = MatcherConfig(method=method, window_size=9, disparity_range=16, min_score=0.0)
        before, after = match(left, right, config), match(left, brighter, config)
        region = (slice(0, 50), slice(20, 95))
        changes[method] = np.nanmean(np.abs(before.score[region] - after.score[region]))
        same = before.valid[region] & after.valid[region]
        assert same.mean() > 0.95
        if method == 'zncc':
            moved = np.abs(before.disparity[region][same] - after.disparity[region][same])
            assert moved.max() < 0.05
    # Eq. 8 only moves by the rounding of the brighter image to integers; Eq. 7 (divided by
    # the window energies, so blind to the gain) still moves with the offset.
    assert changes['zncc'] < 1e-4, changes
    assert changes['plain'] > 5 * changes['zncc'], changes


def test_textureless_region_is_marked_low_texture():
    scene = texture(60, 120, seed=5)
    scene[15:45, 40:90] = 100.0
    left, right = shifted_pair(scene, 5.0)
    result = match(left, right, MatcherConfig(window_size=7, disparity_range=16,
                                              texture_threshold=2.0))
    flat = result.status[20:40, 50:80]
    assert np.all(flat == MatchStatus.LOW_TEXTURE)
    assert result.valid[:, 95:115].mean() > 0.9


def test_repeated_pattern_is_rejected_by_uniqueness():
    x = np.arange(140, dtype=np.float32)
    stripes = 128 + 80 * np.sin(2 * np.pi * x / 8.0)
    scene = np.repeat(stripes[None, :], 40, axis=0)
    left, right = shifted_pair(scene, 3.0)
    region = (slice(5, 35), slice(40, 130))
    loose = match(left, right, MatcherConfig(window_size=7, disparity_range=32,
                                             lr_check_max_diff=-1, uniqueness_ratio=0.0))
    strict = match(left, right, MatcherConfig(window_size=7, disparity_range=32,
                                              lr_check_max_diff=-1, uniqueness_ratio=0.05))
    assert loose.valid[region].mean() > 0.9
    assert np.all(strict.status[region] == MatchStatus.NOT_UNIQUE)


def test_low_scores_are_rejected_by_min_score():
    rng = np.random.default_rng(6)
    left = rng.integers(0, 256, size=(40, 80), dtype=np.uint8)
    right = rng.integers(0, 256, size=(40, 80), dtype=np.uint8)  # unrelated images
    result = match(left, right, MatcherConfig(window_size=9, disparity_range=16, min_score=0.8,
                                              lr_check_max_diff=-1))
    region = result.status[:, 30:75]
    assert np.all(region == MatchStatus.LOW_SCORE)
    assert np.all(result.score[:, 30:75] < 0.8)


def test_subpixel_disparity_on_a_fractional_shift():
    left, right = shifted_pair(texture(60, 120, seed=7, blur=1.5), 5.4)
    region = (slice(0, 60), slice(20, 115))
    refined = match(left, right, MatcherConfig(window_size=9, disparity_range=16))
    whole = match(left, right, MatcherConfig(window_size=9, disparity_range=16, subpixel=False))
    refined_error = np.abs(refined.disparity[region][refined.valid[region]] - 5.4)
    assert np.mean(refined_error) < 0.12
    assert np.all(np.isin(whole.disparity[region][whole.valid[region]], [5.0, 6.0]))
    assert np.mean(refined_error) < np.mean(
        np.abs(whole.disparity[region][whole.valid[region]] - 5.4))


@pytest.mark.parametrize('config', [
    MatcherConfig(window_size=5, disparity_range=16),
    MatcherConfig(method='plain', window_size=7, min_disparity=2, disparity_range=12,
                  uniqueness_ratio=0.05),
    MatcherConfig(window_size=3, disparity_range=20, lr_check_max_diff=0, subpixel=False,
                  roi=(10, 5, 30, 20)),
    MatcherConfig(window_size=5, disparity_range=16, lr_check_max_diff=-1, texture_threshold=10,
                  uniqueness_ratio=0.2, preprocess='edges'),
    MatcherConfig(window_size=9, min_disparity=-3, disparity_range=10, preprocess='binary'),
], ids=['zncc', 'plain-unique', 'roi-lr0', 'edges-texture', 'negative-binary'])
def test_fast_kernel_agrees_with_the_slow_reference(config):
    rng = np.random.default_rng(8)
    scene = texture(40, 80, seed=9)
    left, right = shifted_pair(scene, 6.0)
    right = np.clip(right.astype(int) + rng.integers(-10, 11, right.shape), 0, 255).astype(
        np.uint8)
    fast, slow = match(left, right, config), reference_match(left, right, config)
    assert np.mean(fast.status == slow.status) > 0.995, (fast.status_counts(),
                                                        slow.status_counts())
    both = fast.valid & slow.valid
    assert both.sum() > 0.2 * both.size or config.roi != (0, 0, 0, 0)
    assert np.abs(fast.disparity[both] - slow.disparity[both]).max() < 1e-3
    scored = np.isfinite(fast.score) & np.isfinite(slow.score)
    assert np.array_equal(scored, np.isfinite(slow.score))
    assert np.abs(fast.score[scored] - slow.score[scored]).max() < 1e-4


def test_region_of_interest_matches_only_inside_and_like_the_whole_image():
    left, right = shifted_pair(texture(60, 120, seed=10), 6.0)
    whole = match(left, right, MatcherConfig(window_size=7, disparity_range=16))
    part = match(left, right, MatcherConfig(window_size=7, disparity_range=16,
                                            roi=(30, 10, 50, 25)))
    inside = (slice(10, 35), slice(30, 80))
    outside = np.ones(left.shape, bool)
    outside[inside] = False
    assert np.all(part.status[outside] == MatchStatus.OUTSIDE_ROI)
    assert np.all(np.isnan(part.disparity[outside]))
    assert np.array_equal(part.status[inside], whole.status[inside])
    assert np.array_equal(part.disparity[inside], whole.disparity[inside], equal_nan=True)
    assert part.status_counts()['valid'] == np.count_nonzero(part.valid)


def test_edge_and_binary_preprocessing_still_find_the_shift():
    left, right = shifted_pair(texture(60, 120, seed=11, blur=2.0), 8.0)
    for mode in ('edges', 'binary'):
        result = match(left, right, MatcherConfig(window_size=11, disparity_range=24,
                                                  preprocess=mode))
        region = (slice(0, 60), slice(30, 114))
        valid = result.valid[region]
        assert valid.mean() > 0.5, (mode, result.status_counts())
        assert np.median(np.abs(result.disparity[region][valid] - 8.0)) < 0.5, mode
    binary = preprocess_image(left, 'binary')
    assert set(np.unique(binary)) <= {0, 255}


def test_edge_preprocessing_is_the_exact_gradient_magnitude_wherever_the_arrays_lie():
    # cv2.magnitude rounded differently with its output's address (an edge image changed by a
    # grey level between calls, and so did the matches); allocations in between move it
    image = texture(64, 96, seed=12).astype(np.uint8)
    gx = cv2.Sobel(image, cv2.CV_64F, 1, 0, ksize=3)
    gy = cv2.Sobel(image, cv2.CV_64F, 0, 1, ksize=3)
    exact = np.clip(np.rint(np.hypot(gx, gy) / 4.0), 0, 255).astype(np.uint8)
    sizes = np.random.default_rng(13).integers(1, 64, 12)
    for size in sizes:
        spacer = np.ones(int(size) * 16 + 3, np.uint8)  # noqa: F841 - shifts the next arrays
        np.testing.assert_array_equal(preprocess_image(image, 'edges'), exact)


def test_the_same_pair_gives_the_same_result_after_other_pairs():
    # the matcher keeps its working memory between calls: nothing of one pair may leak into
    # the next, whatever its size, settings or row step
    left, right = shifted_pair(texture(60, 100, seed=14), 5.0)
    config = MatcherConfig(window_size=7, disparity_range=16, preprocess='edges')
    first = match(left, right, config)
    other_left, other_right = shifted_pair(texture(50, 90, seed=15), 9.0)
    match(other_left, other_right, MatcherConfig(window_size=5, disparity_range=24))
    match(left, right, config, row_step=3)
    match(right, left, MatcherConfig(window_size=7, disparity_range=16, method='plain'))
    again = match(left, right, config)
    np.testing.assert_array_equal(again.status, first.status)
    np.testing.assert_array_equal(again.disparity, first.disparity)
    np.testing.assert_array_equal(again.score, first.score)


def test_a_result_or_a_view_of_it_that_the_caller_keeps_is_never_overwritten():
    # the output arrays are recycled only once nothing but the matcher refers to them
    left, right = shifted_pair(texture(60, 100, seed=16), 5.0)
    config = MatcherConfig(window_size=7, disparity_range=16)
    kept = match(left, right, config)
    kept_copy = kept.disparity.copy(), kept.score.copy(), kept.status.copy()
    status_view = match(left, right, config).status[10:20]
    view_copy = status_view.copy()
    other_left, other_right = shifted_pair(texture(60, 100, seed=17), 9.0)
    for _ in range(3):
        match(other_left, other_right, config)
    for array, copy in zip((kept.disparity, kept.score, kept.status), kept_copy, strict=True):
        np.testing.assert_array_equal(array, copy)
    np.testing.assert_array_equal(status_view, view_copy)


@pytest.mark.parametrize(('changes', 'expected'), [
    ({'window_size': 8}, 'odd'),
    ({'window_size': 33}, 'window_size'),
    ({'method': 'sad'}, 'method'),
    ({'disparity_range': 0}, 'disparity_range'),
    ({'min_score': 1.5}, 'min_score'),
    ({'preprocess': 'canny'}, 'preprocess'),
    ({'roi': (0, 0, -5, 10)}, 'roi'),
    ({'texture_threshold': -1.0}, 'texture_threshold'),
])
def test_invalid_configuration_is_refused_with_the_reason(changes, expected):
    with pytest.raises(MatcherConfigError, match=expected):
        MatcherConfig(**changes)


def test_unusable_images_are_refused_with_the_reason():
    image = np.zeros((40, 60), np.uint8)
    with pytest.raises(MatcherInputError, match='60x40 but right image is 61x40'):
        match(image, np.zeros((40, 61), np.uint8))
    with pytest.raises(MatcherInputError, match='one grey channel'):
        match(np.zeros((40, 60, 3), np.uint8), np.zeros((40, 60, 3), np.uint8))
    with pytest.raises(MatcherInputError, match='outside'):
        match(image, image, MatcherConfig(roi=(100, 0, 10, 10)))
    with pytest.raises(MatcherInputError, match='smaller than'):
        match(image[:5], image[:5], MatcherConfig(window_size=9))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**16), window=st.sampled_from([3, 5, 7]),
       min_disparity=st.integers(-4, 8), disparity_range=st.integers(1, 20),
       method=st.sampled_from(['zncc', 'plain']), lr=st.integers(-1, 2),
       subpixel=st.booleans())
def test_every_disparity_lies_in_the_searched_range_and_its_partner_in_the_image(
        seed, window, min_disparity, disparity_range, method, lr, subpixel):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, size=(20, 40), dtype=np.uint8)
    right = np.roll(left, -3, axis=1)
    config = MatcherConfig(method=method, window_size=window, min_disparity=min_disparity,
                           disparity_range=disparity_range, lr_check_max_diff=lr,
                           subpixel=subpixel, min_score=-1.0)
    result = match(left, right, config)
    disparity = result.disparity[result.valid]
    assert np.all(disparity >= min_disparity - 0.5)
    assert np.all(disparity <= config.max_disparity + 0.5)
    columns = np.nonzero(result.valid)[1]
    radius = window // 2
    assert np.all(np.rint(columns - disparity) >= radius - 1)
    assert np.all(np.isnan(result.disparity[~result.valid]))


@pytest.mark.parametrize('row_step', [2, 3])
@pytest.mark.parametrize('roi', [(0, 0, 0, 0), (20, 11, 70, 41)])
@pytest.mark.parametrize('band_count', [1, 5])
def test_row_step_decides_the_same_rows_and_skips_the_others(row_step, roi, band_count):
    left, right = shifted_pair(texture(70, 120, seed=6), 5.0)
    config = MatcherConfig(window_size=7, disparity_range=16, uniqueness_ratio=0.05, roi=roi)
    every_row = match(to_uint8(left), to_uint8(right), config, band_count=band_count)
    stepped = match(to_uint8(left), to_uint8(right), config, band_count=band_count,
                    row_step=row_step)
    decided = np.arange(70) % row_step == 0
    np.testing.assert_array_equal(stepped.status[decided], every_row.status[decided])
    np.testing.assert_array_equal(stepped.disparity[decided], every_row.disparity[decided])
    x, y, width, height = stepped.roi
    inside_skipped = stepped.status[y:y + height, x:x + width][~decided[y:y + height]]
    assert inside_skipped.size > 0
    assert np.all(inside_skipped == MatchStatus.SKIPPED_ROW)
    assert np.all(np.isnan(stepped.disparity[~decided]))
    assert stepped.status_counts()['skipped_row'] == inside_skipped.size
    assert stepped.status_counts()['valid'] > 0


def test_row_step_below_one_is_refused():
    image = texture(20, 30).astype(np.uint8)
    with pytest.raises(ValueError, match='row_step 0'):
        match(image, image, MatcherConfig(window_size=3, disparity_range=4), row_step=0)


def test_the_kernel_and_the_python_enum_agree_on_every_status_code():
    # the C kernel defines the codes it writes; MatchStatus names them for Python
    assert {status.name: status.value for status in MatchStatus} == _kernel.STATUS_CODES


@pytest.mark.parametrize('threads', [1, 2, 3, 7])
def test_any_thread_and_band_count_gives_the_same_result_on_8_bit_images(threads):
    # 8-bit sums are exact: how the rows are split between bands and threads cannot show
    left, right = shifted_pair(texture(70, 110, seed=18), 6.0)
    config = MatcherConfig(window_size=7, disparity_range=20, uniqueness_ratio=0.05)
    one = match(left, right, config, threads=1, band_count=1)
    many = match(left, right, config, threads=threads)
    np.testing.assert_array_equal(many.status, one.status)
    np.testing.assert_array_equal(many.disparity, one.disparity)
    np.testing.assert_array_equal(many.score, one.score)


@pytest.mark.parametrize(('left_dtype', 'right_dtype'), [
    (np.uint16, np.uint16), (np.float32, np.float64), (np.uint8, np.uint16), (np.int16, np.uint8),
])
def test_every_integer_and_float_dtype_agrees_with_the_slow_reference(left_dtype, right_dtype):
    def scaled(image: np.ndarray, dtype: type) -> np.ndarray:
        return (image.astype(np.float64) * 257).astype(dtype) if dtype == np.uint16 else \
            image.astype(dtype)

    left, right = shifted_pair(texture(40, 80, seed=19), 5.0)
    left, right = scaled(left, left_dtype), scaled(right, right_dtype)
    config = MatcherConfig(window_size=5, disparity_range=12)
    fast, slow = match(left, right, config), reference_match(left, right, config)
    assert np.mean(fast.status == slow.status) > 0.995
    both = fast.valid & slow.valid
    assert both.sum() > 0.5 * both.size
    assert np.abs(fast.disparity[both] - slow.disparity[both]).max() < 1e-3


def test_the_kernel_refuses_arrays_that_do_not_fit_its_call():
    # one call with named arguments: a wrong buffer is an exception, never memory corruption
    image = texture(20, 30).astype(np.uint8)
    workspace = np.empty(_kernel.workspace_bytes(height=20, width=30, radius=1,
                                                 disparity_range=4, threads=1), np.uint8)
    outputs = [np.empty((20, 30), np.float32), np.empty((20, 30), np.float32),
               np.empty((20, 30), np.uint8)]
    settings_ = dict(zero_mean=True, radius=1, min_disparity=0, disparity_range=4,
                     texture_threshold=0.5, min_score=0.3, uniqueness_ratio=0.0,
                     lr_max_diff=1, subpixel=True, roi=(0, 0, 30, 20), row_step=1, bands=2,
                     threads=1)
    _kernel.correlate(image, image, *outputs, workspace, **settings_)
    assert np.count_nonzero(outputs[2] == MatchStatus.VALID) > 0
    with pytest.raises(TypeError, match='disparity'):
        _kernel.correlate(image, image, outputs[2], outputs[1], outputs[2], workspace,
                          **settings_)
    with pytest.raises(TypeError, match='left'):
        _kernel.correlate(image[:, ::2], image[:, ::2], *outputs, workspace, **settings_)
    with pytest.raises(ValueError, match='workspace'):
        _kernel.correlate(image, image, *outputs, workspace[:-1], **settings_)
    with pytest.raises(ValueError, match='roi'):
        _kernel.correlate(image, image, *outputs, workspace, **dict(settings_, roi=(5, 0, 30, 20)))
    with pytest.raises(TypeError, match='threads'):
        del settings_['threads']
        _kernel.correlate(image, image, *outputs, workspace, **settings_)


def test_python_threads_matching_at_once_get_the_results_of_matching_alone():
    # the kernel releases the GIL; each Python thread has its own working memory
    from concurrent.futures import ThreadPoolExecutor

    pairs = [shifted_pair(texture(50, 90, seed=30 + index), 4.0 + index) for index in range(4)]
    config = MatcherConfig(window_size=7, disparity_range=16)
    alone = [match(left, right, config).disparity.copy() for left, right in pairs]

    def match_repeatedly(index: int) -> list[np.ndarray]:
        left, right = pairs[index]
        return [match(left, right, config).disparity.copy() for _ in range(5)]

    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(match_repeatedly, range(4)))
    for index, repeats in enumerate(results):
        for disparity in repeats:
            np.testing.assert_array_equal(disparity, alone[index])
