"""A SuperSuit vector env over the PettingZoo env, stepping 1000 times."""

import numpy as np
import supersuit as ss

import highway_arena


def test_supersuit_vector_env_steps_1000_times():
    parallel = highway_arena.parallel_env("highway", max_cycles=40)
    vec = ss.pettingzoo_env_to_vec_env_v1(parallel)
    vec = ss.concat_vec_envs_v1(vec, 2, num_cpus=0, base_class="gymnasium")
    observations, _ = vec.reset(seed=0)
    assert observations.shape == (2, 35) and observations.dtype == np.float32
    episodes_ended = 0
    rng = np.random.default_rng(0)
    for _ in range(1000):
        actions = rng.integers(0, 5, size=vec.num_envs)
        observations, rewards, terminations, truncations, _ = vec.step(actions)
        assert observations.shape == (2, 35) and np.all(np.abs(observations) <= 1.0)
        assert np.all(np.isfinite(rewards))
        episodes_ended += int(np.sum(terminations | truncations))
    # 40-step episodes: each copy must have finished and restarted many times.
    assert episodes_ended >= 2 * 1000 // 40
    vec.close()
