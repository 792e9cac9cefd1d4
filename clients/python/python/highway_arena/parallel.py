"""A PettingZoo ParallelEnv whose world runs on an arena-server."""

from __future__ import annotations

import os
import re

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv as _ParallelEnv

from . import _convert, _core
from ._errors import (
    InvalidActionError,
    InvalidEndpointError,
    ScenarioError,
    ServerNotFoundError,
    clean,
    translate,
    translated,
)

# Connection defaults are defined once, in the Rust protocol crate.
DEFAULT_CONNECT = _core.DEFAULT_CONNECT
DEFAULT_PREFIX = _core.DEFAULT_PREFIX
DEFAULT_TIMEOUT = _core.DEFAULT_TIMEOUT
DEFAULT_CONNECT_TIMEOUT = _core.DEFAULT_CONNECT_TIMEOUT
RENDER_MODES = ["human", "rgb_array", "ansi"]


def default_connect() -> str:
    """$HIGHWAY_ARENA_CONNECT, else tcp/127.0.0.1:7447 (arena-server's default)."""
    return os.environ.get("HIGHWAY_ARENA_CONNECT", DEFAULT_CONNECT)


# A Zenoh endpoint: <protocol>/<address>[?<metadata>][#<config>].
_ENDPOINT = re.compile(r"^[A-Za-z][A-Za-z0-9_+-]*/\S+$")
# Resends of a request that got no reply, by default (a step keeps its sequence number, so
# the server never steps twice): the Rust client's and the CLI's default too.
DEFAULT_RETRIES = 2


def _endpoints(connect) -> list[str]:
    if connect is None:
        connect = default_connect()
    endpoints = [connect] if isinstance(connect, str) else list(connect)
    if not endpoints:
        raise InvalidEndpointError("InvalidEndpoint", "connect= names no endpoint; write e.g. tcp/127.0.0.1:7447")
    for endpoint in endpoints:
        if not isinstance(endpoint, str) or not _ENDPOINT.match(endpoint):
            raise InvalidEndpointError(
                "InvalidEndpoint",
                f"connect={endpoint!r} is not a Zenoh endpoint; write PROTOCOL/HOST:PORT, "
                f"e.g. {DEFAULT_CONNECT} (where arena-server listens by default)",
            )
    return endpoints


# pettingzoo.test's api_test and parallel_api_test reset with exactly this to check that
# reset takes the keyword (PettingZoo's own envs ignore keys they do not know). This env
# refuses unknown keys, since a misspelt one would otherwise silently do nothing; that one
# probe is accepted and ignored so PettingZoo's conformance suite runs as written.
_PETTINGZOO_SIGNATURE_PROBE = {"options": 1}


def reset_options(options) -> dict:
    """The overrides of ``reset(options=...)``, ``{"overrides": {key: value}}``; any other
    key is refused, naming it."""
    if options is None or options == _PETTINGZOO_SIGNATURE_PROBE:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict such as {{'overrides': {{...}}}}, not {type(options).__name__}")
    unknown = sorted(set(options) - {"overrides"})
    if unknown:
        raise ScenarioError(
            "InvalidOption",
            f"unknown reset option(s) {unknown}: the reset options are "
            "{'overrides': {'vehicle.ac.speed': 18.0, ...}} (dotted scenario keys, for this episode)",
        )
    overrides = options.get("overrides") or {}
    if not isinstance(overrides, dict):
        raise TypeError("options['overrides'] must be a dict of dotted scenario keys to values")
    return {str(key): value for key, value in overrides.items()}



def scenario_overrides(overrides, dotted: dict, signature: str, valid) -> dict:
    """``overrides=`` and the ``vehicle__ac__speed=`` keywords as one dict of dotted keys.
    A keyword without ``__`` is not an override: it is refused, naming it and the valid
    keywords, instead of reaching the scenario as an unknown key."""
    unknown = sorted(key for key in dotted if "__" not in key)
    if unknown:
        raise TypeError(
            f"{signature} got unexpected keyword argument(s) {unknown}; its keywords are "
            f"{', '.join(valid)}; scenario overrides are written vehicle__ac__speed=18.0 "
            '(dots as double underscores) or overrides={"vehicle.ac.speed": 18.0}'
        )
    merged = dict(overrides or {})
    merged.update({key.replace("__", "."): value for key, value in dotted.items()})
    return merged


class Connection:
    """One Zenoh session and the server picked on it. ``timeout`` is the seconds each
    attempt of a call waits for its reply and ``retries`` how often a call that got none
    is resent (steps keep their sequence number, so none runs twice), as in the Rust
    client and the CLI; ``zenoh_config`` is a Zenoh JSON5 file (user and password, TLS)
    for a deployment with access control."""

    def __init__(
        self,
        connect=None,
        prefix=DEFAULT_PREFIX,
        timeout=DEFAULT_TIMEOUT,
        connect_timeout=DEFAULT_CONNECT_TIMEOUT,
        zenoh_config=None,
        mode=None,
        retries=DEFAULT_RETRIES,
    ):
        endpoints = _endpoints(connect)
        timeout, connect_timeout = float(timeout), float(connect_timeout)
        if not timeout > 0 or timeout == float("inf"):
            raise ValueError(f"timeout must be a positive number of seconds, not {timeout}")
        if not connect_timeout > 0 or connect_timeout == float("inf"):
            raise ValueError(f"connect_timeout must be a positive number of seconds, not {connect_timeout}")
        if isinstance(retries, bool) or not isinstance(retries, int) or not 0 <= retries <= 100:
            raise ValueError(f"retries must be a whole number of resends from 0 to 100, not {retries!r}")
        where = ", ".join(endpoints)
        try:
            self.client = _core.Client(
                endpoints,
                prefix=prefix,
                timeout=timeout,
                retries=retries,
                zenoh_config=None if zenoh_config is None else str(zenoh_config),
                mode=mode,
            )
        except _core.ArenaError as error:
            code, message = error.args
            if "Unable to connect" in message:
                # A Zenoh client session needs its router at once; a peer does not.
                raise ServerNotFoundError(
                    "NoServer",
                    f"nothing at {where} accepted a Zenoh session: is the router running and listening "
                    "there, and does it ask for credentials (pass zenoh_config= a file with your user "
                    "and password, see docs/deployment.md)?",
                ) from None
            raise InvalidEndpointError(
                "InvalidEndpoint",
                f"cannot open a Zenoh session to {where}: {clean(message)}; "
                f"write the endpoint as PROTOCOL/HOST:PORT, e.g. {DEFAULT_CONNECT}",
            ) from None
        try:
            self.client.pick_server(wait=min(connect_timeout, timeout))
            # Of every server found, the least loaded (see ``place``).
            self.server = self.client.place(1)[0]
        except _core.ArenaError as error:
            self.client.close()
            code, message = error.args
            if code != "NoServer":
                raise translate(error) from None
            raise ServerNotFoundError(
                code,
                f"no arena-server answered at {where} (prefix {prefix!r}): is one running and listening there? "
                f"Start one with `arena-server --listen {endpoints[0]}` on that machine, pass connect= the "
                "endpoint yours listens on, or use highway_arena.launch_server() to start a local one",
            ) from None

    @translated
    def place(self, count):
        """Servers for ``count`` new envs, spread over every server found by load (fewest
        envs per core first): a vector env's envs land on all the servers of a site."""
        return self.client.place(count)

    @translated
    def create(self, scenario, scenario_text=None, overrides=None, server=None, **options):
        """An env on ``server`` (default: the one picked at connection)."""
        pairs = [(str(k), v) for k, v in (overrides or {}).items()]
        return self.client.create_env(server or self.server, scenario, scenario_text, pairs, **options)

    @translated
    def close(self):
        self.client.close()


class ParallelEnv(_ParallelEnv):
    """PettingZoo Parallel API over an env on a server. Arguments: ``scenario`` (a name
    the server knows, or the name of ``scenario_text``), ``connect`` (endpoint),
    ``render_mode`` ('rgb_array' or 'ansi'), ``max_cycles``, ``action_type`` ('meta' or
    'continuous'), ``observation`` ('kinematics' or 'kinematics_with_mask'), ``expert``
    ('nash' or 'stackelberg': infos say what the built-in AV would do), ``policy`` (a
    built-in driver the server drives every learner with, as ``arena eval`` does:
    'gt:<style>:<game>', 'expert' or 'idm'; then ``step({})`` takes no actions),
    ``diagnostics`` (True: infos carry every game-theoretic car's solver counts,
    ``gt.<car>.plans``, ``.qp_iterations``, ``.qp_iterations_total``, ``.fallbacks``,
    ``.inexact``), ``seed`` (used by
    the first ``reset()`` that is given none, for reproducible runs), ``timeout`` (the
    seconds each attempt of a call waits for the server's reply; default 10), ``retries``
    (resends of a call that got no reply; default 2),
    ``connect_timeout`` (the seconds to wait for a server to appear; default 1),
    ``zenoh_config`` (a Zenoh JSON5 file: credentials and TLS for a deployment with access
    control, see docs/deployment.md), ``mode`` (the Zenoh session mode: 'client' through a
    router; default 'peer', or the config file's), and scenario overrides as keyword arguments with dots written as double underscores
    (``vehicle__ac__speed=18.0``) or in ``overrides={"vehicle.ac.speed": 18.0}``."""

    metadata = {"render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(
        self,
        scenario="merge",
        connect=None,
        render_mode=None,
        max_cycles=None,
        action_type=None,
        observation=None,
        expert=None,
        policy=None,
        diagnostics=False,
        scenario_text=None,
        overrides=None,
        prefix=DEFAULT_PREFIX,
        timeout=DEFAULT_TIMEOUT,
        connect_timeout=DEFAULT_CONNECT_TIMEOUT,
        zenoh_config=None,
        mode=None,
        render_size=None,
        seed=None,
        retries=DEFAULT_RETRIES,
        **dotted,
    ):
        # Kept so a pickled env (SuperSuit's vector envs copy them) rebuilds its own.
        self._init_args = {key: value for key, value in locals().items() if key not in ("self", "__class__")}
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, not {render_mode!r}")
        valid = [key for key in self._init_args if key != "dotted"]
        all_overrides = scenario_overrides(overrides, dotted, "parallel_env()", valid)
        self._connection = Connection(connect, prefix, timeout, connect_timeout, zenoh_config, mode, retries)
        try:
            self._env = self._connection.create(
                scenario,
                scenario_text,
                all_overrides,
                action_type=action_type,
                observation=observation,
                max_cycles=max_cycles,
                render_size=render_size,
                expert=expert,
                policy=policy,
                diagnostics=bool(diagnostics),
            )
            specs = self._env.specs()
        except BaseException:
            self._connection.close()
            raise
        self._closed = False
        self._first_seed = seed
        self.render_mode = render_mode
        self.possible_agents = list(specs["possible_agents"])
        self.agents = []
        self.dt = specs["dt"]
        self.max_cycles = specs["max_cycles"]
        self.metadata = {
            "render_modes": list(RENDER_MODES),
            "name": f"highway_arena_{scenario}",
            "is_parallelizable": True,
            "render_fps": specs["render_fps"],
        }
        self.observation_spaces = {a: _convert.space(s) for a, s in specs["observation_spaces"].items()}
        self.action_spaces = {a: _convert.space(s) for a, s in specs["action_spaces"].items()}
        self.state_space = _convert.space(specs["state_space"])

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @translated
    def reset(self, seed=None, options=None):
        """Starts an episode. ``options``: ``{"overrides": {"vehicle.ac.speed": 18.0}}``
        sets scenario keys for this episode only (dotted, as in ``overrides=`` at
        creation); any other key raises ``ScenarioError`` naming it."""
        if seed is None:
            seed, self._first_seed = self._first_seed, None
        if seed is not None and not 0 <= int(seed) < 2**64:
            raise ValueError(f"seed must be in [0, 2**64), not {seed}")
        observations, infos = self._env.reset(None if seed is None else int(seed), reset_options(options))
        self.agents = [a for a in self.possible_agents if a in observations]
        return {a: _convert.observation(o) for a, o in observations.items()}, infos

    @translated
    def step(self, actions):
        wire = {}
        for agent, action in actions.items():
            if agent not in self.action_spaces:
                raise InvalidActionError(
                    "UnknownAgent", f"no agent named {agent!r}; the agents are {self.possible_agents}"
                )
            wire[agent] = _convert.action(action, self.action_spaces[agent], agent)
        observations, rewards, terminations, truncations, infos, agents = self._env.step(wire)
        self.agents = list(agents)
        observations = {a: _convert.observation(o) for a, o in observations.items()}
        return observations, rewards, terminations, truncations, infos

    @translated
    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'ansi'")
            return None
        if self.render_mode == "human":
            # The terminal is this env's screen: the ansi picture, redrawn in place.
            print("\x1b[2J\x1b[H" + self._env.render("ansi")[1], flush=True)
            return None
        frame = self._env.render(self.render_mode)
        if frame[0] == "ansi":
            return frame[1]
        _, height, width, data = frame
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3).copy()

    @property
    def server(self):
        """The id of the server this env lives on (placement picks the least loaded)."""
        return self._connection.server

    @translated
    def state(self):
        return _convert.observation(self._env.state())

    def __getstate__(self):
        return self._init_args

    def __setstate__(self, args):
        args = dict(args)
        dotted = args.pop("dotted", {})
        self.__init__(**args, **dotted)

    def close(self):
        """Closes the env and its Zenoh session; calling it again does nothing."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        try:
            translated(self._env.close)()
        finally:
            self._connection.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass
