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
3. Speed: ms per 640x480 pair, 64 disparities, 9x9 window, against StereoBM on the same images
   in the same process (median of --repeats runs in 3 rounds, as a ratio; with every thread,
   then with one thread each, so that the work per pair shows apart from how each method
   scales on the machine's cores), the numba compile and cache-load cost (in fresh
   processes), and the whole pipeline: rectify + match + triangulate + StereoMatches packing
   (packing only when the ROS workspace is sourced).

Markdown tables go to stdout. Needs numpy, OpenCV and numba; imports the package from src/.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO_ROOT / 'src' / 'stereo_fuzzy_perception'))

from stereo_fuzzy_perception.core.camera_model import (  # noqa: E402
    CameraCalibration,
    StereoCalibration,
)
from stereo_fuzzy_perception.core.matching.stereo_matching import StereoMatchingPipeline  # noqa: E402
from stereo_fuzzy_perception.core.matching.window_matcher import MatcherConfig, match, warm_up  # noqa: E402
from stereo_fuzzy_perception.core.rig_geometry import StereoRig  # noqa: E402

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


def speed_images(data_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """A 640x480 pair: cones resized (real texture), or a synthetic texture without the data."""
    folder = data_dir / 'cones'
    left = cv2.imread(str(folder / 'left.png'), cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(str(folder / 'right.png'), cv2.IMREAD_GRAYSCALE)
    if left is None or right is None:
        rng = np.random.default_rng(0)
        scene = cv2.GaussianBlur(rng.uniform(0, 255, (480, 680)).astype(np.float32), (0, 0), 1.2)
        scene = np.clip(128 + 3 * (scene - scene.mean()), 0, 255).astype(np.uint8)
        return scene[:, :640].copy(), scene[:, 20:660].copy()
    return (cv2.resize(left, (640, 480), interpolation=cv2.INTER_LINEAR),
            cv2.resize(right, (640, 480), interpolation=cv2.INTER_LINEAR))


def kernel_start_cost() -> tuple[float, float]:
    """Return (cold compile, cached load) time of the kernels [s], each in a fresh process."""
    package_dir = str(REPO_ROOT / 'src' / 'stereo_fuzzy_perception')
    code = (f'import sys; sys.path.insert(0, {package_dir!r}); '
            'from stereo_fuzzy_perception.core.matching.window_matcher import warm_up; '
            'print(warm_up())')
    with tempfile.TemporaryDirectory() as cache_dir:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
        times = []
        for _ in range(2):
            done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True,
                                  text=True, check=True)
            times.append(float(done.stdout.strip().splitlines()[-1]))
    return times[0], times[1]


def verged_calibration(width: int, height: int) -> StereoCalibration:
    """A toed-in 640x480 rig calibrated as cv2.stereoRectify would (for the pipeline timing)."""
    K = np.array([[520.0, 0.0, width / 2], [0.0, 520.0, height / 2], [0.0, 0.0, 1.0]])
    D = np.array([-0.05, 0.01, 0.0, 0.0, 0.0])
    rotation, translation = StereoRig(baseline_m=0.06, vergence_deg=6.0).right_from_left()
    R1, R2, P1, P2, *_ = cv2.stereoRectify(K, D, K, D, (width, height), rotation,
                                           translation.reshape(3, 1), alpha=0)
    return StereoCalibration(CameraCalibration(width, height, K, D, R1, P1),
                             CameraCalibration(width, height, K, D, R2, P2))


def speed_section(data_dir: Path, repeats: int) -> str:
    left, right = speed_images(data_dir)
    config = MatcherConfig(window_size=9, disparity_range=DISPARITIES)
    plain = MatcherConfig(window_size=9, disparity_range=DISPARITIES, method='plain')
    bm = cv2.StereoBM.create(numDisparities=DISPARITIES, blockSize=9)
    sgbm = cv2.StereoSGBM.create(minDisparity=0, numDisparities=DISPARITIES, blockSize=5)
    first_call = warm_up()
    runners: dict[str, Callable[[], object]] = {
        'stereo-fuzzy ZNCC (Eq. 8)': lambda: match(left, right, config),
        'stereo-fuzzy plain (Eq. 7)': lambda: match(left, right, plain),
        'OpenCV StereoBM (block 9)': lambda: bm.compute(left, right),
        'OpenCV StereoSGBM (block 5)': lambda: sgbm.compute(left, right),
    }
    quarter = MatcherConfig(window_size=9, disparity_range=DISPARITIES,
                            roi=(160, 120, 320, 240))
    runners['stereo-fuzzy ZNCC, ROI 320x240 (Fig. 2)'] = lambda: match(left, right, quarter)
    calibration = verged_calibration(640, 480)
    pipeline = StereoMatchingPipeline(config)
    packing = _packing_function()

    def whole_pipeline() -> None:
        result = pipeline.process(left, right, calibration)
        if packing is not None:
            packing(result, config)

    runners['pipeline: rectify + match + triangulate' + (' + pack' if packing else '')] = (
        whole_pipeline)
    samples = timed_rounds(runners, repeats)
    lines = speed_table(f'method (640x480, 64 disparities, {_threads()} threads)', samples,
                        'OpenCV StereoBM (block 9)')
    # One thread each: the work per pair, apart from how each method scales on this machine's
    # cores (which on a shared VM changes from one minute to the next; README has the figures).
    single = timed_rounds_on_one_thread({
        'stereo-fuzzy ZNCC (Eq. 8)': runners['stereo-fuzzy ZNCC (Eq. 8)'],
        'OpenCV StereoBM (block 9)': runners['OpenCV StereoBM (block 9)'],
    }, repeats)
    lines.append('')
    lines.extend(speed_table('one thread each', single, 'OpenCV StereoBM (block 9)'))
    gains = ', '.join(
        f'{name} {np.median(single[name]) / np.median(samples[name]):.2f}x' for name in single)
    lines.append('')
    lines.append(f'Gain from 1 to {_threads()} threads: {gains}.')
    cold, cached = kernel_start_cost()
    lines.append('')
    lines.append(f'numba kernels: cold compile {cold:.1f} s, load from cache {cached:.2f} s '
                 f'(fresh processes); first call in this process {first_call:.2f} s; '
                 f'{_threads()} threads. Not counted above.')
    valid = match(left, right, config).valid.mean()
    lines.append(f'Share of valid pixels on the speed pair: {100 * valid:.1f} %.')
    return '\n'.join(lines)


def timed_rounds(runners: dict[str, Callable[[], object]],
                 repeats: int) -> dict[str, list[float]]:
    """Return each runner's timed runs [ms]: 3 rounds, each one untimed run then repeats / 3.

    Rounds of consecutive runs per method: calling numba's and OpenCV's thread pools
    alternately makes each wait for the other's spinning workers, which neither meets in a node
    that runs one matcher.
    """
    samples: dict[str, list[float]] = {name: [] for name in runners}
    rounds = 3
    for _ in range(rounds):
        for name, run in runners.items():
            run()
            for _ in range(max(1, repeats // rounds)):
                start = time.perf_counter()
                run()
                samples[name].append(1e3 * (time.perf_counter() - start))
    return samples


def timed_rounds_on_one_thread(runners: dict[str, Callable[[], object]],
                               repeats: int) -> dict[str, list[float]]:
    """timed_rounds with numba and OpenCV limited to one thread, restored afterwards."""
    import numba

    numba_threads, opencv_threads = numba.get_num_threads(), cv2.getNumThreads()
    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    try:
        return timed_rounds(runners, repeats)
    finally:
        numba.set_num_threads(numba_threads)
        cv2.setNumThreads(opencv_threads)


def speed_table(title: str, samples: dict[str, list[float]], reference: str) -> list[str]:
    """Markdown rows: median and fastest run [ms] of each method and its ratio to reference."""
    reference_median = float(np.median(samples[reference]))
    lines = [f'| {title} | median [ms] | min [ms] | / StereoBM |', '|---|---|---|---|']
    for name, values in samples.items():
        median = float(np.median(values))
        lines.append(f'| {name} | {median:.1f} | {min(values):.1f} | '
                     f'{median / reference_median:.2f} |')
    return lines


def _threads() -> int:
    import numba

    return int(numba.get_num_threads())


def _packing_function() -> Callable | None:
    """StereoMatches packing when the ROS workspace is sourced, else None."""
    try:
        from std_msgs.msg import Header
        from stereo_fuzzy_perception.nodes.conversions import stereo_matches_message
    except ImportError:
        return None

    def pack(result, config: MatcherConfig) -> object:
        return stereo_matches_message(Header(frame_id='left'), result.rectified, result.points,
                                      config)

    return pack


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
