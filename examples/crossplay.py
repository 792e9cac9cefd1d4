"""Cross-play of the shipped BC checkpoints (league/bc-<scenario>.npz) and the AV itself
(`expert`) against every driver the AV can be and IDM, on the same seeds: the matrices
docs/baselines.md shows ("Cross-play"). A PPO checkpoint joins with --ppo.

    python examples/crossplay.py                                   # merge-random and overtake-random, 50 episodes
    python examples/crossplay.py --scenario merge-random --episodes 10 --ppo ppo-merge-random.zip
    python examples/crossplay.py --ppo 'league/ppo-{scenario}.zip'   # each scenario's own checkpoint

Writes out/crossplay/<scenario>/ (crossplay.md, heatmaps, the usual tables) and prints
the matrices.
"""

from __future__ import annotations

import argparse
import pathlib

import highway_arena
import highway_arena.bc

LEAGUE = pathlib.Path(__file__).resolve().parent.parent / "league"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--scenario", action="append", help="scenario (repeatable; default merge-random and overtake-random)")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per cell (default 50)")
    parser.add_argument("--ppo", help="a Stable-Baselines3 PPO checkpoint to add, {scenario} replaced by the scenario's name (needs stable-baselines3)")
    parser.add_argument("--out", default="out/crossplay", help="folder for the results (default out/crossplay)")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, not {args.episodes}")
    with highway_arena.serving(args.connect) as connect:
        for scenario in args.scenario or ["merge-random", "overtake-random"]:
            checkpoint = LEAGUE / f"bc-{scenario}.npz"
            if not checkpoint.exists():
                parser.error(f"no BC checkpoint for {scenario} ({checkpoint}); league/fit_bc.py makes them")
            policies = {"expert": "expert", "bc": highway_arena.bc.load(checkpoint)}
            if args.ppo:
                from stable_baselines3 import PPO

                from highway_arena.sb3 import sampled

                # Sampled from its action distribution, seeded, as the league plays it.
                policies["ppo"] = sampled(PPO.load(args.ppo.format(scenario=scenario), device="cpu"), seed=0)
            result = highway_arena.evaluate(
                policies, scenario, episodes=args.episodes, connect=connect, opponents=True,
                out=str(pathlib.Path(args.out) / scenario),
            )
            print(result.crossplay.markdown, flush=True)


if __name__ == "__main__":
    main()
