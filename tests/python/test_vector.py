"""The vector env against Gymnasium's own SyncVectorEnv over the same single-agent envs:
the same seeds and actions give the same observations, rewards, terminations,
truncations and infos, autoreset included (Gymnasium's data_equivalence); and it steps
1000 times in one round trip per step."""

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode

import highway_arena


@pytest.mark.parametrize(
    "action_type, mode",
    [
        ("meta", AutoresetMode.NEXT_STEP),
        ("continuous", AutoresetMode.NEXT_STEP),
        ("meta", AutoresetMode.SAME_STEP),
    ],
)
def test_the_vector_env_matches_gymnasiums_sync_vector_env_step_for_step(action_type, mode):
    n = 3
    # Short episodes so several sub-envs autoreset within the run.
    ours = highway_arena.vector_env("merge", num_envs=n, action_type=action_type, max_cycles=7, autoreset_mode=mode)
    reference = gymnasium.vector.SyncVectorEnv(
        [lambda: highway_arena.gym_env("merge", action_type=action_type, max_cycles=7) for _ in range(n)],
        autoreset_mode=mode,
    )
    assert ours.metadata["autoreset_mode"] == mode
    assert ours.single_observation_space == reference.single_observation_space
    assert ours.single_action_space == reference.single_action_space
    assert ours.observation_space == reference.observation_space and ours.action_space == reference.action_space
    assert data_equivalence(ours.reset(seed=11), reference.reset(seed=11), exact=True)
    ours.action_space.seed(5)
    ended = 0
    for _ in range(20):
        actions = ours.action_space.sample()
        a, b = ours.step(actions), reference.step(actions)
        assert data_equivalence(a, b, exact=True), (a, b)
        assert ours.observation_space.contains(a[0])
        ended += int(np.sum(a[2] | a[3]))
    assert ended >= n, "every sub-env finished at least one episode"
    ours.close()
    reference.close()


def test_the_vector_env_steps_a_thousand_times_and_seeds_each_sub_env():
    envs = highway_arena.vector_env("highway", num_envs=4)
    observations, _ = envs.reset(seed=[1, 2, 3, 1])
    assert np.array_equal(observations[0], observations[3]) and not np.array_equal(observations[0], observations[1])
    envs.action_space.seed(0)
    for _ in range(1000):
        observations, rewards, terminations, truncations, infos = envs.step(envs.action_space.sample())
        assert observations.shape == (4, 35) and rewards.shape == (4,)
        # A step earns at most 1 and loses at most the risk weight (10); a crash on
        # highway's 40 steps costs -(1 + 10) x 40 (docs/rewards.md).
        assert np.all((rewards <= 1.0) & ((rewards >= -10.0) | (rewards == -440.0))), rewards
    envs.close()
    envs.close()
