"""DAgger with the built-in game-theoretic AV as the expert and highway_arena.bc (numpy
only) as the learner: start from behaviour cloning on a recorded Minari dataset, then for
a few rounds drive with the current policy, label every state it visited with the
expert_action the env reports there, add those pairs to the data and refit. Prints, per
round, the failure rate (collision, off_road or lane_end) and mean return on fixed
evaluation episodes.

    pip install "highway-arena[datasets]"        # minari (the tests' venv has it)
    python examples/dagger.py --scenario merge-random --rounds 6     # about a minute

Launches its own arena-server (or use --connect ENDPOINT for a running one). The expert
dataset goes to a temporary directory unless --path says where.
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import time

import numpy as np

import highway_arena
import highway_arena.bc as bc
from highway_arena.datasets import rollout


def visit(env, policy, episodes: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Drives ``policy`` for ``episodes`` episodes; returns every observation it acted
    on and the expert_action reported for it (the info of the same step)."""
    observations, labels = [], []
    for i in range(episodes):
        observation, info = env.reset(seed=seed + i)
        while True:
            observations.append(observation)
            labels.append(info["expert_action"])
            observation, _, terminated, truncated, info = env.step(policy(observation))
            if terminated or truncated:
                break
    return np.array(observations), np.array(labels)


def report(name: str, result: dict, size: int, seconds: float) -> None:
    endings = dict(collections.Counter(result["end_reasons"]))
    print(
        f"{name:>8}: failure rate {result['failure_rate']:.2f}, mean return {result['mean_return']:7.1f}, "
        f"{size} labelled states, endings {endings} ({seconds:.1f} s)",
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--scenario", default="merge-random", help="scenario (default merge-random)")
    parser.add_argument("--expert-episodes", type=int, default=10, help="expert episodes recorded for round 0 (default 10)")
    parser.add_argument("--rounds", type=int, default=6, help="DAgger rounds after behaviour cloning (default 6)")
    parser.add_argument("--episodes", type=int, default=20, help="episodes driven by the policy per round (default 20)")
    parser.add_argument("--eval-episodes", type=int, default=20, help="evaluation episodes, seeds 10000.. (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the fits and of the first expert episode (default 0)")
    parser.add_argument("--path", help="Minari datasets directory for the expert data (default: a temporary one)")
    args = parser.parse_args()

    def run(connect: str, path: str) -> None:
        started = time.perf_counter()
        dataset = highway_arena.record(
            args.scenario, args.expert_episodes, expert="expert", seed=args.seed, path=path, connect=connect,
            dataset_id=f"dagger/{args.scenario}-v0",
        )
        observations, labels = bc.arrays(dataset)
        print(f"recorded {dataset.total_episodes} expert episodes ({dataset.total_steps} steps) in "
              f"{time.perf_counter() - started:.1f} s")
        # The learner's env, with the same expert (the learner's own style, Stackelberg).
        env = highway_arena.gym_env(args.scenario, connect=connect, expert="stackelberg")
        policy = bc.fit((observations, labels), seed=args.seed, action_space=env.action_space)
        started = time.perf_counter()
        report("BC", rollout(env, policy, args.eval_episodes, seed=10_000), len(labels), time.perf_counter() - started)
        for k in range(1, args.rounds + 1):
            started = time.perf_counter()
            # Fresh episodes each round (seeds 1000 * k ..), labelled by the expert.
            visited, relabelled = visit(env, policy, args.episodes, seed=1000 * k)
            observations = np.concatenate([observations, visited])
            labels = np.concatenate([labels, relabelled])
            policy = bc.fit((observations, labels), seed=args.seed, action_space=env.action_space)
            result = rollout(env, policy, args.eval_episodes, seed=10_000)
            report(f"round {k}", result, len(labels), time.perf_counter() - started)
        started = time.perf_counter()
        env.close()
        # The AV the labels came from, driving in the server on the same seeds.
        expert = highway_arena.gym_env(args.scenario, connect=connect, policy="expert")
        report("expert", rollout(expert, None, args.eval_episodes, seed=10_000), len(labels), time.perf_counter() - started)
        expert.close()

    with tempfile.TemporaryDirectory() as scratch:
        path = args.path or scratch
        with highway_arena.serving(args.connect) as connect:
            run(connect, path)


if __name__ == "__main__":
    main()
