"""The table of docs/baselines.md: learned policies beside the game-theoretic AV.

Records expert episodes of a scenario (highway_arena.record), fits the numpy
behaviour-cloning policy to them (highway_arena.bc), optionally loads PPO checkpoints
that examples/ppo_highway.py saved, and evaluates them all with the built-in policies
over the same seeds (highway_arena.evaluate), writing the tables and plots.

    python examples/baselines.py --scenario merge-random --episodes 50 --out out/baselines
    python examples/baselines.py --scenario merge-random --ppo ppo-merge.zip   # needs stable-baselines3

Launches its own arena-server (or --connect ENDPOINT). The expert episodes use the seeds
recording starts at by default (highway_arena.RECORD_SEED, 1 000 000 on), the evaluation
seeds from --seed (default 0): the learned policies are measured on episodes they never
saw. The BC fitted here is league/fit_bc.py's (the same episodes, the same fit), so its
row equals the league's (league/league.md).
"""

from __future__ import annotations

import argparse
import pathlib
import tempfile
import time

import highway_arena
import highway_arena.bc


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="merge-random", help="scenario to learn and evaluate on (default merge-random)")
    parser.add_argument("--episodes", type=int, default=50, help="evaluation episodes per policy (default 50)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the first evaluation episode (default 0)")
    parser.add_argument("--expert-episodes", type=int, default=30, help="expert episodes BC learns from (default 30)")
    parser.add_argument("--ppo", action="append", default=[], metavar="ZIP", help="a PPO checkpoint to evaluate too (repeatable)")
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--out", default="out/baselines", help="folder for the tables and plots (default out/baselines)")
    args = parser.parse_args()

    def run(connect: str) -> None:
        started = time.perf_counter()
        with tempfile.TemporaryDirectory() as datasets:
            dataset = highway_arena.record(
                args.scenario, args.expert_episodes, expert="expert", path=datasets, connect=connect
            )
            bc = highway_arena.bc.fit(dataset, seed=0)
        print(f"BC fitted to {args.expert_episodes} expert episodes in {time.perf_counter() - started:.0f} s")
        policies = {name: name for name in ("expert", "idm", "idle", "random")}
        policies["bc (numpy)"] = bc
        for path in args.ppo:
            from stable_baselines3 import PPO

            from highway_arena.sb3 import sampled

            # As trained and as the league plays it (sampled, seeded), and by its most
            # likely action (docs/baselines.md, "PPO").
            model = PPO.load(path, device="cpu")
            policies[f"ppo ({pathlib.Path(path).stem})"] = sampled(model, seed=0)
            policies[f"ppo argmax ({pathlib.Path(path).stem})"] = model
        result = highway_arena.evaluate(
            policies, [args.scenario], episodes=args.episodes, seed=args.seed, connect=connect, out=args.out
        )
        print(result.markdown)
        print(result.budget_markdown)
        print(f"written to {args.out}")

    with highway_arena.serving(args.connect) as connect:
        run(connect)


if __name__ == "__main__":
    main()
