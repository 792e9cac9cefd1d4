"""A Gymnasium Env for one learner; the scenario's other vehicles keep their drivers
(other learner vehicles are driven by IDM)."""

from __future__ import annotations

import gymnasium
from gymnasium.envs.registration import EnvSpec

from . import parallel
from ._connection import takes_connection_keywords, takes_env_options
from .parallel import ParallelEnv, refuse_unknown


@takes_connection_keywords
@takes_env_options
class GymEnv(gymnasium.Env):
    """One agent of a scenario as a ``gymnasium.Env``. Takes ParallelEnv's arguments
    (the env options and the connection keywords among them, below), plus ``agent``
    (default: the scenario's first learner); any other keyword raises TypeError naming it
    and the valid ones. With ``policy`` the server drives the learner and ``step`` ignores
    its action (pass None)."""

    # Read by gymnasium.make before an instance exists; instances add render_fps.
    metadata = {"render_modes": ["human", "rgb_array", "ansi"]}

    def __init__(self, scenario="highway", agent=None, render_mode=None, **kwargs):
        refuse_unknown("gym_env()", kwargs, KEYWORDS)
        # A spec lets gymnasium.make (and check_env's render checks) build siblings.
        self.spec = EnvSpec(
            id=f"highway_arena/{scenario}-v0",
            entry_point="highway_arena.single:GymEnv",
            kwargs={"scenario": scenario, "agent": agent, **kwargs},
        )
        overrides = dict(kwargs.pop("overrides", None) or {})
        probe = ParallelEnv(scenario, render_mode=render_mode, overrides=overrides, **kwargs)
        agents = probe.possible_agents
        chosen = agent if agent is not None else (agents[0] if agents else None)
        if chosen not in agents:
            probe.close()
            raise ValueError(f"scenario {scenario!r} has no learner named {chosen!r}; its learners are {agents}")
        others = [a for a in agents if a != chosen]
        if others:
            # The other learners' vehicles drive themselves, as background traffic does.
            probe.close()
            overrides.update({f"vehicle.{a}.driver": '{ kind = "idm" }' for a in others})
            probe = ParallelEnv(scenario, render_mode=render_mode, overrides=overrides, **kwargs)
        self._parallel = probe
        self._driven = kwargs.get("policy") is not None
        self.agent = chosen
        self.render_mode = render_mode
        self.observation_space = probe.observation_space(chosen)
        self.action_space = probe.action_space(chosen)
        self.metadata = dict(probe.metadata)
        self.dt = probe.dt

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        observations, infos = self._parallel.reset(seed=seed, options=options)
        return observations[self.agent], infos[self.agent]

    def step(self, action):
        # With ``policy`` the server drives the learner: its steps carry no action.
        actions = {} if self._driven else {self.agent: action}
        observations, rewards, terminations, truncations, infos = self._parallel.step(actions)
        return (
            observations[self.agent],
            float(rewards[self.agent]),
            bool(terminations[self.agent]),
            bool(truncations[self.agent]),
            infos[self.agent],
        )

    def render(self):
        return self._parallel.render()

    @property
    def render_follow(self):
        """The name of the vehicle frames follow (``ParallelEnv.render_follow``); None is
        the first learner. Set it to follow another."""
        return self._parallel.render_follow

    @render_follow.setter
    def render_follow(self, name):
        self._parallel.render_follow = name

    def snapshot(self) -> bytes:
        """``ParallelEnv.snapshot``: the env's whole state as bytes."""
        return self._parallel.snapshot()

    def restore(self, snapshot):
        """``ParallelEnv.restore``: (observation, info) of this agent, as ``reset`` gives
        them; an agent that had finished when the snapshot was taken raises
        ``InvalidActionError`` (reset instead)."""
        observations, infos = self._parallel.restore(snapshot)
        if self.agent not in observations:
            from ._errors import InvalidActionError

            raise InvalidActionError("AgentNotLive", f"agent {self.agent!r} had finished when the snapshot was taken")
        return observations[self.agent], infos[self.agent]

    def start_recording(self, path=None, **where):
        """``ParallelEnv.start_recording``: every vehicle, and this agent's actions,
        rewards and infos."""
        return self._parallel.start_recording(path, **where)

    def stop_recording(self):
        """``ParallelEnv.stop_recording``."""
        return self._parallel.stop_recording()

    def close(self):
        self._parallel.close()
        super().close()


# Every keyword GymEnv (and gym_env) takes by name: its own and ParallelEnv's.
KEYWORDS = ["scenario", "agent", "render_mode", *(k for k in parallel.KEYWORDS if k not in ("scenario", "render_mode"))]
