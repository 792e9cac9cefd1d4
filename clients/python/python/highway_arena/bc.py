"""Behaviour cloning with numpy alone: a small MLP fitted to (observation, action) pairs,
such as a Minari dataset that ``highway_arena.record`` wrote.

    import highway_arena.bc
    policy = highway_arena.bc.fit(dataset, seed=0)         # a MinariDataset or (observations, actions)
    action = policy(observation)                           # an int (meta) or 2 floats (continuous)
    policy.save("bc.npz"); policy = highway_arena.bc.load("bc.npz")

Numpy only, because the default test command installs no torch (it is large, and the
envs need none): the network is one or two tanh layers whose gradients are written out
by hand, trained with Adam on standardised flattened kinematics observations. Meta
actions (Discrete) are a softmax classifier trained on cross-entropy; by default each
class is weighted by the inverse square root of its frequency (``class_weight="sqrt"``),
because the expert idles in nearly every step and changes lane in about one in two
hundred. Fitted (seed 0) to 30 expert episodes of merge-random and played on 30 others,
unweighted it never changes lane (27 of 30 episodes run out of lane); weighted by the
inverse frequency (``"balanced"``) it changes lane so often that it drives off the far
side of the road (9 of 30); with sqrt weights 1 of 30 fail (fit seeds 1-3: 0, 7, 14;
a uniform random policy: 21). Continuous actions (Box) are regressed on squared error
and clipped to the space. The fit is deterministic given ``seed`` (initial weights and
minibatch order come from ``numpy.random.default_rng(seed)``).
"""

from __future__ import annotations

import os

import numpy as np

FORMAT_VERSION = 1


def arrays(data) -> tuple[np.ndarray, np.ndarray]:
    """``(observations, actions)`` of every step: from a MinariDataset (each episode's
    first T of its T + 1 observations, with its T actions), or a pair of arrays."""
    if isinstance(data, tuple) and len(data) == 2:
        observations, actions = data
        return np.asarray(observations), np.asarray(actions)
    if hasattr(data, "iterate_episodes"):
        observations, actions = [], []
        for episode in data.iterate_episodes():
            if not isinstance(episode.observations, np.ndarray):
                raise TypeError("bc fits flat Box observations; this dataset's observations are not one array")
            observations.append(episode.observations[:-1])
            actions.append(episode.actions)
        if not observations:
            raise ValueError("the dataset has no episodes")
        return np.concatenate(observations), np.concatenate(actions)
    raise TypeError(f"fit takes a MinariDataset or (observations, actions), not {type(data).__name__}")


# The fields of a saved policy that some policies lack.
OPTIONAL = ("n_actions", "low", "high", "target_mean", "target_std", "training_seeds")


class Policy:
    """A fitted MLP. ``policy(observation)`` is the action for one observation (an int
    for a discrete policy, a float32 array for a continuous one) or, for a batch
    (2-D), an array of actions; ``policy.probabilities(observations)`` gives a discrete
    policy's class probabilities."""

    def __init__(
        self,
        mean,
        std,
        layers,
        discrete: bool,
        n_actions=None,
        low=None,
        high=None,
        target_mean=None,
        target_std=None,
        training_seeds=None,
    ):
        self.mean = np.asarray(mean, dtype=np.float64)
        self.std = np.asarray(std, dtype=np.float64)
        self.layers = [(np.asarray(w, dtype=np.float64), np.asarray(b, dtype=np.float64)) for w, b in layers]
        self.discrete = bool(discrete)
        self.n_actions = None if n_actions is None else int(n_actions)
        self.low = None if low is None else np.asarray(low, dtype=np.float64)
        self.high = None if high is None else np.asarray(high, dtype=np.float64)
        self.target_mean = None if target_mean is None else np.asarray(target_mean, dtype=np.float64)
        self.target_std = None if target_std is None else np.asarray(target_std, dtype=np.float64)
        # The reset seeds of the episodes it was fitted to, when its data said them:
        # ``evaluate`` warns when it plays the policy on them.
        self.training_seeds = None if training_seeds is None else [int(s) for s in np.asarray(training_seeds).ravel()]

    def _outputs(self, observations: np.ndarray) -> np.ndarray:
        x = (np.asarray(observations, dtype=np.float64).reshape(len(observations), -1) - self.mean) / self.std
        return _forward(self.layers, x)[-1]

    def probabilities(self, observations) -> np.ndarray:
        if not self.discrete:
            raise TypeError("a continuous policy has no class probabilities")
        return _softmax(self._outputs(np.atleast_2d(observations)))

    def predict(self, observations) -> np.ndarray:
        """Actions for a batch of observations (one per row)."""
        outputs = self._outputs(np.asarray(observations))
        if self.discrete:
            return outputs.argmax(axis=1)
        actions = outputs * self.target_std + self.target_mean
        return np.clip(actions, self.low, self.high).astype(np.float32)

    def __call__(self, observation):
        observation = np.asarray(observation)
        if observation.ndim >= 2:
            return self.predict(observation)
        action = self.predict(observation[None])[0]
        return int(action) if self.discrete else action

    def save(self, path) -> None:
        """Writes the policy to an ``.npz`` file (numpy arrays only; ``load`` reads it)."""
        fields = {
            "format_version": np.array(FORMAT_VERSION),
            "discrete": np.array(self.discrete),
            "mean": self.mean,
            "std": self.std,
            "n_layers": np.array(len(self.layers)),
        }
        for i, (w, b) in enumerate(self.layers):
            fields[f"w{i}"], fields[f"b{i}"] = w, b
        for name in OPTIONAL:
            value = getattr(self, name)
            if value is not None:
                fields[name] = np.asarray(value)
        with open(os.fspath(path), "wb") as file:
            np.savez(file, **fields)

    @classmethod
    def load(cls, path) -> "Policy":
        with np.load(os.fspath(path), allow_pickle=False) as data:
            version = int(data["format_version"])
            if version != FORMAT_VERSION:
                raise ValueError(f"{path}: a bc policy of format {version}; this highway_arena reads {FORMAT_VERSION}")
            layers = [(data[f"w{i}"], data[f"b{i}"]) for i in range(int(data["n_layers"]))]
            optional = {name: data[name] for name in OPTIONAL if name in data}
            return cls(data["mean"], data["std"], layers, bool(data["discrete"]), **optional)


def load(path) -> Policy:
    """The policy ``Policy.save`` wrote to ``path``."""
    return Policy.load(path)


def _softmax(z: np.ndarray) -> np.ndarray:
    z = z - z.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


def _forward(layers, x: np.ndarray) -> list[np.ndarray]:
    """Every layer's output, input first; tanh between layers, the last one linear."""
    outputs = [x]
    for i, (w, b) in enumerate(layers):
        z = outputs[-1] @ w + b
        outputs.append(np.tanh(z) if i < len(layers) - 1 else z)
    return outputs


def _gradients(layers, outputs, d_out: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Backpropagation of d loss / d (last layer's output) through the tanh layers."""
    grads = [None] * len(layers)
    delta = d_out
    for i in reversed(range(len(layers))):
        w, _ = layers[i]
        grads[i] = (outputs[i].T @ delta, delta.sum(axis=0))
        if i > 0:
            delta = (delta @ w.T) * (1.0 - outputs[i] ** 2)
    return grads


def fit(
    data,
    seed: int = 0,
    hidden=(64,),
    epochs: int = 60,
    batch_size: int = 256,
    learning_rate: float = 3e-3,
    weight_decay: float = 1e-4,
    class_weight: str | None = "sqrt",
    action_space=None,
) -> Policy:
    """Fits a policy to ``data`` (a MinariDataset, or ``(observations, actions)``).

    ``hidden``: the tanh layers' widths. ``epochs`` passes of Adam over minibatches of
    ``batch_size``, ``learning_rate``, L2 ``weight_decay`` on the weights.
    ``class_weight``: ``"sqrt"`` (each meta action weighted by the inverse square root of
    its frequency), ``"balanced"`` (by the inverse of its frequency) or None.
    ``action_space``: the actions' gymnasium space (default: the dataset's, else
    Discrete if the actions are integers)."""
    observations, actions = arrays(data)
    if len(observations) != len(actions) or len(actions) == 0:
        raise ValueError(f"need as many observations as actions, and some: got {len(observations)} and {len(actions)}")
    if class_weight not in ("balanced", "sqrt", None):
        raise ValueError(f"class_weight must be 'balanced', 'sqrt' or None, not {class_weight!r}")
    if action_space is None and hasattr(data, "action_space"):
        action_space = data.action_space
    x = observations.reshape(len(observations), -1).astype(np.float64)
    mean = x.mean(axis=0)
    # Features that never vary (absent rows) keep scale 1 instead of dividing by zero.
    std = np.where(x.std(axis=0) > 1e-6, x.std(axis=0), 1.0)
    x = (x - mean) / std
    rng = np.random.default_rng(seed)

    discrete = np.issubdtype(actions.dtype, np.integer) if action_space is None else hasattr(action_space, "n")
    extra = {}
    if discrete:
        if action_space is not None and int(action_space.start) != 0:
            raise ValueError(f"bc fits Discrete spaces that start at 0, not {action_space}")
        n = int(action_space.n) if action_space is not None else int(actions.max()) + 1
        labels = actions.astype(np.int64).reshape(-1)
        targets = np.eye(n)[labels]
        counts = np.bincount(labels, minlength=n).astype(np.float64)
        if class_weight in ("balanced", "sqrt"):
            present = counts > 0
            per_class = np.where(present, len(labels) / (present.sum() * np.maximum(counts, 1.0)), 0.0)
            if class_weight == "sqrt":
                per_class = np.sqrt(per_class)
        else:
            per_class = np.ones(n)
        sample_weight = per_class[labels]
        extra["n_actions"] = n
        width_out = n
    else:
        y = actions.reshape(len(actions), -1).astype(np.float64)
        target_mean = y.mean(axis=0)
        target_std = np.where(y.std(axis=0) > 1e-6, y.std(axis=0), 1.0)
        targets = (y - target_mean) / target_std
        sample_weight = np.ones(len(y))
        low = action_space.low if action_space is not None else y.min(axis=0)
        high = action_space.high if action_space is not None else y.max(axis=0)
        extra.update(low=low, high=high, target_mean=target_mean, target_std=target_std)
        width_out = y.shape[1]

    widths = [x.shape[1], *hidden, width_out]
    layers = [
        (rng.normal(0.0, 1.0 / np.sqrt(fan_in), size=(fan_in, fan_out)), np.zeros(fan_out))
        for fan_in, fan_out in zip(widths[:-1], widths[1:])
    ]
    # Adam (Kingma & Ba), bias-corrected, with the paper's default betas.
    beta1, beta2, eps, t = 0.9, 0.999, 1e-8, 0
    moments = [[np.zeros_like(p) for p in layer] for layer in layers]
    squares = [[np.zeros_like(p) for p in layer] for layer in layers]
    total_weight = sample_weight.sum()
    for _ in range(int(epochs)):
        order = rng.permutation(len(x))
        for start in range(0, len(x), batch_size):
            batch = order[start : start + batch_size]
            outputs = _forward(layers, x[batch])
            weight = sample_weight[batch, None] * (len(x) / total_weight) / len(batch)
            if discrete:
                d_out = (_softmax(outputs[-1]) - targets[batch]) * weight
            else:
                d_out = 2.0 * (outputs[-1] - targets[batch]) * weight
            grads = _gradients(layers, outputs, d_out)
            t += 1
            for i, ((w, b), (gw, gb)) in enumerate(zip(layers, grads)):
                gw = gw + weight_decay * w
                for j, (param, grad) in enumerate(((w, gw), (b, gb))):
                    moments[i][j] = beta1 * moments[i][j] + (1 - beta1) * grad
                    squares[i][j] = beta2 * squares[i][j] + (1 - beta2) * grad**2
                    m_hat = moments[i][j] / (1 - beta1**t)
                    v_hat = squares[i][j] / (1 - beta2**t)
                    param -= learning_rate * m_hat / (np.sqrt(v_hat) + eps)
    if hasattr(data, "storage"):
        from .datasets import training_seeds

        extra["training_seeds"] = training_seeds(data)
    return Policy(mean, std, layers, discrete, **extra)
