"""Train PPO (Stable-Baselines3) against a scenario through the vector env
(highway_arena.sb3.vec_env: every step of all envs in one round trip), and print the
mean episode return and the success, collision and off-road rates of the policy before
and after training (highway_arena.evaluate, on seeds training never used).

    pip install -r examples/requirements-ppo.txt     # stable-baselines3 and torch
    python examples/ppo_highway.py --scenario merge --timesteps 20000

Launches its own arena-server (or use --connect ENDPOINT for a running one). A step the
learner survives earns within [-w - b, 1 + b], with the risk weight w = 10 and the goal
bonus b = 0 (overtake: 15 and 50), and a crash -((1 + w) x the episode length + 2b)
(docs/rewards.md: the risk term, the goal bonus), so PPO
learns on rewards scaled by the running spread of returns (SB3's VecNormalize, rewards
only; --no-normalize turns it off), with an entropy bonus of 0.01 (without it PPO stops
short of merge-random's lane end). The league's checkpoints were made so:

    python examples/ppo_highway.py --scenario merge-random --timesteps 300000 --envs 8 --episodes 20 --ent-coef 0.01 --save league/ppo-merge-random.zip
    python examples/ppo_highway.py --scenario overtake-random --timesteps 300000 --envs 8 --episodes 20 --ent-coef 0.01 --save league/ppo-overtake-random.zip

The report gives the policy twice: sampled from its action distribution (seeded: how it
trained, and how the league plays it) and by its most likely action, which on
overtake-random crashes where the sampled policy passes (docs/baselines.md, "PPO").
"""

from __future__ import annotations

import argparse
import json
import time

from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecNormalize

import highway_arena
from highway_arena.sb3 import sampled, vec_env


def parse_override(text: str) -> tuple[str, object]:
    """KEY=VALUE, the value read as JSON (numbers, true/false) or else kept as text."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise SystemExit(f"--override {text!r}: expected KEY=VALUE, e.g. reward.risk_weight=0")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def report(when: str, model, scenario: str, connect: str, episodes: int, overrides: dict) -> None:
    """The policy on held-out seeds (10 000 on), measured as arena eval measures: sampled
    from its action distribution (seed 0, as trained and as the league plays it) and by
    its most likely action."""
    policies = {"sampled": sampled(model, seed=0), "argmax": model}
    result = highway_arena.evaluate(
        policies, scenario, episodes, seed=10_000, connect=connect, quiet=True, overrides=overrides
    )
    for name in policies:
        figures = result.summary(scenario, name)
        rates = ", ".join(f"{key} {figures[key]['mean']:.0%}" for key in ("success", "collision", "off_road"))
        print(f"{when}, {name}: mean return {figures['return']['mean']:.1f}, {rates} ({episodes} episodes)", flush=True)


class Progress(BaseCallback):
    """Prints the steps done, the time taken and the time left every tenth of the run (a
    run on highway-gt takes about 17 minutes on two cores)."""

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
    parser.add_argument("--scenario", default="highway", help="scenario to train on (default highway)")
    parser.add_argument("--timesteps", type=int, default=20_000, help="PPO training steps (default 20000)")
    parser.add_argument("--envs", type=int, default=8, help="parallel envs for training (default 8)")
    parser.add_argument("--episodes", type=int, default=10, help="evaluation episodes (default 10)")
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

    def run(connect: str) -> None:
        vec = vec_env(args.scenario, num_envs=args.envs, connect=connect, overrides=overrides)
        if not args.no_normalize:
            vec = VecNormalize(vec, norm_obs=False, norm_reward=True)
        set_random_seed(0)
        model = PPO("MlpPolicy", vec, n_steps=256, batch_size=256, ent_coef=args.ent_coef, seed=0, verbose=0)
        report("before training", model, args.scenario, connect, args.episodes, overrides)
        started = time.perf_counter()
        model.learn(total_timesteps=args.timesteps, callback=Progress(args.timesteps))
        seconds = time.perf_counter() - started
        report(f"after {args.timesteps} steps ({seconds:.0f} s)", model, args.scenario, connect, args.episodes, overrides)
        if args.save:
            model.save(args.save)
        vec.close()

    with highway_arena.serving(args.connect) as connect:
        run(connect)


if __name__ == "__main__":
    main()
