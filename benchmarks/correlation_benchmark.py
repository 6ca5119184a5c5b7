"""Correlation stage benchmark: accuracy, robustness and speed against OpenCV, in one run.

    python benchmarks/correlation_benchmark.py                 # everything, a few minutes
    python benchmarks/correlation_benchmark.py --scenes cones,teddy --repeats 5
    python benchmarks/correlation_benchmark.py --skip-speed

1. Accuracy on the Middlebury scenes (ground truth + all / non-occluded masks): this project's
   matcher (Eq. 8, default MatcherConfig) against OpenCV StereoBM (block 9) and StereoSGBM
   (block 5, default P1/P2), all with the same 64 disparities. bad-2.0 counts pixels with no
   estimate as bad; density and the mean absolute error among estimated pixels are shown too.
2. Robustness: the same with the right image's brightness changed (gain 1.3, offset +20,
   clipped): Eq. 8 against Eq. 7 (plain) and StereoBM.
3. Speed: ms per pair, 9x9 window, at 320x240 with 32 disparities, 640x480 with 64 and
   1280x960 with 128, against StereoBM (block 9) and StereoSGBM (block 5) on the same images in
   the same process (median of --repeats runs in rounds of 3, as a ratio to StereoBM), with every
   thread; and the whole correlation stage as correlation_node runs it, a StereoPair message in
   and StereoMatches out (decode, rectify with a toed-in rig's maps, match, triangulate, pack;
   the message parts only when the ROS workspace is sourced), at point_stride 1 and 3, with
   its steps' times. Then each size with one thread each (OpenCV too), timed in CPU time of the
   calling thread, so that the work per pair shows apart from how each method scales on the
   machine's cores and from the time a loaded machine keeps a process waiting.

Markdown tables go to stdout. Needs numpy and OpenCV, and the package built (scripts/setup.sh);
imports the package from src/.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT / 'src' / 'stereo_fuzzy_perception'))

from stereo_fuzzy_perception.core.camera_model import (  # noqa: E402
    StereoCalibration,
)
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline  # noqa: E402
from stereo_fuzzy_perception.core.matching.window_matcher import (  # noqa: E402
    MatcherConfig,
    default_threads,
    match,
    warm_up,
)
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402
from stereo_fuzzy_perception.simulation.synthetic_scenes import rectified_calibration  # noqa: E402

SCENES = ('tsukuba', 'venus', 'sawtooth', 'barn1', 'cones', 'teddy')
GT_SCALE = {'tsukuba': 16, 'venus': 8, 'sawtooth': 8, 'barn1': 8, 'cones': 4, 'teddy': 4}
DISPARITIES = 64  # covers every scene's ground truth (cones reaches 55 px)


@dataclass(frozen=True)
class Scene:
    """One Middlebury pair with its ground truth [px] and evaluation masks."""

    name: str
    left: np.ndarray
    right: np.ndarray
    truth: np.ndarray
    all_mask: np.ndarray
    nonocc_mask: np.ndarray


def load_scene(data_dir: Path, name: str) -> Scene:
    """Read a scene's grey images, ground truth and masks."""
    folder = data_dir / name
    left = cv2.imread(str(folder / 'left.png'), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(folder / 'right.png'), cv2.IMREAD_GRAYSCALE)
    raw = cv2.imread(str(folder / 'gt_disp_left.pgm'), cv2.IMREAD_UNCHANGED)
    if left is None or right is None or raw is None:
        raise SystemExit(f'cannot read scene {name} in {folder}')
    truth = raw.astype(np.float32) / GT_SCALE[name]
    known = raw > 0
    all_mask = (cv2.imread(str(folder / 'all_derived.png'), cv2.IMREAD_GRAYSCALE) > 0) & known
    nonocc = (cv2.imread(str(folder / 'nonocc_derived.png'), cv2.IMREAD_GRAYSCALE) > 0) & known
    return Scene(name, left, right, truth, all_mask, nonocc)


# --- the matchers ---------------------------------------------------------------------------


def ours(config: MatcherConfig) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """This project's matcher: disparity [px], NaN where invalid."""
    return lambda left, right: match(left, right, config).disparity


def opencv_bm(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """OpenCV StereoBM, 64 disparities, block 9 (its defaults otherwise)."""
    raw = cv2.StereoBM.create(numDisparities=DISPARITIES, blockSize=9).compute(left, right)
    return np.where(raw >= 0, raw / 16.0, np.nan).astype(np.float32)


def opencv_sgbm(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """OpenCV StereoSGBM, 64 disparities, block 5, default P1/P2."""
    raw = cv2.StereoSGBM.create(minDisparity=0, numDisparities=DISPARITIES,
                                blockSize=5).compute(left, right)
    return np.where(raw >= 0, raw / 16.0, np.nan).astype(np.float32)


def default_config() -> MatcherConfig:
    return MatcherConfig(disparity_range=DISPARITIES)


# --- metrics --------------------------------------------------------------------------------


def scores(estimate: np.ndarray, scene: Scene) -> dict[str, float]:
    """bad-2.0 on all and non-occluded pixels [%], density [%], MAE among estimated [px]."""
    estimated = np.isfinite(estimate)
    error = np.abs(np.where(estimated, estimate, 0.0) - scene.truth)
    bad = ~estimated | (error > 2.0)
    covered = scene.all_mask & estimated
    return {
        'bad_all': 100.0 * bad[scene.all_mask].mean(),
        'bad_nonocc': 100.0 * bad[scene.nonocc_mask].mean(),
        'density': 100.0 * estimated[scene.all_mask].mean(),
        'mae': float(error[covered].mean()) if covered.any() else math.nan,
    }


def brighter(image: np.ndarray) -> np.ndarray:
    """The right image with gain 1.3 and offset +20, clipped to 0..255."""
    return np.clip(1.3 * image.astype(np.float32) + 20.0, 0, 255).astype(np.uint8)


# --- sections -------------------------------------------------------------------------------


def accuracy_table(scenes: list[Scene], right_transform: Callable[[np.ndarray], np.ndarray],
                   methods: dict[str, Callable]) -> str:
    lines = ['| scene | method | bad-2.0 all [%] | bad-2.0 nonocc [%] | density [%] | '
             'MAE estimated [px] |', '|---|---|---|---|---|---|']
    for scene in scenes:
        right = right_transform(scene.right)
        for name, method in methods.items():
            result = scores(method(scene.left, right), scene)
            lines.append(f'| {scene.name} | {name} | {result["bad_all"]:.1f} | '
                         f'{result["bad_nonocc"]:.1f} | {result["density"]:.1f} | '
                         f'{result["mae"]:.2f} |')
    return '\n'.join(lines)


def speed_images(data_dir: Path, width: int = 640,
                 height: int = 480) -> tuple[np.ndarray, np.ndarray]:
    """A pair of `width` x `height`: cones resized (real texture), or a synthetic texture."""
    folder = data_dir / 'cones'
    left = cv2.imread(str(folder / 'left.png'), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(folder / 'right.png'), cv2.IMREAD_GRAYSCALE)
    if left is None or right is None:
        rng = np.random.default_rng(0)
        shift = width // 32
        scene = cv2.GaussianBlur(rng.uniform(0, 255, (height, width + shift)).astype(np.float32),
                                 (0, 0), 1.2)
        scene = np.clip(128 + 3 * (scene - scene.mean()), 0, 255).astype(np.uint8)
        return scene[:, :width].copy(), scene[:, shift:shift + width].copy()
    return (cv2.resize(left, (width, height), interpolation=cv2.INTER_LINEAR),
            cv2.resize(right, (width, height), interpolation=cv2.INTER_LINEAR))


def verged_calibration(width: int, height: int) -> StereoCalibration:
    """A toed-in rig (520 px focal length at 640 wide) calibrated as cv2.stereoRectify would."""
    focal = 520.0 * width / 640.0
    K = np.array([[focal, 0.0, width / 2], [0.0, focal, height / 2], [0.0, 0.0, 1.0]])
    return StereoCalibration(*rectified_calibration(
        StereoRig(baseline_m=0.06, vergence_deg=6.0), K, width, height,
        distortion=np.array([-0.05, 0.01, 0.0, 0.0, 0.0])))


# (width, height, disparities) of the speed comparison; 640x480x64 is the reference case.
SCALES = ((320, 240, 32), (640, 480, 64), (1280, 960, 128))
BM = 'OpenCV StereoBM (block 9)'
SGBM = 'OpenCV StereoSGBM (block 5)'
OURS = 'stereo-fuzzy ZNCC (Eq. 8)'


def speed_section(data_dir: Path, repeats: int) -> str:
    first_call = warm_up()
    stage = _stage_function()
    lines = [f'Threads: {default_threads()} (ours, per call) and {cv2.getNumThreads()} '
             f'(OpenCV); the stage is {stage.__doc__}.', '']
    for width, height, disparities in SCALES:
        lines.extend(scale_table(data_dir, width, height, disparities, repeats, stage))
        lines.append('')
    # One thread each, timed in CPU time: the work per pair, apart from how each method scales
    # on this machine's cores and from the time a loaded machine keeps it waiting.
    opencv_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        for width, height, disparities in SCALES:
            lines.extend(cpu_time_table(data_dir, width, height, disparities, repeats, stage))
            lines.append('')
    finally:
        cv2.setNumThreads(opencv_threads)
    left, right = speed_images(data_dir)
    config = MatcherConfig(window_size=9, disparity_range=DISPARITIES)
    lines.append(f'First call in this process (loads the kernel): {first_call * 1e3:.1f} ms. '
                 f'Share of valid pixels on the 640x480 pair: '
                 f'{100 * match(left, right, config).valid.mean():.1f} %.')
    return '\n'.join(lines)


def scale_table(data_dir: Path, width: int, height: int, disparities: int, repeats: int,
                stage: Callable) -> list[str]:
    """Markdown rows: matchers and the whole correlation stage on one pair of this size."""
    left, right = speed_images(data_dir, width, height)
    config = MatcherConfig(window_size=9, disparity_range=disparities)
    bm = cv2.StereoBM.create(numDisparities=disparities, blockSize=9)
    sgbm = cv2.StereoSGBM.create(minDisparity=0, numDisparities=disparities, blockSize=5)
    runners: dict[str, Callable[[], object]] = {
        OURS: lambda: match(left, right, config),
        BM: lambda: bm.compute(left, right),
        SGBM: lambda: sgbm.compute(left, right),
    }
    if (width, height) == (640, 480):
        plain = MatcherConfig(window_size=9, disparity_range=disparities, method='plain')
        quarter = MatcherConfig(window_size=9, disparity_range=disparities,
                                roi=(160, 120, 320, 240))
        runners['stereo-fuzzy plain (Eq. 7)'] = lambda: match(left, right, plain)
        runners['stereo-fuzzy ZNCC, ROI 320x240 (Fig. 2)'] = lambda: match(left, right, quarter)
    calibration = verged_calibration(width, height)
    for stride in (1, 3):
        pipeline = StereoMatchingPipeline(config, point_stride=stride)
        runners[f'correlation stage, point_stride {stride}'] = (
            lambda pipeline=pipeline: stage(left, right, calibration, pipeline))
    samples = timed_rounds(runners, repeats)
    table = speed_table(f'{width}x{height}, {disparities} disparities', samples, BM)
    parts = _stage_parts(left, right, calibration, config, repeats)
    table.append(f'| (stage, point_stride 1, by part: {parts}) | | | |')
    return table


def cpu_time_table(data_dir: Path, width: int, height: int, disparities: int, repeats: int,
                   stage: Callable) -> list[str]:
    """Markdown rows: CPU time per pair with one thread each (OpenCV set to one thread)."""
    left, right = speed_images(data_dir, width, height)
    config = MatcherConfig(window_size=9, disparity_range=disparities)
    bm = cv2.StereoBM.create(numDisparities=disparities, blockSize=9)
    calibration = verged_calibration(width, height)
    runners: dict[str, Callable[[], object]] = {
        OURS: lambda: match(left, right, config, threads=1),
        BM: lambda: bm.compute(left, right),
    }
    for stride in (1, 3):
        pipeline = StereoMatchingPipeline(config, point_stride=stride, threads=1)
        runners[f'correlation stage, point_stride {stride}'] = (
            lambda pipeline=pipeline: stage(left, right, calibration, pipeline))
    samples = timed_rounds(runners, repeats, clock=time.thread_time)
    return speed_table(f'{width}x{height}, {disparities} disparities, one thread each, CPU time',
                       samples, BM)


def _stage_parts(left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                 config: MatcherConfig, repeats: int) -> str:
    """Median time of each step of StereoMatchingPipeline.process [ms], as it reports them."""
    pipeline = StereoMatchingPipeline(config)
    timings: dict[str, list[float]] = {}
    for _ in range(max(3, repeats)):
        for name, value in pipeline.process(left, right, calibration).timings_ms.items():
            timings.setdefault(name, []).append(value)
    return ', '.join(f'{name} {np.median(values):.2f} ms' for name, values in timings.items())


def timed_rounds(runners: dict[str, Callable[[], object]], repeats: int,
                 clock: Callable[[], float] = time.perf_counter) -> dict[str, list[float]]:
    """Return each runner's timed runs [ms]: rounds of one untimed run and three timed ones.

    Methods take turns round by round, so that the load of a shared machine, which changes from
    one second to the next, falls on all of them alike; within a round the runs are consecutive,
    so that a method does not wait for the threads the previous method left spinning (OpenCV's
    pool), which it would not meet in a node that runs one matcher.
    """
    samples: dict[str, list[float]] = {name: [] for name in runners}
    per_round = 3
    for _ in range(max(1, (repeats + per_round - 1) // per_round)):
        for name, run in runners.items():
            run()
            for _ in range(per_round):
                start = clock()
                run()
                samples[name].append(1e3 * (clock() - start))
    return samples


def speed_table(title: str, samples: dict[str, list[float]], reference: str) -> list[str]:
    """Markdown rows: median and fastest run [ms] of each method and its ratio to reference."""
    reference_median = float(np.median(samples[reference]))
    lines = [f'| {title} | median [ms] | min [ms] | / StereoBM |', '|---|---|---|---|']
    for name, values in samples.items():
        median = float(np.median(values))
        lines.append(f'| {name} | {median:.1f} | {min(values):.1f} | '
                     f'{median / reference_median:.2f} |')
    return lines


def _stage_function() -> Callable:
    """The correlation stage as correlation_node runs it: a StereoPair message in, StereoMatches
    out (decode, rectify, match, triangulate, pack) when the ROS workspace is sourced; without
    it, the ROS-free part (rectify, match, triangulate) on arrays."""
    try:
        from std_msgs.msg import Header
        from stereo_fuzzy_perception.nodes.conversions import (
            array_to_image,
            calibration_to_camera_info,
            stereo_matches_message,
            stereo_pair_to_domain,
        )

        from stereo_fuzzy_msgs.msg import StereoPair
    except ImportError:
        def arrays_stage(left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                         pipeline: StereoMatchingPipeline) -> object:
            return pipeline.process(left, right, calibration)

        arrays_stage.__doc__ = 'rectify + match + triangulate on arrays (ROS not sourced)'
        return arrays_stage

    header = Header(frame_id='left_optical')
    # The message is made once per pair, as a subscription receives it; the cache holds the
    # images themselves, so that a later pair can never be taken for an earlier one.
    pairs: list[tuple[np.ndarray, np.ndarray, StereoCalibration, object]] = []

    def message_stage(left: np.ndarray, right: np.ndarray, calibration: StereoCalibration,
                      pipeline: StereoMatchingPipeline) -> object:
        cached = [entry[3] for entry in pairs
                  if entry[0] is left and entry[1] is right and entry[2] is calibration]
        if not cached:
            cached.append(StereoPair(
                header=header, left_image=array_to_image(left, 'mono8', header),
                right_image=array_to_image(right, 'mono8', header),
                left_info=calibration_to_camera_info(calibration.left, header),
                right_info=calibration_to_camera_info(calibration.right, header)))
            pairs.append((left, right, calibration, cached[0]))
        raw_left, raw_right, raw_calibration = stereo_pair_to_domain(cached[0])
        result = pipeline.process(raw_left, raw_right, raw_calibration)
        return stereo_matches_message(header, result.rectified, result.points,
                                      pipeline.config)

    message_stage.__doc__ = ('StereoPair message in -> StereoMatches out: decode, rectify, '
                             'match, triangulate, pack')
    return message_stage


def main() -> None:
    """Run the sections asked for and print their tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, default=REPO_ROOT.parent / 'shared' / 'data'
                        / 'middlebury', help='folder of the Middlebury scenes')
    parser.add_argument('--scenes', default=','.join(SCENES), help='comma-separated scenes')
    parser.add_argument('--repeats', type=int, default=15, help='timed runs per method')
    parser.add_argument('--skip-accuracy', action='store_true')
    parser.add_argument('--skip-robustness', action='store_true')
    parser.add_argument('--skip-speed', action='store_true')
    arguments = parser.parse_args()

    warm_up()
    scenes = []
    if not (arguments.skip_accuracy and arguments.skip_robustness):
        scenes = [load_scene(arguments.data, name) for name in arguments.scenes.split(',')
                  if name]
    if not arguments.skip_accuracy:
        print('## 1. Accuracy (Middlebury, 64 disparities; no estimate counts as bad)\n')
        print(accuracy_table(scenes, lambda image: image, {
            'stereo-fuzzy ZNCC (Eq. 8)': ours(default_config()),
            'OpenCV StereoBM': opencv_bm,
            'OpenCV StereoSGBM': opencv_sgbm,
        }))
        print()
    if not arguments.skip_robustness:
        print('## 2. Robustness: right image x1.3 + 20 (clipped)\n')
        print(accuracy_table(scenes, brighter, {
            'stereo-fuzzy ZNCC (Eq. 8)': ours(default_config()),
            'stereo-fuzzy plain (Eq. 7)': ours(MatcherConfig(disparity_range=DISPARITIES,
                                                             method='plain')),
            'OpenCV StereoBM': opencv_bm,
        }))
        print()
    if not arguments.skip_speed:
        print('## 3. Speed\n')
        print(speed_section(arguments.data, arguments.repeats))


if __name__ == '__main__':
    main()
