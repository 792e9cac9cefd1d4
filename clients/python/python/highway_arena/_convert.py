"""Wire values from the extension -> gymnasium spaces and fresh numpy arrays, and
Python actions -> what the extension takes."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces


def space(spec: dict) -> spaces.Space:
    kind = spec["type"]
    if kind == "box":
        shape = tuple(spec["shape"])
        dtype = np.dtype(spec["dtype"])
        low = np.asarray(spec["low"], dtype=np.float64).reshape(shape)
        high = np.asarray(spec["high"], dtype=np.float64).reshape(shape)
        return spaces.Box(low.astype(dtype), high.astype(dtype), shape=shape, dtype=dtype)
    if kind == "discrete":
        return spaces.Discrete(spec["n"], start=spec["start"])
    if kind == "dict":
        return spaces.Dict({key: space(inner) for key, inner in spec["spaces"]})
    raise ValueError(f"unknown space type {kind!r}")


def _tensor(value) -> np.ndarray:
    dtype, shape, data = value
    # frombuffer shares the (immutable) bytes; copy gives every caller a fresh array.
    return np.frombuffer(data, dtype=np.dtype(dtype).newbyteorder("<")).astype(dtype).reshape(shape)


def observation(value):
    kind, payload = value
    if kind == "tensor":
        return _tensor(payload)
    return {key: _tensor(tensor) for key, tensor in payload}


def action(value, action_space: spaces.Space, agent: str):
    """An int for Discrete, two floats for Box; numpy scalars and arrays accepted."""
    if isinstance(action_space, spaces.Discrete):
        array = np.asarray(value)
        if array.shape != () or not np.issubdtype(array.dtype, np.integer):
            raise ValueError(f"agent {agent!r}: expected an int for {action_space}, got {value!r}")
        return int(array)
    array = np.asarray(value, dtype=np.float32).reshape(-1)
    return [float(x) for x in array]
