"""Many multi-agent envs of one scenario on one server, stepped in one round trip each
step (the server spreads a batch over its cores); each env's reset and step give what
a ParallelEnv's give. Finished envs reset themselves."""

from __future__ import annotations

from . import _convert
from ._errors import InvalidActionError, translate, translated
from . import _core
from .parallel import DEFAULT_CONNECT_TIMEOUT, DEFAULT_PREFIX, DEFAULT_RETRIES, DEFAULT_TIMEOUT, Connection, reset_options


class BatchEnv:
    """``num_envs`` copies of a scenario; env ``i`` is seeded ``seed + i`` and re-seeded
    from its own stream when its episode ends."""

    def __init__(
        self,
        scenario="highway",
        num_envs=8,
        connect=None,
        prefix=DEFAULT_PREFIX,
        timeout=DEFAULT_TIMEOUT,
        connect_timeout=DEFAULT_CONNECT_TIMEOUT,
        zenoh_config=None,
        mode=None,
        retries=DEFAULT_RETRIES,
        **options,
    ):
        if num_envs < 1:
            raise ValueError(f"num_envs must be at least 1, not {num_envs}")
        self._connection = Connection(connect, prefix, timeout, connect_timeout, zenoh_config, mode, retries)
        self._envs = []
        try:
            for server in self._connection.place(num_envs):
                self._envs.append(self._connection.create(scenario, server=server, **options))
            specs = self._envs[0].specs()
        except BaseException:
            self.close()
            raise
        self.possible_agents = list(specs["possible_agents"])
        self.dt = specs["dt"]
        self.action_spaces = {a: _convert.space(s) for a, s in specs["action_spaces"].items()}
        self.num_envs = num_envs

    @translated
    def reset(self, seed=0, options=None):
        """Resets every env (env ``i`` with ``seed + i``). Returns one (observations,
        infos) per env, as ``ParallelEnv.reset`` does."""
        wire = reset_options(options)
        out = []
        for i, env in enumerate(self._envs):
            observations, infos = env.reset(seed + i, wire)
            out.append(({a: _convert.observation(o) for a, o in observations.items()}, infos))
        return out

    @translated
    def step(self, actions):
        """``actions``: one dict per env. Returns one (observations, rewards,
        terminations, truncations, infos) per env; an env whose agents all finished is
        reset, and its tuple's observations are the new episode's first."""
        wire = []
        for per_env in actions:
            for agent in per_env:
                if agent not in self.action_spaces:
                    raise InvalidActionError(
                        "UnknownAgent", f"no agent named {agent!r}; the agents are {self.possible_agents}"
                    )
            wire.append({agent: _convert.action(a, self.action_spaces[agent], agent) for agent, a in per_env.items()})
        results = self._connection.client.step_batch(self._envs, wire)
        out = []
        for env, result in zip(self._envs, results):
            if isinstance(result, _core.ArenaError):
                raise translate(result)
            observations, rewards, terminations, truncations, infos, agents = result
            if not agents:
                observations, _ = env.reset(None, None)
            observations = {a: _convert.observation(o) for a, o in observations.items()}
            out.append((observations, rewards, terminations, truncations, infos))
        return out

    @property
    def servers(self):
        """The id of the server each env lives on, in env order (envs are spread over every
        server found, by load)."""
        return [env.server for env in self._envs]

    def close(self):
        for env in self._envs:
            translated(env.close)()
        self._envs = []
        self._connection.close()
