"""Train PPO with Ray RLlib on the paper's merge with two learners (EC merging, AC in the
target lane, one shared policy), collected by several env runners. Each env runner holds
its env on whichever arena-server placement picks: given a router's address, the envs of
all runners spread over every server of the site (docs/deployment.md).

    pip install -r examples/requirements-rllib.txt      # ray[rllib] and torch
    # a site on one machine: a router and two servers (three terminals)
    arena-server --mode router --route-only --listen tcp/127.0.0.1:7450
    arena-server --mode client --connect tcp/127.0.0.1:7450
    arena-server --mode client --connect tcp/127.0.0.1:7450
    python examples/rllib_ppo.py --connect tcp/127.0.0.1:7450 --mode client --env-runners 2 --iterations 5

Uses RLlib's own PettingZoo wrapper (ParallelPettingZooEnv) on highway_arena's
ParallelEnv, RLlib's new API stack. Prints, per iteration, the env steps sampled, the
mean episode return and the wall time; each env runner says which server its env lives
on. Not part of the test command (Ray is large to install and slow to start).
"""

from __future__ import annotations

import argparse
import sys
import time

import ray
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.tune.registry import register_env

# The adjacent car becomes a learner too: two agents, ec_0 and ac.
TWO_LEARNERS = {"vehicle.ac.driver": '{ kind = "agent" }'}


def make_env(config):
    """One env per env runner, on the server placement picks, seeded by the runner's index
    so runners see different traffic."""
    import highway_arena

    env = highway_arena.parallel_env(
        config["scenario"],
        connect=config["connect"],
        mode=config["mode"],
        overrides=TWO_LEARNERS,
        seed=1000 * config.worker_index + config.vector_index,
    )
    print(f"env runner {config.worker_index}: env on server {env.server}", file=sys.stderr, flush=True)
    return ParallelPettingZooEnv(env)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", required=True, help="endpoint of a router (or a single arena-server)")
    parser.add_argument("--mode", default="client", choices=["peer", "client"], help="Zenoh mode (default client)")
    parser.add_argument("--scenario", default="merge-random", help="scenario with ec_0 and ac (default merge-random)")
    parser.add_argument("--env-runners", type=int, default=2, help="RLlib env runners (default 2)")
    parser.add_argument("--iterations", type=int, default=5, help="training iterations (default 5)")
    parser.add_argument("--batch", type=int, default=2000, help="env steps per iteration (default 2000)")
    args = parser.parse_args()

    ray.init(num_cpus=args.env_runners + 1, include_dashboard=False, log_to_driver=True)
    register_env("highway-arena", make_env)
    config = (
        PPOConfig()
        .environment(
            "highway-arena", env_config={"scenario": args.scenario, "connect": args.connect, "mode": args.mode}
        )
        .env_runners(num_env_runners=args.env_runners, num_envs_per_env_runner=1)
        .multi_agent(policies={"shared"}, policy_mapping_fn=lambda agent_id, *rest, **kw: "shared")
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={"shared": RLModuleSpec()}))
        .training(train_batch_size_per_learner=args.batch, minibatch_size=250, num_epochs=5, lr=3e-4)
    )
    algo = config.build_algo()
    started = time.monotonic()
    print("| iteration | env steps (total) | mean episode return | wall s |")
    print("|---:|---:|---:|---:|")
    for iteration in range(1, args.iterations + 1):
        result = algo.train()
        runners = result.get("env_runners", {})
        steps = runners.get("num_env_steps_sampled_lifetime", float("nan"))
        returned = runners.get("episode_return_mean", float("nan"))
        print(f"| {iteration} | {steps:.0f} | {returned:.2f} | {time.monotonic() - started:.0f} |", flush=True)
    algo.stop()
    ray.shutdown()


if __name__ == "__main__":
    main()
