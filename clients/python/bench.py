"""Simulated seconds per wall second through the Python API on highway.toml (set up
like highway-env's highway-v0; --scenario for another): one ParallelEnv stepped through
the PettingZoo API,
batches of envs stepped in one round trip each (highway_arena.batch_env), and the
Gymnasium vector env (highway_arena.vector_env). With --vs-envpool, EnvPool's C++
Highway-v0 in the same run (pip install envpool): 1 env on 1 thread, and each batch
size on 2 threads.

    python clients/python/bench.py --binary target/release/arena-server [--vs-envpool]

Without --connect it launches its own arena-server (the --binary given, else the one
highway_arena.launch_server finds). With --vs OTHER, it launches that server binary too
and measures the one env on the two servers in turn, --rounds times (the order flipped
each round), printing each round's pair and the median of their ratios: two builds
compared side by side on a machine whose speed drifts. Every policy is `idle` (meta action 1, as in
highway-env); with --actions random the single env's actions are drawn from its action
spaces (seeded). Prints a table, or JSON with --json.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import highway_arena


def single(where: dict, scenario: str, seconds: float, actions: str = "idle") -> tuple:
    """(simulated s per wall s, median step time in µs) of one env stepped alone, with
    idle actions or, with ``actions="random"``, actions sampled from its spaces (seeded)."""
    env = highway_arena.parallel_env(scenario, **where)
    env.reset(seed=0)
    for k, agent in enumerate(env.possible_agents):
        env.action_space(agent).seed(k)

    def act(agent):
        return env.action_space(agent).sample() if actions == "random" else 1

    steps, episodes, times = 0, 0, []
    started = time.perf_counter()
    while time.perf_counter() - started < seconds:
        before = time.perf_counter()
        env.step({agent: act(agent) for agent in env.agents})
        times.append(time.perf_counter() - before)
        steps += 1
        if not env.agents:
            episodes += 1
            env.reset(seed=episodes)
    elapsed = time.perf_counter() - started
    env.close()
    times.sort()
    return steps * env.dt / elapsed, times[len(times) // 2] * 1e6


def rounds_per_second(step, seconds: float) -> float:
    """Calls ``step()`` for ``seconds`` wall seconds; returns calls per second."""
    rounds = 0
    started = time.perf_counter()
    while time.perf_counter() - started < seconds:
        step()
        rounds += 1
    return rounds / (time.perf_counter() - started)


def batched(where: dict, scenario: str, num_envs: int, seconds: float) -> float:
    envs = highway_arena.batch_env(scenario, num_envs=num_envs, **where)
    envs.reset(seed=0)
    actions = [{agent: 1 for agent in envs.possible_agents} for _ in range(num_envs)]
    rate = rounds_per_second(lambda: envs.step(actions), seconds)
    envs.close()
    return rate * num_envs * envs.dt


def vectorised(where: dict, scenario: str, num_envs: int, seconds: float) -> float:
    envs = highway_arena.vector_env(scenario, num_envs=num_envs, **where)
    envs.reset(seed=0)
    actions = [1] * num_envs
    rate = rounds_per_second(lambda: envs.step(actions), seconds)
    envs.close()
    return rate * num_envs * envs.dt


def envpool_rate(num_envs: int, threads: int, seconds: float) -> float:
    """EnvPool's Highway-v0: one step is one simulated second (policy frequency 1)."""
    import envpool
    import numpy as np

    envs = envpool.make("Highway-v0", env_type="gymnasium", num_envs=num_envs, num_threads=threads)
    envs.reset()
    actions = np.ones(num_envs, dtype=np.int32)
    rate = rounds_per_second(lambda: envs.step(actions), seconds)
    envs.close()
    return rate * num_envs


def side_by_side(args, overrides: dict) -> int:
    """The one env on --binary (A) and --vs (B) in turn, --rounds times: each round's
    simulated s per wall s and B / A, then the medians."""
    import statistics

    binaries = {"A": args.binary, "B": args.vs}
    rounds = []
    with highway_arena.launch_server(binary=args.binary) as a, highway_arena.launch_server(binary=args.vs) as b:
        servers = {"A": a, "B": b}
        for k in range(args.rounds):
            order = ("A", "B") if k % 2 == 0 else ("B", "A")
            got = {}
            for name in order:
                where = {"connect": servers[name].endpoint, "mode": "peer"}
                if overrides:
                    where["overrides"] = overrides
                print(f"round {k + 1}, {name} ...", file=sys.stderr)
                got[name] = single(where, args.scenario, args.seconds, args.actions)[0]
            rounds.append(got)
    ratios = [r["B"] / r["A"] for r in rounds]
    if args.json:
        print(json.dumps({"scenario": args.scenario, "actions": args.actions, "binaries": binaries, "rounds": rounds,
                          "median_ratio": statistics.median(ratios)}, indent=2))
        return 0
    print(f"scenario {args.scenario}, one env, {args.actions} actions, simulated s per wall s:")
    print(f"  A = {args.binary or 'the default server'}\n  B = {args.vs}")
    print("round        A        B    B / A")
    for k, (r, ratio) in enumerate(zip(rounds, ratios)):
        print(f"{k + 1:>5} {r['A']:8.1f} {r['B']:8.1f} {ratio:8.3f}")
    a, b = statistics.median(r["A"] for r in rounds), statistics.median(r["B"] for r in rounds)
    print(f"median {a:7.1f} {b:8.1f} {statistics.median(ratios):8.3f}")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server or router (default: launch one)")
    parser.add_argument(
        "--mode",
        choices=["peer", "client"],
        default="peer",
        help="Zenoh session mode: 'client' through a router, where envs spread over every server (default peer)",
    )
    parser.add_argument("--binary", help="arena-server binary to launch (default: found as launch_server finds it)")
    parser.add_argument("--seconds", type=float, default=5.0, help="wall seconds per measurement (default 5)")
    parser.add_argument(
        "--scenario", default="highway", help="scenario to step (default highway; EnvPool's figures are always Highway-v0)"
    )
    parser.add_argument(
        "--batch", "--batches", dest="batches", default="16,64,128", help="comma-separated batch sizes (default 16,64,128)"
    )
    parser.add_argument(
        "--override",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a scenario override for every env, e.g. 'vehicle.ac.driver={ kind = \"idm\", style = \"normal\" }' "
        "(repeatable; VALUE as in a scenario file's TOML)",
    )
    parser.add_argument(
        "--actions",
        choices=["idle", "random"],
        default="idle",
        help="the single env's actions: idle (meta action 1, the default) or drawn from its action spaces, seeded",
    )
    parser.add_argument(
        "--vs",
        metavar="BINARY",
        help="a second arena-server binary: the one env measured on both servers in turn (no batches)",
    )
    parser.add_argument("--rounds", type=int, default=5, help="with --vs: rounds of the pair (default 5)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--vs-envpool", action="store_true", help="also measure EnvPool's Highway-v0 (pip install envpool)")
    args = parser.parse_args()
    sizes = [int(size) for size in args.batches.split(",") if size]
    overrides = {}
    for text in args.override:
        key, sep, value = text.partition("=")
        if not sep or not key:
            parser.error(f"--override {text!r} is not KEY=VALUE")
        overrides[key.strip()] = value.strip()

    if args.vs_envpool:
        try:
            import envpool  # noqa: F401
        except ImportError:
            parser.error("--vs-envpool needs EnvPool in this Python: pip install envpool")

    def run(connect: str) -> dict:
        where = {"connect": connect, "mode": args.mode}
        if overrides:
            where["overrides"] = overrides
        figures = {"single_sim_s_per_s": None, "single_step_p50_us": None, "batch": {}, "vector": {}}
        print("one env through the PettingZoo API ...", file=sys.stderr)
        figures["single_sim_s_per_s"], figures["single_step_p50_us"] = single(
            where, args.scenario, args.seconds, args.actions
        )
        for size in sizes:
            print(f"batch of {size} envs ...", file=sys.stderr)
            figures["batch"][str(size)] = batched(where, args.scenario, size, args.seconds)
            print(f"vector env of {size} envs ...", file=sys.stderr)
            figures["vector"][str(size)] = vectorised(where, args.scenario, size, args.seconds)
        if args.vs_envpool:
            figures["envpool"] = {"1 (1 thread)": envpool_rate(1, 1, args.seconds)}
            for size in sizes:
                print(f"EnvPool Highway-v0, {size} envs on 2 threads ...", file=sys.stderr)
                figures["envpool"][f"{size} (2 threads)"] = envpool_rate(size, 2, args.seconds)
        return figures

    if not args.seconds > 0:
        parser.error(f"--seconds must be a positive number of wall seconds, not {args.seconds}")
    for flag, path in (("--binary", args.binary), ("--vs", args.vs)):
        if path is not None and not (os.path.isfile(path) and os.access(path, os.X_OK)):
            parser.error(f"{flag} {path!r} is not an executable file")
    if args.vs:
        if args.connect:
            parser.error("--vs launches both servers; it cannot be used with --connect")
        if args.rounds < 1:
            parser.error(f"--rounds must be at least 1, not {args.rounds}")
        return side_by_side(args, overrides)
    if args.connect:
        figures = run(args.connect)
    else:
        with highway_arena.launch_server(binary=args.binary) as server:
            figures = run(server.endpoint)
    if args.json:
        print(json.dumps({"scenario": args.scenario, "actions": args.actions, **figures}, indent=2))
    else:
        print(f"scenario {args.scenario}:")
        print(
            f"one env:            {figures['single_sim_s_per_s']:9.1f} simulated s per wall s"
            f" (step p50 {figures['single_step_p50_us']:.0f} µs"
            + (", random actions)" if args.actions == "random" else ")")
        )
        for size, rate in figures["batch"].items():
            print(f"batch of {size:>3}:       {rate:9.1f} simulated s per wall s")
        for size, rate in figures["vector"].items():
            print(f"vector env of {size:>3}:  {rate:9.1f} simulated s per wall s")
        for label, rate in figures.get("envpool", {}).items():
            print(f"EnvPool {label:>14}: {rate:9.1f} simulated s per wall s")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except highway_arena.ArenaError as error:
        # A scenario the server does not have, a server that cannot be reached: what the
        # server said, without a traceback.
        print(f"bench.py: error: {error}", file=sys.stderr)
        sys.exit(2)
