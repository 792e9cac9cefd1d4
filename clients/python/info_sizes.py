"""What sparse infos save: one agent's info after a step, pickled (what a
multiprocessing vector env sends through its pipe per agent and step), and env-steps per
second of ``highway_arena.vector_env`` (8 envs of merge-random, idle actions), with every
info key and with ``info_keys`` naming the four of the episode summary, the two cases
taken in turn for ``--rounds`` rounds (the median rate of each is printed: the machine's
speed drifts). The figures of docs/performance.md, "Sparse infos".

    python clients/python/info_sizes.py [--binary target/release/arena-server] [--seconds 5] [--rounds 3]
"""

from __future__ import annotations

import argparse
import pickle
import time

import numpy as np

import highway_arena

SUMMARY = ["end_reason", "episode_done", "episode_success", "episode_return"]


def measure(endpoint: str, seconds: float, info_keys) -> tuple[int, float]:
    """(pickled bytes of one agent's info after a step, env-steps per second)."""
    parallel = highway_arena.parallel_env("merge-random", connect=endpoint, info_keys=info_keys)
    parallel.reset(seed=0)
    _, _, _, _, infos = parallel.step({"ec_0": 1})
    size = len(pickle.dumps(infos["ec_0"]))
    parallel.close()
    envs = highway_arena.vector_env("merge-random", num_envs=8, connect=endpoint, info_keys=info_keys)
    envs.reset(seed=0)
    idle = np.ones(envs.num_envs, dtype=np.int64)
    steps, started = 0, time.perf_counter()
    while time.perf_counter() - started < seconds:
        envs.step(idle)
        steps += envs.num_envs
    rate = steps / (time.perf_counter() - started)
    envs.close()
    return size, rate


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--binary", help="arena-server binary to launch (default: found as launch_server finds it)")
    parser.add_argument("--seconds", type=float, default=5.0, help="seconds of stepping per case and round")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of the two cases in turn (default 3)")
    args = parser.parse_args()
    cases = {"every key": None, "info_keys=" + ",".join(SUMMARY): SUMMARY}
    sizes, rates = {}, {name: [] for name in cases}
    with highway_arena.launch_server(binary=args.binary) as server:
        for _ in range(args.rounds):
            for name, info_keys in cases.items():
                sizes[name], rate = measure(server.endpoint, args.seconds, info_keys)
                rates[name].append(rate)
    for name in cases:
        shown = ", ".join(f"{rate:.0f}" for rate in rates[name])
        median = float(np.median(rates[name]))
        print(f"{name}: {sizes[name]} bytes pickled per agent and step; {median:.0f} env-steps/s (rounds: {shown})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
