"""The neural-network baseline the chapter compares against: a small MLP, numpy only. ROS-free.

Inputs are the fuzzy system's own features: the four ratios r_k (as log r, clipped), the four area
centres relative to the whole area's centre (world x, y) and that centre's world x, y. The output
is an offset [m] from (centre x, centre y, top height), like the fitted rule base's consequents.
One tanh hidden layer; trained by full-batch Adam on simulated scenes (scripts/train_*.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereo_fuzzy_perception.core.best_point.correlation_area import CorrelationArea, FourAreas

FEATURE_COUNT = 14
LOG_RATIO_LIMIT = 3.0


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
        hidden = np.tanh(((features - self.input_mean) / self.input_std) @ self.w1 + self.b1)
        return np.asarray((hidden @ self.w2 + self.b2) * self.output_scale)

    def save(self, path: str | Path) -> None:
        """Write the weights as a compressed .npz file."""
        np.savez_compressed(path, input_mean=self.input_mean, input_std=self.input_std,
                            w1=self.w1, b1=self.b1, w2=self.w2, b2=self.b2,
                            output_scale=np.array(self.output_scale))

    @classmethod
    def load(cls, path: str | Path) -> NeuralBaseline:
        """Read weights written by save().

        Raises:
            NeuralBaselineError: When the file is missing or the shapes do not fit.
        """
        try:
            with np.load(path) as data:
                arrays = {name: np.asarray(data[name], dtype=float) for name in (
                    'input_mean', 'input_std', 'w1', 'b1', 'w2', 'b2', 'output_scale')}
        except (OSError, KeyError, ValueError) as error:
            raise NeuralBaselineError(f'{path}: cannot read network weights ({error})') from error
        hidden = arrays['w1'].shape[-1]
        expected = {'input_mean': (FEATURE_COUNT,), 'input_std': (FEATURE_COUNT,),
                    'w1': (FEATURE_COUNT, hidden), 'b1': (hidden,), 'w2': (hidden, 3),
                    'b2': (3,)}
        for name, shape in expected.items():
            if arrays[name].shape != shape:
                raise NeuralBaselineError(f'{path}: {name} has shape {arrays[name].shape}, '
                                          f'expected {shape}')
        return cls(arrays['input_mean'], arrays['input_std'], arrays['w1'], arrays['b1'],
                   arrays['w2'], arrays['b2'], float(arrays['output_scale']))


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
