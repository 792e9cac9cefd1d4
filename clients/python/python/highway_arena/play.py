"""``highway_arena.play``: watch any policy drive, the Python twin of ``arena play`` for
trained policies. A policy is a built-in name ('gt:<style>:<game>', 'expert', 'idm':
driven in the server; 'idle', 'random': here), a callable observation -> action, or a
model with ``predict`` (Stable-Baselines3), as ``evaluate`` takes them. The episodes go to
a Rerun recording (``record=PATH``), a desktop viewer (``spawn=True``), a web viewer
(``serve=True``), or, with none of those, only the returns come back.

    import highway_arena
    from stable_baselines3 import PPO
    highway_arena.play(PPO.load("ppo.zip"), "merge-random", episodes=3, record="ppo.rrd")
    # then: python -m highway_arena.view ppo.rrd
"""

from __future__ import annotations

from .evaluation import CLIENT_POLICIES, _actions, _seeded_spaces
from .parallel import ParallelEnv


def play(
    policy,
    scenario="merge",
    episodes=1,
    seed=0,
    connect=None,
    record=None,
    spawn=False,
    serve=False,
    max_cycles=None,
    **env_kwargs,
) -> list:
    """Drives every learner of ``scenario`` with ``policy`` for ``episodes`` episodes
    (episode i reset with seed ``seed + i``), recording them as asked; returns each
    episode's return per agent, ``[{agent: return}]``. Other keyword arguments go to the
    env (``explain=True`` adds the AV's decisions to the recording, ``action_type``,
    ``overrides``, ...)."""
    episodes = int(episodes)
    if episodes < 1:
        raise ValueError(f"episodes must be at least 1, not {episodes}")
    built_in = isinstance(policy, str) and policy not in CLIENT_POLICIES
    if not (built_in or policy in CLIENT_POLICIES or callable(policy) or hasattr(policy, "predict")):
        raise TypeError(f"policy must be a built-in name, a callable or a model with predict(), not {policy!r}")
    env = ParallelEnv(scenario, connect=connect, max_cycles=max_cycles, policy=policy if built_in else None, **env_kwargs)
    returns = []
    try:
        if record is not None or spawn or serve:
            env.start_recording(record, spawn=spawn, serve=serve)
        for i in range(episodes):
            observations, _ = env.reset(seed=int(seed) + i)
            spaces = _seeded_spaces(env, int(seed) + i)
            total = {agent: 0.0 for agent in env.possible_agents}
            while env.agents:
                actions = _actions(policy, built_in, spaces, env.agents, observations)
                observations, rewards, _, _, _ = env.step(actions)
                for agent, reward in rewards.items():
                    total[agent] += float(reward)
            returns.append(total)
    finally:
        env.close()
    return returns
