"""Makes the league's BC checkpoints (league/bc-<scenario>.npz): records the AV's own
episodes (the learner's style, Stackelberg: the `expert` row) on seeds from
highway_arena.RECORD_SEED on, apart from the league's seeds 0.., and fits the numpy
behaviour-cloning policy (highway_arena.bc) to them.

    python league/fit_bc.py                      # every scenario league/evaluate.py trains for
    python league/fit_bc.py --scenario merge-ac --episodes 30
"""

from __future__ import annotations

import argparse
import pathlib
import tempfile
import time

import highway_arena
import highway_arena.bc

HERE = pathlib.Path(__file__).resolve().parent
TRAINED = ["merge-random", "merge-ac", "overtake-random", "highway-gt"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--scenario", action="append", choices=TRAINED, help="only these scenarios (repeatable; default all)")
    parser.add_argument("--episodes", type=int, default=30, help="expert episodes to learn from (default 30)")
    parser.add_argument("--out", default=str(HERE), help="folder for the checkpoints (default: this one)")
    args = parser.parse_args()
    with highway_arena.serving(args.connect) as connect, tempfile.TemporaryDirectory() as datasets:
        for scenario in args.scenario or TRAINED:
            started = time.perf_counter()
            dataset = highway_arena.record(scenario, args.episodes, expert="expert", path=datasets, connect=connect, progress=False)
            policy = highway_arena.bc.fit(dataset, seed=0)
            path = pathlib.Path(args.out) / f"bc-{scenario}.npz"
            policy.save(path)
            print(f"{scenario}: {path} from {args.episodes} expert episodes in {time.perf_counter() - started:.0f} s", flush=True)


if __name__ == "__main__":
    main()
