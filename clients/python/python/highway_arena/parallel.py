"""A PettingZoo ParallelEnv whose world runs on an arena-server."""

from __future__ import annotations

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv as _ParallelEnv

from . import _convert
from ._connection import Connection, env_options, keywords, split, takes_connection_keywords, takes_env_options
from ._errors import ScenarioError, translated
from ._recordings import recording_meta

RENDER_MODES = ["human", "rgb_array", "ansi"]


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


# How an unknown keyword's error says scenario overrides are written.
OVERRIDE_FORMS = (
    "scenario overrides are written vehicle__ac__speed=18.0 (dots as double underscores) "
    'or overrides={"vehicle.ac.speed": 18.0}'
)


def refuse_unknown(signature: str, given, valid, overrides: bool = True) -> None:
    """Raises TypeError naming each of ``given`` that is not in ``valid`` and listing the
    valid keywords; with ``overrides``, a keyword with ``__`` is a scenario override and
    no unknown keyword."""
    unknown = sorted(key for key in given if key not in valid and not (overrides and "__" in key))
    if unknown:
        raise TypeError(
            f"{signature} got unexpected keyword argument(s) {unknown}; its keywords are {', '.join(valid)}"
            + (f"; {OVERRIDE_FORMS}" if overrides else "")
        )


def scenario_overrides(overrides, dotted: dict, signature: str, valid) -> dict:
    """``overrides=`` and the ``vehicle__ac__speed=`` keywords as one dict of dotted keys.
    A keyword without ``__`` is not an override: it is refused, naming it and the valid
    keywords, instead of reaching the scenario as an unknown key."""
    refuse_unknown(signature, dotted, valid)
    merged = dict(overrides or {})
    merged.update({key.replace("__", "."): value for key, value in dotted.items()})
    return merged


@takes_connection_keywords
@takes_env_options
class ParallelEnv(_ParallelEnv):
    """PettingZoo Parallel API over an env on a server. Arguments: ``scenario`` (a name
    the server knows, or the name of ``scenario_text``), ``connect`` (endpoint),
    ``render_mode`` ('rgb_array' or 'ansi'), ``render_follow`` (the name of the vehicle
    frames follow, any vehicle of the scenario, e.g. 'ac'; default the first learner; the
    attribute of the same name changes it later), ``seed`` (used by the first ``reset()``
    that is given none, for reproducible runs), ``record`` (a path: record every episode
    into that Rerun ``.rrd`` file from the start, as ``start_recording(path)`` does;
    docs/viewing.md), the env options and the connection keywords (both below), and
    scenario overrides as keyword arguments with dots written as double underscores
    (``vehicle__ac__speed=18.0``) or in ``overrides={"vehicle.ac.speed": 18.0}``. With
    ``policy`` ``step({})`` takes no actions; with ``explain`` the decisions of each step
    are in ``explanations`` and in the recording (docs/viewing.md, "The AV explained").
    Any other keyword raises TypeError naming it and the valid ones."""

    metadata = {"render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(
        self,
        scenario="merge",
        connect=None,
        render_mode=None,
        max_cycles=None,
        *,
        scenario_text=None,
        overrides=None,
        render_follow=None,
        seed=None,
        record=None,
        **kwargs,
    ):
        # Kept so a pickled env (SuperSuit's vector envs copy them) rebuilds its own.
        named = {key: value for key, value in locals().items() if key not in ("self", "__class__", "kwargs")}
        # A copy records nothing: copies writing one file would spoil it.
        self._init_args = {**{k: v for k, v in named.items() if k != "record"}, **kwargs}
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, not {render_mode!r}")
        connection, rest = split(kwargs, connect=connect)
        options = {**env_options(rest), "max_cycles": max_cycles}
        all_overrides = scenario_overrides(overrides, rest, "parallel_env()", KEYWORDS)
        self._connection = Connection(**connection)
        try:
            self._env = self._connection.create(
                scenario, scenario_text, all_overrides, record=record is not None, **options
            )
            specs = self._env.specs()
        except BaseException:
            self._connection.close()
            raise
        self._closed = False
        self._recording = None
        # The decisions the last step explained (``explain=True``): dicts as the extension's
        # ``take_explanations`` gives them.
        self.explanations = []
        self._scenario = scenario
        self._first_seed = seed
        self.render_mode = render_mode
        self.render_follow = render_follow
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
        if record is not None:
            try:
                self._recording = self._new_recording(record)
            except BaseException:
                self.close()
                raise

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
        self.explanations = []
        if self._recording is not None:
            start, _ = self._env.take_world()
            if start is not None:
                self._recording.begin_episode(start, seed=seed, infos=infos)
        return {a: _convert.observation(o) for a, o in observations.items()}, infos

    @translated
    def step(self, actions):
        # The server says whether the env has each agent and checks each action.
        wire = {agent: _convert.action(a, self.action_spaces.get(agent), agent) for agent, a in actions.items()}
        observations, rewards, terminations, truncations, infos, agents = self._env.step(wire)
        self.agents = list(agents)
        self.explanations = self._env.take_explanations()
        if self._recording is not None:
            _, frames = self._env.take_world()
            self._recording.add_step(frames, wire, rewards, terminations, truncations, infos)
            self._recording.add_explanations(self.explanations)
        observations = {a: _convert.observation(o) for a, o in observations.items()}
        return observations, rewards, terminations, truncations, infos

    @translated
    def snapshot(self) -> bytes:
        """The env's whole state as bytes: the world (every vehicle, every driver's memory,
        the RNG), the agents, their episodes' figures and the seed stream. ``restore`` it
        into this env or another of the same scenario and options, on any server of the
        same protocol version, to continue from here bit for bit (docs/protocol.md,
        "Snapshots")."""
        return bytes(self._env.snapshot())

    @translated
    def restore(self, snapshot):
        """Puts ``snapshot``'s state into this env, which then steps exactly as the env it
        was taken of would have; returns (observations, infos) of the agents live in it,
        as ``reset`` does. A snapshot of another scenario, options or protocol version,
        or a damaged one, raises ``SnapshotError`` and leaves the env as it was."""
        observations, infos = self._env.restore(bytes(snapshot))
        self.agents = [a for a in self.possible_agents if a in observations]
        if self._recording is not None:
            start, _ = self._env.take_world()
            if start is not None:
                self._recording.begin_episode(start, infos=infos)
        return {a: _convert.observation(o) for a, o in observations.items()}, infos

    @translated
    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'ansi'")
            return None
        if self.render_mode == "human":
            # The terminal is this env's screen: the ansi picture, redrawn in place.
            print("\x1b[2J\x1b[H" + self._env.render("ansi", self.render_follow)[1], flush=True)
            return None
        frame = self._env.render(self.render_mode, self.render_follow)
        if frame[0] == "ansi":
            return frame[1]
        _, height, width, data = frame
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3).copy()

    def _new_recording(self, path=None, **where):
        from .recording import Recording  # rerun-sdk is an optional extra

        # The road view follows the car the env's frames follow.
        meta = recording_meta(self._scenario, self.dt, self.possible_agents)
        return Recording(path, meta=meta, follow=self.render_follow, **where)

    @translated
    def start_recording(self, path=None, *, spawn=False, serve=False, web_port=9090, grpc_port=9876):
        """Records every episode from now on: every vehicle at every control period (the
        road, poses, speeds, lanes, drivers, collisions) and every agent's action, reward
        and infos at every step, with rerun-sdk (``pip install 'highway-arena[view]'``),
        into the ``.rrd`` file ``path``, a desktop viewer it starts (``spawn=True``), or a
        web viewer served on 127.0.0.1 (``serve=True``; its address is the returned
        recording's ``url``; it stays up until this process exits). Started mid-episode, it begins with the world as it is.
        Returns the ``Recording``; ``stop_recording()`` ends it."""
        if self._recording is not None:
            raise RuntimeError("this env is recording already: stop_recording() first")
        recording = self._new_recording(path, spawn=spawn, serve=serve, web_port=web_port, grpc_port=grpc_port)
        try:
            start = self._env.record(True)
        except BaseException:
            recording.close()
            raise
        self._recording = recording
        if start is not None:
            recording.begin_episode(start)
        return recording

    def stop_recording(self):
        """Ends the recording (the file is complete then) and tells the server to stop
        sending the world; returns the file's path (None for a viewer only)."""
        recording, self._recording = self._recording, None
        if recording is None:
            return None
        try:
            if not self._closed:
                translated(self._env.record)(False)
        finally:
            recording.close()
        return recording.path

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
        args.update(args.pop("dotted", {}))  # as pickled before the keywords were one list
        self.__init__(**args)

    def close(self):
        """Closes the env and its Zenoh session; calling it again does nothing."""
        if getattr(self, "_closed", True):
            return
        recording, self._recording = getattr(self, "_recording", None), None
        self._closed = True
        try:
            if recording is not None:
                recording.close()
            translated(self._env.close)()
        finally:
            self._connection.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


# Every keyword ParallelEnv (and parallel_env) takes by name, connection keywords included.
KEYWORDS = keywords(ParallelEnv.__init__)
