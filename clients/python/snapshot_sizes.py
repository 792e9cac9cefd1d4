"""The size of an env's snapshot after 50 idle steps (meta action 1) of highway-gt,
merge-random and merge with an expert, each reset with seed 27: the figures of
docs/protocol.md, "Snapshots".

    python clients/python/snapshot_sizes.py [--binary target/release/arena-server]
"""

from __future__ import annotations

import argparse

import highway_arena

CASES = [("highway-gt", {}), ("merge-random", {}), ("merge", {"expert": "stackelberg"})]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--binary", help="arena-server binary to launch (default: found as launch_server finds it)")
    args = parser.parse_args()
    with highway_arena.launch_server(binary=args.binary) as server:
        for scenario, options in CASES:
            env = highway_arena.parallel_env(scenario, max_cycles=150, connect=server.endpoint, **options)
            env.reset(seed=27)
            for _ in range(50):
                if not env.agents:
                    break
                env.step({agent: 1 for agent in env.agents})
            shown = ", ".join(f"{key} {value}" for key, value in options.items())
            print(f"{scenario}{f' ({shown})' if shown else ''}: {len(env.snapshot())} bytes")
            env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
