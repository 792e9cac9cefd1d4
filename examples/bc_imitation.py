"""Behaviour cloning with the `imitation` library (torch) on a Minari dataset that
highway_arena.record wrote, evaluated against the numpy BC of highway_arena.bc and the
expert on the same episodes.

    pip install -r examples/requirements-imitation.txt     # torch, stable-baselines3, minari
    pip install --no-deps imitation==1.0.1                 # see the requirements file for why
    python examples/bc_imitation.py --scenario merge-random --episodes 30

Records the dataset first (into --path, default a temporary directory), or loads
--dataset-id from $MINARI_DATASETS_PATH when given. Launches its own arena-server (or use
--connect ENDPOINT). The expert changes lane in about one step of 200 and imitation's BC
has no class weights, so --oversample repeats the transitions whose expert action is
not the most common one (without it, 50 epochs never merge: 27 of 30 episodes run out
of lane).
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import time

import minari
import numpy as np
import torch
from imitation.algorithms import bc as imitation_bc
from imitation.data import rollout as imitation_rollout
from imitation.data import types
from imitation.util import logger as imitation_logger

import highway_arena
import highway_arena.bc
from highway_arena.datasets import rollout


def transitions(dataset, oversample: int):
    """The dataset's episodes as imitation's Trajectory objects, flattened to transitions;
    with ``oversample`` > 1, every transition whose action is not the most common one is
    repeated that many times."""
    trajectories = [
        types.Trajectory(obs=e.observations, acts=e.actions, infos=None, terminal=bool(e.terminations[-1]))
        for e in dataset.iterate_episodes()
    ]
    flat = imitation_rollout.flatten_trajectories(trajectories)
    if oversample > 1 and np.issubdtype(flat.acts.dtype, np.integer):
        common = np.bincount(flat.acts).argmax()
        index = np.concatenate([np.arange(len(flat))] + [np.flatnonzero(flat.acts != common)] * (oversample - 1))
        flat = types.Transitions(
            obs=flat.obs[index], acts=flat.acts[index], infos=flat.infos[index],
            next_obs=flat.next_obs[index], dones=flat.dones[index],
        )
    return flat


def summary(name: str, result: dict) -> None:
    endings = dict(collections.Counter(result["end_reasons"]))
    print(f"{name:>16}: failure rate {result['failure_rate']:.2f}, mean return {result['mean_return']:7.1f}, {endings}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--scenario", default="merge-random", help="scenario to record (default merge-random)")
    parser.add_argument("--episodes", type=int, default=30, help="expert episodes to record (default 30)")
    parser.add_argument("--dataset-id", help="use this Minari dataset instead of recording one")
    parser.add_argument("--path", help="Minari datasets directory to record into (default: a temporary one)")
    parser.add_argument("--epochs", type=int, default=50, help="imitation BC epochs (default 50)")
    parser.add_argument("--oversample", type=int, default=60, help="repeat rare-action transitions this often (default 60; 1: off)")
    parser.add_argument("--eval-episodes", type=int, default=30, help="evaluation episodes, seeds 1000.. (default 30)")
    parser.add_argument("--save", help="write imitation's policy to this file (torch)")
    args = parser.parse_args()

    def run(connect: str, path: str) -> None:
        if args.dataset_id:
            dataset = minari.load_dataset(args.dataset_id)
        else:
            dataset = highway_arena.record(args.scenario, args.episodes, path=path, connect=connect)
        print(f"dataset {dataset.id}: {dataset.total_episodes} episodes, {dataset.total_steps} steps")
        demonstrations = transitions(dataset, args.oversample)
        torch.manual_seed(0)  # the policy's initial weights
        trainer = imitation_bc.BC(
            observation_space=dataset.observation_space,
            action_space=dataset.action_space,
            demonstrations=demonstrations,
            rng=np.random.default_rng(0),
            batch_size=256,
            # No stdout tables and no log files outside the scratch directory.
            custom_logger=imitation_logger.configure(folder=f"{path}/imitation-log", format_strs=[]),
        )
        started = time.perf_counter()
        trainer.train(n_epochs=args.epochs, progress_bar=False, log_interval=10**9)
        print(f"imitation BC: {len(demonstrations)} transitions, {args.epochs} epochs in {time.perf_counter() - started:.1f} s")
        if args.save:
            trainer.policy.save(args.save)

        # The recovered env (the dataset's own spec) on episodes the recording never saw.
        env = dataset.recover_environment(connect=connect)
        imitation_policy = lambda observation: int(trainer.policy.predict(observation, deterministic=True)[0])  # noqa: E731
        summary("imitation BC", rollout(env, imitation_policy, args.eval_episodes, seed=1000))
        summary("highway_arena.bc", rollout(env, highway_arena.bc.fit(dataset, seed=0), args.eval_episodes, seed=1000))
        env.close()
        # The AV the dataset recorded, driving in the server on the same seeds.
        expert = dataset.recover_environment(connect=connect, policy="expert")
        summary("expert", rollout(expert, None, args.eval_episodes, seed=1000))
        expert.close()

    with tempfile.TemporaryDirectory() as scratch:
        path = args.path or scratch
        with highway_arena.serving(args.connect) as connect:
            run(connect, path)


if __name__ == "__main__":
    main()
