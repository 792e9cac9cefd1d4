"""A Gymnasium ``VectorEnv`` for training loops: ``num_envs`` copies of one learner's
view of a scenario on one server, all stepped in one round trip per step (the server
spreads the batch over its cores). Autoreset is Gymnasium 1.x's default, next-step (the
step after an episode ends resets that sub-env, returning its first observation with
reward 0 and no termination, and ignores its action), or same-step on request (the
ending step resets at once; the episode's last observation and info go into
``final_obs`` and ``final_info``), which is what Stable-Baselines3 expects (``sb3``)."""

from __future__ import annotations

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from . import _convert, _fork
from ._connection import Connection, env_options, keywords, split, takes_connection_keywords, takes_env_options
from ._errors import translate, translated
from ._recordings import EnvRecordings, recording_meta
from .parallel import reset_options, scenario_overrides


@takes_connection_keywords
@takes_env_options
class VectorEnv(gymnasium.vector.VectorEnv):
    """``num_envs`` copies of ``scenario`` for one learner (``agent``, default the first;
    other learners' vehicles are driven by IDM, as in ``gym_env``). Takes
    ``scenario_text``, scenario overrides (``overrides=`` or ``vehicle__ac__speed=18.0``),
    ``autoreset_mode``, ``record`` (a folder: record every sub-env from the start, as
    ``start_recording`` does), the env options and the connection keywords (both below);
    any other keyword raises TypeError naming it and the valid ones. ``reset(seed=s)``
    seeds sub-env ``i`` with ``s + i``; a list gives each its own seed."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        scenario="highway",
        num_envs=8,
        agent=None,
        connect=None,
        *,
        scenario_text=None,
        overrides=None,
        autoreset_mode=AutoresetMode.NEXT_STEP,
        record=None,
        **kwargs,
    ):
        connection, rest = split(kwargs, connect=connect)
        options = env_options(rest)
        overrides = scenario_overrides(overrides, rest, "vector_env()", KEYWORDS)
        autoreset_mode = AutoresetMode(autoreset_mode)
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, not {autoreset_mode}")
        self.metadata = {**self.metadata, "autoreset_mode": autoreset_mode}
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be at least 1, not {num_envs}")
        self.num_envs = int(num_envs)
        self._envs = []
        self._connection = Connection(**connection)
        try:
            # Spread over every server found, by load; each env stays where it lands.
            servers = self._connection.place(self.num_envs)
            probe = self._connection.create(scenario, scenario_text, overrides, server=servers[0], **options)
            learners = list(probe.specs()["possible_agents"])
            self.agent = agent if agent is not None else learners[0]
            if self.agent not in learners:
                translated(probe.close)()
                raise ValueError(f"scenario {scenario!r} has no learner named {self.agent!r}; its learners are {learners}")
            others = [a for a in learners if a != self.agent]
            if others:
                translated(probe.close)()
                overrides.update({f"vehicle.{a}.driver": '{ kind = "idm" }' for a in others})
                probe = self._connection.create(scenario, scenario_text, overrides, server=servers[0], **options)
            self._envs.append(probe)
            for server in servers[1:]:
                self._envs.append(self._connection.create(scenario, scenario_text, overrides, server=server, **options))
            specs = probe.specs()
        except BaseException:
            self.close()
            raise
        self.single_observation_space = _convert.space(specs["observation_spaces"][self.agent])
        self.single_action_space = _convert.space(specs["action_spaces"][self.agent])
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.dt = specs["dt"]
        self._observations = create_empty_array(self.single_observation_space, self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=np.bool_)
        self._meta = recording_meta(scenario, self.dt, [self.agent])
        self._recordings = None
        if record is not None:
            self.start_recording(record)

    def start_recording(self, folder):
        """Records every sub-env from now on, env ``i`` into ``<folder>/env-<i>.rrd`` (000,
        001, ...), each as ``ParallelEnv.start_recording`` records one (docs/viewing.md)."""
        if self._recordings is not None:
            raise RuntimeError("this vector env is recording already: stop_recording() first")
        self._recordings = EnvRecordings(self._envs, folder, self._meta)

    def stop_recording(self) -> list:
        """Ends the recordings (the files are complete then); returns their paths."""
        recordings, self._recordings = self._recordings, None
        return [] if recordings is None else recordings.close()

    @translated
    def snapshot(self, i) -> bytes:
        """Sub-env ``i``'s whole state as bytes (``ParallelEnv.snapshot``)."""
        return bytes(self._envs[self._index(i)].snapshot())

    @translated
    def restore(self, i, snapshot):
        """Puts ``snapshot`` into sub-env ``i`` (``ParallelEnv.restore``); returns its
        (observation, info). Its next ``step`` continues from there."""
        index = self._index(i)
        observations, infos = self._envs[index].restore(bytes(snapshot))
        self._autoreset[index] = False
        if self._recordings is not None:
            self._recordings.reset(index, None, infos)
        return _convert.observation(observations[self.agent]), infos[self.agent]

    def _index(self, i) -> int:
        if not 0 <= int(i) < self.num_envs:
            raise IndexError(f"env index {i} out of range: this vector env has {self.num_envs} envs")
        return int(i)

    def _seeds(self, seed):
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, int):
            return [seed + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"{len(seeds)} seeds for {self.num_envs} envs")
        return seeds

    @translated
    def reset(self, *, seed=None, options=None):
        seeds = self._seeds(seed)
        super().reset(seed=seed if isinstance(seed, int) else None)
        wire = reset_options(options)
        observations, infos = [], {}
        for i, (env, env_seed) in enumerate(zip(self._envs, seeds)):
            obs, info = env.reset(env_seed, wire)
            self._record_reset(i, env_seed, info)
            observations.append(_convert.observation(obs[self.agent]))
            infos = self._add_info(infos, info[self.agent], i)
        self._autoreset[:] = False
        return self._batch(observations), infos

    @translated
    def step(self, actions):
        actions = np.asarray(actions) if not isinstance(actions, dict) else actions
        stepping = [i for i in range(self.num_envs) if not self._autoreset[i]]
        wire = [{self.agent: _convert.action(actions[i], self.single_action_space, self.agent)} for i in stepping]
        results = self._connection.client.step_batch([self._envs[i] for i in stepping], wire) if stepping else []
        observations = [None] * self.num_envs
        rewards = np.zeros(self.num_envs, dtype=np.float64)
        terminations = np.zeros(self.num_envs, dtype=np.bool_)
        truncations = np.zeros(self.num_envs, dtype=np.bool_)
        infos = {}
        for i, sent, result in zip(stepping, wire, results):
            if isinstance(result, _fork.errors):
                raise translate(result)
            obs, reward, terminated, truncated, info, _agents = result
            if self._recordings is not None:
                self._recordings.step(i, sent, reward, terminated, truncated, info)
            observations[i] = _convert.observation(obs[self.agent])
            rewards[i] = reward[self.agent]
            terminations[i] = terminated[self.agent]
            truncations[i] = truncated[self.agent]
            if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP and (terminations[i] or truncations[i]):
                infos = self._add_info(infos, {"final_obs": observations[i], "final_info": info[self.agent]}, i)
                obs, info = self._envs[i].reset(None, {})
                self._record_reset(i, None, info)
                observations[i] = _convert.observation(obs[self.agent])
            infos = self._add_info(infos, info[self.agent], i)
        for i in range(self.num_envs):
            if self._autoreset[i]:
                obs, info = self._envs[i].reset(None, {})
                self._record_reset(i, None, info)
                observations[i] = _convert.observation(obs[self.agent])
                infos = self._add_info(infos, info[self.agent], i)
        if self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP:
            self._autoreset = terminations | truncations
        return self._batch(observations), rewards, terminations, truncations, infos

    def _record_reset(self, i, seed, infos):
        if self._recordings is not None:
            self._recordings.reset(i, seed, infos)

    def _batch(self, observations):
        return concatenate(self.single_observation_space, observations, self._observations).copy()

    @property
    def servers(self):
        """The id of the server each env lives on, in env order (envs are spread over every
        server found, by load)."""
        return [env.server for env in self._envs]

    def close_extras(self, **kwargs):
        recordings, self._recordings = getattr(self, "_recordings", None), None
        if recordings is not None:
            recordings.close(envs_open=False)
        for env in getattr(self, "_envs", []):
            translated(env.close)()
        self._envs = []
        if hasattr(self, "_connection"):
            self._connection.close()


# Every keyword VectorEnv (and vector_env) takes by name: its own, the env options and the
# connection keywords (its signature shows them all).
KEYWORDS = keywords(VectorEnv.__init__)
