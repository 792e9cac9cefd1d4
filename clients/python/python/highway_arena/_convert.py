"""Wire values from the extension -> gymnasium spaces and fresh numpy arrays, and
Python actions -> what the extension takes."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ._errors import InvalidActionError


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


# The extension's (dtype, shape, bytes) columns, for other modules (recordings).
tensor = _tensor


def observation(value):
    kind, payload = value
    if kind == "tensor":
        return _tensor(payload)
    return {key: _tensor(tensor) for key, tensor in payload}


def action(value, action_space: spaces.Space, agent: str):
    """An int for Discrete (a Python int, a numpy integer, or an integer array of one
    element), floats for Box (any sequence or array of the space's size)."""
    if isinstance(action_space, spaces.Discrete):
        if type(value) is int:
            index = value
        else:
            array = np.asarray(value)
            if array.size != 1 or not np.issubdtype(array.dtype, np.integer):
                raise InvalidActionError(
                    "InvalidAction", f"agent {agent!r}: expected an int for {action_space}, got {value!r}"
                )
            index = int(array.reshape(()))
        first = int(action_space.start)
        if not first <= index < first + int(action_space.n):
            last = first + int(action_space.n) - 1
            raise InvalidActionError(
                "InvalidAction", f"agent {agent!r}: action {index} is outside {action_space}: use {first}..{last}"
            )
        return index
    try:
        array = np.asarray(value, dtype=np.float32)
    except (TypeError, ValueError):
        array = None
    if array is None or array.size != int(np.prod(action_space.shape)):
        raise InvalidActionError(
            "InvalidAction",
            f"agent {agent!r}: expected {int(np.prod(action_space.shape))} floats for {action_space}, got {value!r}",
        )
    return array.reshape(-1).tolist()
