"""Wire values from the extension -> gymnasium spaces and fresh numpy arrays, and
Python actions -> what the extension takes."""

from __future__ import annotations

import enum

import numpy as np
from gymnasium import spaces

from ._core import END_REASONS
from ._errors import InvalidActionError

# The end reasons by name (``EndReason.COLLISION``), made from the protocol's list, so a
# misspelt one fails where it is written instead of matching nothing.
EndReason = enum.IntEnum("EndReason", [(name.upper(), code) for code, name in enumerate(END_REASONS)])


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


def action(value, action_space: spaces.Space | None, agent: str):
    """The Python value of an action as the extension takes it: an int for a Discrete
    space (a Python int, a numpy integer, or an integer array of one element), a flat
    list of floats for a Box (any sequence or array). Nothing is checked against the
    space here: the server checks every action, once, and the extension refuses what the
    wire cannot carry, in the server's words. ``action_space`` None (an agent the env
    does not have, which the server will name) takes either form."""
    if isinstance(action_space, spaces.Discrete) or (action_space is None and _integral(value)):
        if type(value) is int:
            return value
        if not _integral(value):
            raise InvalidActionError(
                "InvalidAction", f"agent {agent!r}: expected an int for {action_space}, got {value!r}"
            )
        return int(np.asarray(value).reshape(()))
    try:
        return np.asarray(value, dtype=np.float32).reshape(-1).tolist()
    except (TypeError, ValueError):
        kind = "numbers" if action_space is not None else "an int or numbers"
        raise InvalidActionError(
            "InvalidAction", f"agent {agent!r}: expected {kind} for {action_space or 'an action'}, got {value!r}"
        ) from None


def _integral(value) -> bool:
    """An int, or a numpy integer or integer array of one element (a bool is no int)."""
    if type(value) is int:
        return True
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):  # a ragged sequence is no int either
        return False
    return array.size == 1 and np.issubdtype(array.dtype, np.integer)
