"""Re-evaluates the shipped league (league/league.json, league/league.md): the
game-theoretic AV in its three styles and two games, IDM, and the BC and PPO checkpoints
in this folder, on the compete scenarios, every policy on the same seeds. Re-evaluation,
not retraining: the checkpoints are loaded as they are (league/README.md says how they
were made).

    python league/evaluate.py                 # launches its own arena-server
    python league/evaluate.py --connect tcp/127.0.0.1:7447 --episodes 10 --out /tmp/league

BC checkpoints are bc-<scenario>.npz, PPO ones ppo-<scenario>.zip (Stable-Baselines3); a
checkpoint serves the scenarios CHECKPOINT_OF maps to it (the random variants' policies
also play their paper scenario). PPO needs stable-baselines3 (examples/requirements-ppo.txt).
"""

from __future__ import annotations

import argparse
import pathlib
import time

import highway_arena
import highway_arena.bc

HERE = pathlib.Path(__file__).resolve().parent

# The compete scenarios (issue 26) and which scenario's checkpoints play each.
CHECKPOINT_OF = {
    "merge": "merge-random",
    "merge-random": "merge-random",
    "merge-ac": "merge-ac",
    "overtake": "overtake-random",
    "overtake-random": "overtake-random",
    "highway-gt": "highway-gt",
    # The 1 Hz tasks of the README's training command (docs/scenarios.md, "Versions").
    "merge-random-1hz-v2": "merge-random-1hz-v2",
    "overtake-random-1hz-v2": "overtake-random-1hz-v2",
}

# Every style and game of the AV (the protocol's names), Stackelberg's first as the league
# was first written, then IDM.
BUILT_IN = [f"gt:{style}:{game}" for game in reversed(highway_arena.GAMES) for style in highway_arena.STYLES]
BUILT_IN.append("idm")


def learned(folder: pathlib.Path, scenario: str) -> dict:
    """The BC and PPO policies shipped for ``scenario``, by league name."""
    source = CHECKPOINT_OF[scenario]
    policies = {}
    bc = folder / f"bc-{source}.npz"
    if bc.exists():
        policies["bc"] = highway_arena.bc.load(bc)
    ppo = folder / f"ppo-{source}.zip"
    if ppo.exists():
        try:
            from stable_baselines3 import PPO
        except ImportError:
            raise SystemExit(
                f"{ppo.name} needs Stable-Baselines3: pip install -r examples/requirements-ppo.txt"
            ) from None

        from highway_arena.sb3 import sampled

        # Played as trained: actions sampled from its distribution, seeded (its most
        # likely action crashes on overtake-random; docs/baselines.md, "PPO").
        policies["ppo"] = sampled(PPO.load(ppo, device="cpu"), seed=0)
    return policies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per policy and scenario (default 50)")
    parser.add_argument("--scenario", action="append", choices=sorted(CHECKPOINT_OF), help="only these scenarios (repeatable; default all)")
    parser.add_argument("--checkpoints", default=str(HERE), help="folder of the BC and PPO checkpoints (default: this one)")
    parser.add_argument("--out", default=str(HERE), help="folder for league.json and league.md (default: this one)")
    parser.add_argument("--rank", default="return", help="the figure league.md ranks by (default return)")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, not {args.episodes}")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    league = out / "league.json"
    # A fresh league: every row is re-evaluated now, under this version's reward and world.
    if league.exists() and args.scenario is None:
        league.unlink()
    scenarios = args.scenario or list(CHECKPOINT_OF)

    with highway_arena.serving(args.connect) as connect:
        for scenario in scenarios:
            started = time.perf_counter()
            policies = {name: name for name in BUILT_IN}
            policies.update(learned(pathlib.Path(args.checkpoints), scenario))
            highway_arena.evaluate(
                policies, scenario, episodes=args.episodes, seed=0, connect=connect, league=str(league), rank=args.rank, quiet=True
            )
            print(f"{scenario}: {len(policies)} policies x {args.episodes} episodes in {time.perf_counter() - started:.0f} s", flush=True)
    print(f"written: {league} and {out / 'league.md'}")


if __name__ == "__main__":
    main()
