"""Train PPO (Stable-Baselines3) against a scenario through the vector env
(highway_arena.sb3.vec_env: every step of all envs in one round trip), and print the
mean episode return and the success, collision and off-road rates of the policy before
and after training (highway_arena.evaluate, on seeds training never used), played both
by its most likely action (SB3's `deterministic=True`) and sampled.

    pip install -r examples/requirements-ppo.txt     # stable-baselines3 and torch
    python examples/ppo_highway.py --scenario merge-random-1hz-v2

The defaults (100 000 steps, 8 envs, entropy bonus 0.01, rewards normalised, seed 0,
200 evaluation episodes) are the benchmark of docs/baselines.md ("Learning curves"), on
merge-random-1hz-v2, merge-random deciding once a second (docs/scenarios.md, "Decision
rate") where running out of time in the ending lane fails as a crash does ("Versions"):
the tables there have every seed measured, played either way, and overtake-random-1hz-v2. Launches its own arena-server (or use --connect ENDPOINT for a running one)
and prints the training's wall time and CPU seconds (this process and, when it launched
it, the server).

A step the learner survives earns within [-w - b, 1 + b], with the risk weight w = 10 and
the goal bonus b (merge-random-1hz-v2: b = 2; overtake-random-1hz-v2: w = 15, b = 5;
docs/rewards.md), and a crash, or a failure at the time limit on the -v2 scenarios,
-((1 + w) x the episode length + 2b), so PPO learns on rewards scaled by the
running spread of returns (SB3's VecNormalize, rewards only; --no-normalize turns it
off), with an entropy bonus of 0.01 (without it PPO stops short of merge-random's lane
end).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

import highway_arena
from highway_arena.sb3 import sampled, vec_env

# The first held-out seed: training draws its episodes from other seeds.
HELD_OUT_SEED = 10_000


def parse_override(text: str) -> tuple[str, object]:
    """KEY=VALUE, the value read as JSON (numbers, true/false) or else kept as text."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise SystemExit(f"--override {text!r}: expected KEY=VALUE, e.g. reward.risk_weight=0")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


# Steps each env takes per PPO rollout.
N_STEPS = 256


def make_model(vec, seed: int, ent_coef: float, normalize: bool) -> PPO:
    """The benchmark's PPO: MlpPolicy, N_STEPS per env, batch 256, rewards normalised."""
    if normalize:
        vec = VecNormalize(vec, norm_obs=False, norm_reward=True)
    set_random_seed(seed)
    return PPO("MlpPolicy", vec, n_steps=N_STEPS, batch_size=256, ent_coef=ent_coef, seed=seed, verbose=0)


def whole_rollouts(timesteps: int, envs: int) -> int:
    """The steps of the whole rollouts that fit in ``timesteps`` (at least one): SB3 ends
    the rollout it is in, so 100 000 steps asked of 8 envs would take 100 352."""
    rollout = N_STEPS * envs
    return max(rollout, timesteps // rollout * rollout)


def rates(model, scenario: str, connect: str, episodes: int, overrides: dict) -> dict:
    """The policy on held-out seeds (10 000 on), measured as arena eval measures, played
    by its most likely action and sampled from its action distribution (seed 0, as the
    league plays it): {"argmax": figures, "sampled": figures}, figures as
    ``Evaluation.summary`` gives them."""
    policies = {"argmax": model, "sampled": sampled(model, seed=0)}
    result = highway_arena.evaluate(
        policies, scenario, episodes, seed=HELD_OUT_SEED, connect=connect, quiet=True, bootstrap=200, overrides=overrides
    )
    return {name: result.summary(scenario, name) for name in policies}


def report(when: str, model, scenario: str, connect: str, episodes: int, overrides: dict) -> None:
    for name, figures in rates(model, scenario, connect, episodes, overrides).items():
        shares = ", ".join(f"{key} {figures[key]['mean']:.0%}" for key in ("success", "collision", "off_road"))
        print(f"{when}, {name}: mean return {figures['return']['mean']:.1f}, {shares} ({episodes} episodes)", flush=True)


def cpu_seconds(pid: int | None = None) -> float:
    """CPU seconds (user + system) used so far by this process (all its threads), or by
    process ``pid`` (Linux: /proc; 0 where it cannot be read)."""
    if pid is None:
        return time.process_time()
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def with_server(connect: str | None, run) -> None:
    """Calls ``run(endpoint, server_pid)``: on ``connect`` (pid None) if given, else on an
    arena-server launched for the call."""
    if connect:
        run(connect, None)
        return
    with highway_arena.launch_server() as server:
        run(server.endpoint, server.process.pid)


class Progress(BaseCallback):
    """Prints the steps done, the time taken and the time left every tenth of the run."""

    def __init__(self, total: int):
        super().__init__()
        self.total, self.tenth = total, max(total // 10, 1)
        self.next, self.started = self.tenth, time.perf_counter()

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next:
            elapsed = time.perf_counter() - self.started
            left = elapsed * (self.total - self.num_timesteps) / self.num_timesteps
            print(f"  {self.num_timesteps} / {self.total} steps, {elapsed:.0f} s, about {left:.0f} s left", flush=True)
            self.next += self.tenth
        return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument(
        "--scenario", default="merge-random-1hz-v2", help="scenario to train on (default merge-random-1hz-v2)"
    )
    parser.add_argument(
        "--timesteps", type=int, default=100_000, help="PPO training steps, in whole rollouts (default 100000: 98304)"
    )
    parser.add_argument("--envs", type=int, default=8, help="parallel envs for training (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    parser.add_argument("--episodes", type=int, default=200, help="evaluation episodes (default 200)")
    parser.add_argument("--save", help="write the trained model to this .zip file")
    parser.add_argument("--no-normalize", action="store_true", help="train on the raw rewards (no VecNormalize)")
    parser.add_argument(
        "--ent-coef", type=float, default=0.01, help="PPO's entropy bonus (default 0.01; SB3's is 0: docs/baselines.md)"
    )
    parser.add_argument(
        "--override",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scenario override for training and evaluation, e.g. reward.risk_weight=0 (repeatable)",
    )
    args = parser.parse_args()
    overrides = dict(parse_override(text) for text in args.override)
    # One thread: PPO's small MLP gains nothing from more, and the server needs the cores.
    torch.set_num_threads(1)

    def run(connect: str, server_pid: int | None) -> None:
        vec = vec_env(args.scenario, num_envs=args.envs, connect=connect, overrides=overrides)
        model = make_model(vec, args.seed, args.ent_coef, not args.no_normalize)
        report("before training", model, args.scenario, connect, args.episodes, overrides)
        steps = whole_rollouts(args.timesteps, args.envs)
        started, cpu = time.perf_counter(), (cpu_seconds(), cpu_seconds(server_pid) if server_pid else 0.0)
        model.learn(total_timesteps=steps, callback=Progress(steps))
        seconds = time.perf_counter() - started
        learner, server = cpu_seconds() - cpu[0], (cpu_seconds(server_pid) - cpu[1]) if server_pid else None
        spent = f"{learner:.0f} CPU-s here" + (f", {server:.0f} CPU-s in the server" if server is not None else "")
        print(f"trained {model.num_timesteps} steps in {seconds:.0f} s ({spent})", flush=True)
        report(f"after {model.num_timesteps} steps", model, args.scenario, connect, args.episodes, overrides)
        if args.save:
            model.save(args.save)
        vec.close()

    with_server(args.connect, run)


if __name__ == "__main__":
    main()
