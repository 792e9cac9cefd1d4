"""Train PPO (Stable-Baselines3) on highway.toml through SuperSuit, and print the mean
episode reward of the policy before and after training.

    pip install -r examples/requirements-ppo.txt     # stable-baselines3 and torch
    python examples/ppo_highway.py --timesteps 20000

Launches its own arena-server (or use --connect ENDPOINT for a running one).
"""

from __future__ import annotations

import argparse

import numpy as np
import supersuit as ss
from stable_baselines3 import PPO
from stable_baselines3.common.utils import set_random_seed

import highway_arena


def mean_episode_reward(model, connect: str, episodes: int) -> float:
    env = highway_arena.gym_env("highway", connect=connect)
    totals = []
    for episode in range(episodes):
        observation, _ = env.reset(seed=10_000 + episode)
        total, done = 0.0, False
        while not done:
            action, _ = model.predict(observation, deterministic=True)
            observation, reward, terminated, truncated, _ = env.step(int(action))
            total += reward
            done = terminated or truncated
        totals.append(total)
    env.close()
    return float(np.mean(totals))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--timesteps", type=int, default=20_000, help="PPO training steps (default 20000)")
    parser.add_argument("--envs", type=int, default=8, help="parallel envs for training (default 8)")
    parser.add_argument("--episodes", type=int, default=10, help="evaluation episodes (default 10)")
    args = parser.parse_args()

    def run(connect: str) -> None:
        parallel = highway_arena.parallel_env("highway", connect=connect)
        vec = ss.pettingzoo_env_to_vec_env_v1(parallel)
        vec = ss.concat_vec_envs_v1(vec, args.envs, num_cpus=0, base_class="stable_baselines3")
        # Rewards are minus the paper's cost J, which spans orders of magnitude. (SB3 warns
        # here that `render_mode` is not defined: SuperSuit's ConcatVecEnv has no get_attr.)
        from stable_baselines3.common.vec_env import VecNormalize

        vec = VecNormalize(vec, norm_obs=False, norm_reward=True)
        # SuperSuit's ConcatVecEnv has no seed(); seed torch and numpy, not the env.
        set_random_seed(0)
        model = PPO("MlpPolicy", vec, n_steps=256, batch_size=256, verbose=0)
        before = mean_episode_reward(model, connect, args.episodes)
        print(f"mean episode reward before training: {before:.1f}")
        model.learn(total_timesteps=args.timesteps, progress_bar=False)
        after = mean_episode_reward(model, connect, args.episodes)
        print(f"mean episode reward after {args.timesteps} steps: {after:.1f}")
        vec.close()

    if args.connect:
        run(args.connect)
    else:
        with highway_arena.launch_server() as server:
            run(server.endpoint)


if __name__ == "__main__":
    main()
