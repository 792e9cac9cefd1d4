"""What a saved PPO policy (examples/ppo_highway.py --save) would do along its own
most-likely-action episodes: per held-out episode (seeds 10 000 on), the largest
probability it gave `lane_left` while still in the ending lane, and the chance that
sampling would have changed lanes by then (1 - the product of 1 - p(lane_left) over
those steps). A policy can give lane_left a small share at every step, small enough
never to be its most likely action, yet large enough that a sampled episode of many
steps almost surely takes it: then sampling merges and the argmax never does
(docs/scenarios.md, "Decision rate").

    python examples/action_probabilities.py MODEL.zip --scenario merge-random --episodes 20
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from ppo_highway import HELD_OUT_SEED
from stable_baselines3 import PPO

import highway_arena

LANE_LEFT = 0
# Column of the lateral position d (normalised) in the agent's own row of the observation.
D_COLUMN = 2


def probabilities(model, observation) -> np.ndarray:
    tensor, _ = model.policy.obs_to_tensor(observation)
    with torch.no_grad():
        return model.policy.get_distribution(tensor).distribution.probs.cpu().numpy()[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", help="a PPO .zip of examples/ppo_highway.py")
    parser.add_argument("--scenario", default="merge-random")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model = PPO.load(args.model, device="cpu")
    largest, merge_chance, steps = [], [], []
    with highway_arena.serving(args.connect) as connect:
        env = highway_arena.gym_env(args.scenario, connect=connect)
        for i in range(args.episodes):
            observation, _ = env.reset(seed=HELD_OUT_SEED + i)
            start_d, p_left = observation[D_COLUMN], []
            while True:
                if abs(observation[D_COLUMN] - start_d) < 0.25:
                    p_left.append(float(probabilities(model, observation)[LANE_LEFT]))
                action, _ = model.predict(observation, deterministic=True)
                observation, _, terminated, truncated, _ = env.step(int(action))
                if terminated or truncated:
                    break
            largest.append(max(p_left))
            merge_chance.append(1.0 - float(np.prod(1.0 - np.array(p_left))))
            steps.append(len(p_left))
        env.close()
    print(
        f"{args.scenario}, {args.episodes} episodes by the most likely action: steps in the starting lane "
        f"{np.mean(steps):.1f} (mean); largest p(lane_left) there {np.median(largest):.3f} (median), "
        f"{np.max(largest):.3f} (max); chance a sampled policy would have changed lanes by then "
        f"{np.median(merge_chance):.3f} (median)"
    )


if __name__ == "__main__":
    main()
