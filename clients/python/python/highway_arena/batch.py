"""Many multi-agent envs of one scenario on one server, stepped in one round trip each
step (the server spreads a batch over its cores); each env's reset and step give what
a ParallelEnv's give. Finished envs reset themselves."""

from __future__ import annotations

from . import _convert, _fork
from ._connection import Connection, env_options, keywords, split, takes_connection_keywords, takes_env_options
from ._errors import translate, translated
from ._recordings import EnvRecordings, recording_meta
from .parallel import reset_options, scenario_overrides


@takes_connection_keywords
@takes_env_options
class BatchEnv:
    """``num_envs`` copies of a scenario; env ``i`` is seeded ``seed + i`` and re-seeded
    from its own stream when its episode ends. Takes ``scenario_text``, scenario overrides
    (``overrides={"vehicle.ac.speed": 18.0}`` or ``vehicle__ac__speed=18.0``), ``record``
    (a folder: record every env from the start, as ``start_recording`` does), the env
    options and the connection keywords (both below); any other keyword raises TypeError
    naming it and the valid ones."""

    def __init__(
        self, scenario="highway", num_envs=8, connect=None, *, scenario_text=None, overrides=None, record=None, **kwargs
    ):
        connection, rest = split(kwargs, connect=connect)
        options = env_options(rest)
        overrides = scenario_overrides(overrides, rest, "batch_env()", KEYWORDS)
        if num_envs < 1:
            raise ValueError(f"num_envs must be at least 1, not {num_envs}")
        self._envs = []
        self._connection = Connection(**connection)
        try:
            for server in self._connection.place(num_envs):
                self._envs.append(self._connection.create(scenario, scenario_text, overrides, server=server, **options))
            specs = self._envs[0].specs()
        except BaseException:
            self.close()
            raise
        self.possible_agents = list(specs["possible_agents"])
        self.dt = specs["dt"]
        self.action_spaces = {a: _convert.space(s) for a, s in specs["action_spaces"].items()}
        self.num_envs = num_envs
        self._scenario = scenario
        self._recordings = None
        if record is not None:
            self.start_recording(record)

    @translated
    def reset(self, seed=0, options=None):
        """Resets every env (env ``i`` with ``seed + i``). Returns one (observations,
        infos) per env, as ``ParallelEnv.reset`` does."""
        wire = reset_options(options)
        out = []
        for i, env in enumerate(self._envs):
            observations, infos = env.reset(seed + i, wire)
            if self._recordings is not None:
                self._recordings.reset(i, seed + i, infos)
            out.append(({a: _convert.observation(o) for a, o in observations.items()}, infos))
        return out

    @translated
    def step(self, actions):
        """``actions``: one dict per env. Returns one (observations, rewards,
        terminations, truncations, infos) per env; an env whose agents all finished is
        reset, and its tuple's observations are the new episode's first."""
        # The server says whether the env has each agent and checks each action.
        wire = [
            {agent: _convert.action(a, self.action_spaces.get(agent), agent) for agent, a in per_env.items()}
            for per_env in actions
        ]
        results = self._connection.client.step_batch(self._envs, wire)
        out = []
        for i, (env, result) in enumerate(zip(self._envs, results)):
            if isinstance(result, _fork.errors):
                raise translate(result)
            observations, rewards, terminations, truncations, infos, agents = result
            if self._recordings is not None:
                self._recordings.step(i, wire[i], rewards, terminations, truncations, infos)
            if not agents:
                observations, first_infos = env.reset(None, None)
                if self._recordings is not None:
                    self._recordings.reset(i, None, first_infos)
            observations = {a: _convert.observation(o) for a, o in observations.items()}
            out.append((observations, rewards, terminations, truncations, infos))
        return out

    @translated
    def snapshot(self, i) -> bytes:
        """Env ``i``'s whole state as bytes (``ParallelEnv.snapshot``)."""
        return bytes(self._envs[self._index(i)].snapshot())

    @translated
    def restore(self, i, snapshot):
        """Puts ``snapshot`` into env ``i`` (``ParallelEnv.restore``); returns its
        (observations, infos)."""
        index = self._index(i)
        observations, infos = self._envs[index].restore(bytes(snapshot))
        if self._recordings is not None:
            self._recordings.reset(index, None, infos)
        return {a: _convert.observation(o) for a, o in observations.items()}, infos

    def _index(self, i) -> int:
        if not 0 <= int(i) < len(self._envs):
            raise IndexError(f"env index {i} out of range: this batch has {len(self._envs)} envs")
        return int(i)

    def start_recording(self, folder):
        """Records every env from now on, env ``i`` into ``<folder>/env-<i>.rrd`` (000, 001,
        ...), each as ``ParallelEnv.start_recording`` records one (docs/viewing.md)."""
        if self._recordings is not None:
            raise RuntimeError("this batch is recording already: stop_recording() first")
        meta = recording_meta(self._scenario, self.dt, self.possible_agents)
        self._recordings = EnvRecordings(self._envs, folder, meta)

    def stop_recording(self) -> list:
        """Ends the recordings (the files are complete then); returns their paths."""
        recordings, self._recordings = self._recordings, None
        return [] if recordings is None else recordings.close()

    @property
    def servers(self):
        """The id of the server each env lives on, in env order (envs are spread over every
        server found, by load)."""
        return [env.server for env in self._envs]

    def close(self):
        recordings, self._recordings = getattr(self, "_recordings", None), None
        if recordings is not None:
            recordings.close(envs_open=False)
        for env in self._envs:
            translated(env.close)()
        self._envs = []
        if hasattr(self, "_connection"):
            self._connection.close()


# Every keyword BatchEnv (and batch_env) takes by name: its own, the env options and the
# connection keywords (its signature shows them all).
KEYWORDS = keywords(BatchEnv.__init__)
