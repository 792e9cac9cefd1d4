"""Learning curves of examples/ppo_highway.py's PPO (its defaults: 100 000 steps, 8 envs,
entropy bonus 0.01, rewards normalised): for each scenario and training seed, the
success, collision and off-road rates and the mean return on held-out seeds (10 000 on),
played by the most likely action and sampled, every `--every` steps from the start;
the last point is measured on `--final-episodes` episodes. Writes every point to
`curves.csv` in `--out`, with the training's wall time and CPU seconds so far (learner
and server, evaluation left out), and plots `<scenario>.png` from it and prints the last points as a table
(`--plot-only` does both for an existing CSV).

    python examples/learning_curves.py --out docs/images/learning-curves

One training run at a time, torch on one thread: the figures are what one process pair
(learner and server) takes on the machine it runs on.
"""

from __future__ import annotations

import argparse
import csv
import os
import time

import torch
from ppo_highway import HELD_OUT_SEED, cpu_seconds, make_model, rates, whole_rollouts, with_server
from stable_baselines3.common.callbacks import BaseCallback

from highway_arena.sb3 import vec_env

SCENARIOS = ["merge-random-1hz-v2", "overtake-random-1hz-v2", "highway-gt"]
COLUMNS = [
    "scenario",
    "seed",
    "steps",
    "played",
    "episodes",
    "success",
    "collision",
    "off_road",
    "return",
    "train_wall_s",
    "train_cpu_learner_s",
    "train_cpu_server_s",
]


class Clock:
    """Wall time and CPU seconds (this process, the server) spent while running, with the
    spans between `pause` and `resume` left out."""

    def __init__(self, server_pid: int | None):
        self.server_pid = server_pid
        self.spent = [0.0, 0.0, 0.0]
        self.mark = None

    def now(self) -> list[float]:
        return [time.perf_counter(), cpu_seconds(), cpu_seconds(self.server_pid) if self.server_pid else 0.0]

    def resume(self) -> None:
        self.mark = self.now()

    def pause(self) -> None:
        self.spent = [total + now - then for total, now, then in zip(self.spent, self.now(), self.mark)]


class Curve(BaseCallback):
    """Measures the policy at every multiple of `every` steps before `last` (training
    paused)."""

    def __init__(self, measure, every: int, last: int):
        super().__init__()
        self.measure, self.every, self.next, self.last = measure, every, every, last

    def _on_step(self) -> bool:
        if self.last > self.num_timesteps >= self.next:
            self.measure(self.model, self.num_timesteps)
            self.next += self.every
        return True


def train_and_measure(args, scenario: str, seed: int, connect: str, server_pid, writer) -> None:
    clock = Clock(server_pid)
    vec = vec_env(scenario, num_envs=args.envs, connect=connect)
    model = make_model(vec, seed, args.ent_coef, normalize=True)

    last = whole_rollouts(args.timesteps, args.envs)

    def measure(model, steps: int) -> None:
        clock.pause()
        episodes = args.final_episodes if steps >= last else args.episodes
        for played, figures in rates(model, scenario, connect, episodes, {}).items():
            writer.writerow(
                [scenario, seed, steps, played, episodes]
                + [f"{figures[key]['mean']:.4f}" for key in ("success", "collision", "off_road", "return")]
                + [f"{value:.1f}" for value in clock.spent]
            )
            print(
                f"{scenario} seed {seed} {steps} steps {played}: success {figures['success']['mean']:.0%} "
                f"({episodes} episodes), training {clock.spent[0]:.0f} s",
                flush=True,
            )
        args.csv_file.flush()
        clock.resume()

    clock.resume()
    measure(model, 0)
    model.learn(total_timesteps=last, callback=Curve(measure, args.every, last))
    measure(model, model.num_timesteps)
    vec.close()


def summary(path: str) -> str:
    """The last point of every run as a Markdown table (docs/baselines.md's)."""
    with open(path, encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    last = {}
    for row in rows:
        last[(row["scenario"], row["seed"], row["played"])] = row
    lines = [
        "| scenario | seed | steps | episodes | most likely action: success / collision / off-road "
        "| sampled: success / collision / off-road | training (s) | CPU-s (learner + server) |",
        "|---|---:|---:|---:|---|---|---:|---:|",
    ]
    for (scenario, seed, played), row in last.items():
        if played != "argmax":
            continue
        shares = [
            " / ".join(f"{100 * float(each[key]):.0f} %" for key in ("success", "collision", "off_road"))
            for each in (row, last[(scenario, seed, "sampled")])
        ]
        cpu = f"{float(row['train_cpu_learner_s']):.0f} + {float(row['train_cpu_server_s']):.0f}"
        lines.append(
            f"| {scenario} | {seed} | {row['steps']} | {row['episodes']} | {shares[0]} | {shares[1]} "
            f"| {float(row['train_wall_s']):.0f} | {cpu} |"
        )
    return "\n".join(lines)


def plot(path: str, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(path, encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    for scenario in dict.fromkeys(row["scenario"] for row in rows):
        figure, axes = plt.subplots(figsize=(6.4, 3.6))
        for played, colour in (("argmax", "tab:blue"), ("sampled", "tab:orange")):
            mine = [row for row in rows if row["scenario"] == scenario and row["played"] == played]
            seeds = sorted({row["seed"] for row in mine})
            by_step: dict[int, list[float]] = {}
            for seed in seeds:
                points = sorted((int(row["steps"]), 100 * float(row["success"])) for row in mine if row["seed"] == seed)
                axes.plot(*zip(*points), color=colour, alpha=0.3, linewidth=0.8)
                for step, value in points:
                    by_step.setdefault(step, []).append(value)
            steps = sorted(by_step)
            label = f"{'most likely action' if played == 'argmax' else 'sampled'} (mean of {len(seeds)} seeds)"
            axes.plot(steps, [sum(by_step[s]) / len(by_step[s]) for s in steps], color=colour, marker="o", label=label)
        axes.set(xlabel="environment steps", ylabel="success (%)", ylim=(-2, 102), title=f"PPO on {scenario}")
        axes.axhline(90, color="grey", linestyle=":", linewidth=0.8)
        axes.legend(loc="lower right", fontsize="small")
        figure.tight_layout()
        figure.savefig(os.path.join(out, f"{scenario}.png"), dpi=100)
        plt.close(figure)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--connect", help="endpoint of a running arena-server (default: launch one)")
    parser.add_argument("--scenario", action="append", help=f"repeatable (default {', '.join(SCENARIOS)})")
    parser.add_argument("--seeds", type=int, default=3, help="training seeds 0..N-1 (default 3)")
    parser.add_argument("--timesteps", type=int, default=100_000, help="steps per run, in whole rollouts (default 100000)")
    parser.add_argument("--every", type=int, default=25_000, help="steps between two measurements (default 25000)")
    parser.add_argument("--episodes", type=int, default=30, help="held-out episodes per measurement (default 30)")
    parser.add_argument("--final-episodes", type=int, default=200, help="held-out episodes of the last (default 200)")
    parser.add_argument("--envs", type=int, default=8, help="parallel envs for training (default 8)")
    parser.add_argument("--ent-coef", type=float, default=0.01, help="PPO's entropy bonus (default 0.01)")
    parser.add_argument("--out", required=True, help="folder for curves.csv and the PNGs")
    parser.add_argument("--plot-only", action="store_true", help="plot the CSV in --out, train nothing")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "curves.csv")
    if not args.plot_only:
        torch.set_num_threads(1)
        fresh = not os.path.exists(path)
        with open(path, "a", newline="", encoding="utf-8") as args.csv_file:
            writer = csv.writer(args.csv_file)
            if fresh:
                writer.writerow(COLUMNS)

            def run(connect: str, server_pid: int | None) -> None:
                # Seed by seed, so that every scenario has a curve early on.
                for seed in range(args.seeds):
                    for scenario in args.scenario or SCENARIOS:
                        train_and_measure(args, scenario, seed, connect, server_pid, writer)

            with_server(args.connect, run)
    plot(path, args.out)
    print(summary(path))
    print(f"wrote {path} and the PNGs beside it (held-out seeds from {HELD_OUT_SEED})")


if __name__ == "__main__":
    main()
