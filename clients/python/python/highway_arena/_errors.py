"""Exceptions raised by highway_arena, and the translation from the Rust client's."""

from __future__ import annotations

import functools
import re

from . import _core, _fork


class ArenaError(RuntimeError):
    """An error from highway-arena. ``code`` names what went wrong (a server error code
    such as ``InvalidAction``, or ``NoServer``, ``Timeout``, ``Zenoh``, ``Protocol``)."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code


class ServerNotFoundError(ArenaError, ConnectionError):
    """No arena-server answered at the address given."""


class ArenaTimeoutError(ArenaError, TimeoutError):
    """A request got no reply within the timeout."""


class InvalidActionError(ArenaError, ValueError):
    """An action the env refused: outside its space, of the wrong type, or for an agent
    that is not live."""


class ServerGoneError(ArenaError, ConnectionError):
    """The env's arena-server no longer answers (it stopped or restarted): the env is
    gone with it; create a new one."""


class InvalidEndpointError(ArenaError, ValueError):
    """``connect`` is not a Zenoh endpoint this client can use (write tcp/HOST:PORT)."""


class ScenarioError(ArenaError, ValueError):
    """A scenario the server does not have, or one that does not validate."""


class RequestTooLargeError(ArenaError, ValueError):
    """A request, or one of its strings or lists, is past its bound (docs/protocol.md, "Bounds")."""


class SnapshotError(ArenaError, ValueError):
    """A snapshot ``restore`` refused: not a snapshot, truncated or corrupted, or of
    another scenario, env options or protocol version (the message names which)."""


class ForkedProcessError(ArenaError):
    """This process was made by ``fork()`` from one that had opened a connection: Zenoh's
    runtime threads did not come along, so no connection can work here. Start worker
    processes with the ``spawn`` (or ``forkserver``) start method."""


class EnvClosedError(ArenaError):
    """The env was closed (by this client, by idling, or because the server forgot it)."""


_BY_CODE = {
    "InvalidEndpoint": InvalidEndpointError,
    "NoServer": ServerNotFoundError,
    "ServerGone": ServerGoneError,
    "ShuttingDown": ServerGoneError,
    "Timeout": ArenaTimeoutError,
    "InvalidAction": InvalidActionError,
    "WrongActionType": InvalidActionError,
    "UnknownAgent": InvalidActionError,
    "AgentNotLive": InvalidActionError,
    "InvalidOption": ScenarioError,
    "UnknownScenario": ScenarioError,
    "InvalidScenario": ScenarioError,
    "PayloadTooLarge": RequestTooLargeError,
    "EnvClosed": EnvClosedError,
    "UnknownEnv": EnvClosedError,
    "InvalidSnapshot": SnapshotError,
    "Forked": ForkedProcessError,
}

_HINTS = {
    "AgentNotLive": " (only agents in env.agents may act; reset when env.agents is empty)",
    "UnknownScenario": " (or pass scenario_text= with a scenario file's TOML)",
    "Forked": (
        ' (multiprocessing.get_context("spawn"); Gymnasium: AsyncVectorEnv(env_fns, context="spawn"); '
        'Stable-Baselines3: SubprocVecEnv(env_fns, start_method="spawn"))'
    ),
    "TooManyEnvs": " (close envs you no longer use, or start arena-server with a larger --max-envs or --max-envs-per-client)",
}

# Zenoh's messages end with where in its sources they were raised: noise to a user.
_SOURCE_LOCATION = re.compile(r" at /\S+?\.rs:\d+\.?")


def clean(message: str) -> str:
    """A Zenoh error message without source locations."""
    return _SOURCE_LOCATION.sub("", message)


def translate(error: _core.ArenaError) -> ArenaError:
    code, message = error.args
    return _BY_CODE.get(code, ArenaError)(code, clean(message) + _HINTS.get(code, ""))


def translated(function):
    """Raises our exception types instead of the extension's."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        try:
            return function(*args, **kwargs)
        except _fork.errors as error:
            raise translate(error) from None

    return wrapper
