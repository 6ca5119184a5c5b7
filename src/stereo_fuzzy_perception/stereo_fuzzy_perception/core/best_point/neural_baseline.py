"""The neural-network baseline the chapter compares against: a small MLP, numpy only. ROS-free.

Inputs are the fuzzy system's own features: the four ratios r_k (as log r, clipped), the four area
centres relative to the whole area's centre (world x, y) and that centre's world x, y. The output
is an offset [m] from (centre x, centre y, top height), like the fitted rule base's consequents.
One tanh hidden layer; trained by full-batch Adam on simulated scenes (scripts/train_*.py).
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import CorrelationArea
from stereo_fuzzy_perception.core.best_point.four_areas import FourAreas
from stereo_fuzzy_perception.core.yaml_file import MAX_DATA_FILE_BYTES, read_file_bytes

FEATURE_COUNT = 14
LOG_RATIO_LIMIT = 3.0
MAX_OUTPUT_SCALE = 1.0
"""Largest output_scale [m per output unit] a weights file may hold (trained ones: 1e-3)."""
WEIGHT_ARRAYS = ('input_mean', 'input_std', 'w1', 'b1', 'w2', 'b2', 'output_scale')


class NeuralBaselineError(ValueError):
    """A weights file that cannot be used, with the reason."""


def neural_features(area: CorrelationArea, areas: FourAreas) -> np.ndarray:
    """Return the (14,) input vector of one decision (empty areas contribute zeros)."""
    with np.errstate(invalid='ignore', divide='ignore'):
        log_ratio = np.clip(np.log(np.maximum(areas.ratio, 1e-12)), -LOG_RATIO_LIMIT,
                            LOG_RATIO_LIMIT)
    relative = (areas.centres[:, :2] - areas.centre[:2]).ravel()
    log_ratio, relative = np.nan_to_num(log_ratio), np.nan_to_num(relative)  # empty areas: 0
    return np.concatenate([log_ratio, relative, areas.centre[:2]])


def neural_base_point(area: CorrelationArea, areas: FourAreas) -> np.ndarray:
    """Return the point the network's offset is added to: (centre x, centre y, top height)."""
    return np.array([areas.centre[0], areas.centre[1], area.top_height])


@dataclass(frozen=True)
class NeuralBaseline:
    """Weights of a one-hidden-layer perceptron (tanh), with input and output scaling.

    Attributes:
        input_mean: (F,) subtracted from the features.
        input_std: (F,) divides the centred features.
        w1: (F, H) first layer weights.
        b1: (H,) first layer bias.
        w2: (H, 3) output weights.
        b2: (3,) output bias.
        output_scale: Metres per output unit.
    """

    input_mean: np.ndarray
    input_std: np.ndarray
    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: np.ndarray
    output_scale: float

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Return offsets [m], shape (..., 3), for features of shape (..., F)."""
        with np.errstate(over='ignore', invalid='ignore'):  # huge weights: inf, checked later
            hidden = np.tanh(((features - self.input_mean) / self.input_std) @ self.w1
                             + self.b1)
            return np.asarray((hidden @ self.w2 + self.b2) * self.output_scale)

    def save(self, path: str | Path) -> None:
        """Write the weights as a compressed .npz file."""
        np.savez_compressed(path, input_mean=self.input_mean, input_std=self.input_std,
                            w1=self.w1, b1=self.b1, w2=self.w2, b2=self.b2,
                            output_scale=np.array(self.output_scale))

    @classmethod
    def load(cls, path: str | Path) -> NeuralBaseline:
        """Read weights written by save(), checking every array before it is used.

        The file must be a regular .npz file within the size cap (yaml_file.read_file_bytes),
        its uncompressed arrays within the same cap, every array numeric, of the expected
        shape and finite, input_std non-zero and output_scale one positive finite number.

        Raises:
            NeuralBaselineError: When the file is missing, unreadable, or any check fails.
        """
        data = read_file_bytes(Path(path), NeuralBaselineError, 'network weights')
        arrays = _read_npz(data, str(path))
        return cls.from_arrays(arrays, str(path))

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], source: str = '<arrays>'
                    ) -> NeuralBaseline:
        """Build a network from named arrays (the .npz members), checking them all.

        Raises:
            NeuralBaselineError: Naming the array and what was expected.
        """
        missing = [name for name in WEIGHT_ARRAYS if name not in arrays]
        if missing:
            raise NeuralBaselineError(f'{source}: missing array(s) {", ".join(missing)}')
        values: dict[str, np.ndarray] = {}
        for name in WEIGHT_ARRAYS:
            array = np.asarray(arrays[name])
            if array.dtype.kind not in 'biuf':
                raise NeuralBaselineError(f'{source}: {name} holds {array.dtype} values, '
                                          'expected real numbers')
            values[name] = array.astype(np.float64)
            if not np.all(np.isfinite(values[name])):
                raise NeuralBaselineError(f'{source}: {name} holds NaN or infinity')
        w1 = values['w1']
        hidden = w1.shape[-1] if w1.ndim == 2 else -1
        expected = {'input_mean': (FEATURE_COUNT,), 'input_std': (FEATURE_COUNT,),
                    'w1': (FEATURE_COUNT, hidden), 'b1': (hidden,), 'w2': (hidden, 3),
                    'b2': (3,), 'output_scale': ()}
        if values['output_scale'].shape == (1,):
            values['output_scale'] = values['output_scale'].reshape(())
        for name, shape in expected.items():
            if values[name].shape != shape or hidden < 1:
                wanted = tuple('H' if size == hidden else size for size in shape)
                raise NeuralBaselineError(f'{source}: {name} has shape {values[name].shape}, '
                                          f'expected {wanted} (H hidden units >= 1)')
        if np.any(values['input_std'] == 0.0):
            raise NeuralBaselineError(f'{source}: input_std holds zeros (features divide by it)')
        scale = float(values['output_scale'])
        if not 0.0 < scale <= MAX_OUTPUT_SCALE:
            raise NeuralBaselineError(f'{source}: output_scale {scale:g} must be in '
                                      f'(0, {MAX_OUTPUT_SCALE:g}] [m per output unit]')
        return cls(values['input_mean'], values['input_std'], w1, values['b1'],
                   values['w2'], values['b2'], scale)


def _read_npz(data: bytes, source: str) -> dict[str, np.ndarray]:
    """Return the arrays of an .npz archive held in `data`, never unpickling objects.

    Raises:
        NeuralBaselineError: For a file that is not an .npz archive (an .npy, say), members
            that would decompress beyond the size cap, or unreadable members.
    """
    if not zipfile.is_zipfile(io.BytesIO(data)):
        raise NeuralBaselineError(f'{source}: not an .npz archive (np.savez); an .npy file or '
                                  'another format cannot hold the network')
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            total = sum(member.file_size for member in archive.infolist())
        if total > MAX_DATA_FILE_BYTES:
            raise NeuralBaselineError(f'{source}: arrays of {total} bytes uncompressed, more '
                                      f'than the {MAX_DATA_FILE_BYTES} allowed')
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            names = [name for name in archive.files if name in WEIGHT_ARRAYS]
            return {name: np.asarray(archive[name]) for name in names}
    except NeuralBaselineError:
        raise
    except Exception as error:  # zipfile, zlib and numpy's format module raise many types
        raise NeuralBaselineError(f'{source}: cannot read network weights '
                                  f'({type(error).__name__}: {str(error)[:200]})') from error


def train_neural_baseline(features: np.ndarray, offsets: np.ndarray, hidden: int = 16,
                          iterations: int = 4000, learning_rate: float = 0.01,
                          weight_decay: float = 1e-4, seed: int = 0) -> NeuralBaseline:
    """Fit the perceptron to (features, offsets [m]) by full-batch Adam on the squared error.

    Args:
        features: (S, F) inputs.
        offsets: (S, 3) targets [m].
        hidden: Hidden units.
        iterations: Adam steps.
        learning_rate: Adam step size.
        weight_decay: L2 penalty on the weights.
        seed: Initialisation seed.

    Returns:
        The trained network.
    """
    rng = np.random.default_rng(seed)
    mean = features.mean(axis=0)
    std = features.std(axis=0) + 1e-9
    x = (features - mean) / std
    scale = 1e-3  # outputs in millimetres
    y = offsets / scale
    params = [rng.normal(0.0, 1.0 / np.sqrt(x.shape[1]), (x.shape[1], hidden)),
              np.zeros(hidden), rng.normal(0.0, 1.0 / np.sqrt(hidden), (hidden, 3)),
              np.zeros(3)]
    moments = [np.zeros_like(p) for p in params]
    squares = [np.zeros_like(p) for p in params]
    beta1, beta2 = 0.9, 0.999
    count = len(x)
    for step in range(1, iterations + 1):
        w1, b1, w2, b2 = params
        hidden_out = np.tanh(x @ w1 + b1)
        error = hidden_out @ w2 + b2 - y
        grad_out = 2.0 * error / count
        grad_w2 = hidden_out.T @ grad_out + weight_decay * w2
        grad_b2 = grad_out.sum(axis=0)
        grad_hidden = (grad_out @ w2.T) * (1.0 - hidden_out ** 2)
        grad_w1 = x.T @ grad_hidden + weight_decay * w1
        grad_b1 = grad_hidden.sum(axis=0)
        for index, grad in enumerate((grad_w1, grad_b1, grad_w2, grad_b2)):
            moments[index] = beta1 * moments[index] + (1 - beta1) * grad
            squares[index] = beta2 * squares[index] + (1 - beta2) * grad ** 2
            corrected = moments[index] / (1 - beta1 ** step)
            params[index] = params[index] - learning_rate * corrected / (
                np.sqrt(squares[index] / (1 - beta2 ** step)) + 1e-8)
    return NeuralBaseline(mean, std, params[0], params[1], params[2], params[3], scale)
