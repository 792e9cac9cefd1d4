"""``highway_arena.evaluate``: the Python twin of ``arena eval`` (docs/evaluation.md).
Policies are compared on scenarios over the same seeds; built-in drivers run in the
server, callables (a trained Stable-Baselines3 model, a behaviour-cloning policy) in this
process; the figures and their 95 % intervals come from the same Rust code as the CLI's:
rates with Wilson intervals, other figures as median and IQM with seeded bootstrap
intervals (the estimators of rliable, checked against it), and every policy's paired
differences from a reference policy over the same seeds.

    import highway_arena
    result = highway_arena.evaluate(
        {"expert": "expert", "idle": "idle", "mine": lambda obs: 1}, ["merge"], episodes=20
    )
    print(result.markdown)
    result.write("out/eval")           # results.md/.csv/.json, episodes.csv, PNG plots
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import _core
from .datasets import RECORD_SEED
from .parallel import ParallelEnv

CLIENT_POLICIES = ("idle", "random")


@dataclass
class Evaluation:
    """What ``evaluate`` found: the tables as Markdown, one summary per (scenario,
    policy) with each figure's count, mean and the mean's interval, median and IQM with
    their intervals, the differences from the reference policy, every episode, and each
    policy's compute budget (``budget``, ``budget_markdown``: wall time per decision on
    this machine, kept out of the figures, which are the same bits on every run)."""

    markdown: str
    summaries: list
    episodes: list
    figures: list
    _files: dict = field(repr=False, default_factory=dict)
    crossplay: "Crossplay | None" = None
    # What each policy's decisions cost per agent and step on this machine: dicts with
    # "scenario", "policy", "clock" ('server': a built-in driver, timed by the server;
    # 'client': a callable, timed here), "steps", "p50_us", "p99_us".
    budget: list = field(default_factory=list)
    budget_markdown: str = ""

    def summary(self, scenario, policy) -> dict:
        """{figure: {"n", "mean", "low", "high", "median", "iqm"}} of one policy on one
        scenario; ``median`` and ``iqm`` are {"value", "low", "high"} (None for rates)."""
        for s in self.summaries:
            if s["scenario"] == scenario and s["policy"] == policy:
                return {key: estimate for key, estimate in s["figures"]}
        raise KeyError(f"no summary of policy {policy!r} on scenario {scenario!r}")

    def difference(self, scenario, policy) -> dict:
        """{figure: {"n", "difference", "improvement"}}: ``policy`` minus the reference
        over the same seeds (``difference``: {"value", "low", "high"}) and rliable's
        probability that ``policy`` is better (None where a figure has no better side);
        empty for the reference itself."""
        for s in self.summaries:
            if s["scenario"] == scenario and s["policy"] == policy:
                return {key: d for key, d in s["differences"]}
        raise KeyError(f"no summary of policy {policy!r} on scenario {scenario!r}")

    def write(self, out) -> list:
        """Writes results.md, results.csv, differences.csv, episodes.csv, results.json,
        budget.md, budget.csv and, with
        matplotlib installed, costs_<scenario>.png and rates_<scenario>.png into ``out``;
        returns the paths written."""
        os.makedirs(out, exist_ok=True)
        written = []
        for name, text in self._files.items():
            path = os.path.join(out, name)
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
            written.append(path)
        try:
            from ._plots import plot_costs, plot_rates
        except ImportError:
            print("highway_arena.evaluate: matplotlib is not installed, so no PNG plots were drawn", file=sys.stderr)
            return written
        for scenario in dict.fromkeys(e["scenario"] for e in self.episodes):
            written.append(plot_costs(self, scenario, os.path.join(out, f"costs_{scenario}.png")))
            written.append(plot_rates(self, scenario, os.path.join(out, f"rates_{scenario}.png")))
        if self.crossplay is not None:
            from ._plots import plot_crossplay

            for scenario, figure in dict.fromkeys((c[0], c[1]) for c in self.crossplay.cells):
                path = os.path.join(out, f"crossplay_{scenario}_{figure}.png")
                written.append(plot_crossplay(self.crossplay, scenario, figure, path))
        return written


@dataclass
class Crossplay:
    """The cross-play matrices: ``markdown`` (as ``arena eval --opponents`` writes
    crossplay.md) and ``cells``, one (scenario, figure, policy, opponent, value, low, high,
    one distinct episode, near the best: its interval overlaps the best cell's) per cell, the
    numbers None where no episode applies."""

    markdown: str
    cells: list

    def matrix(self, scenario, figure) -> dict:
        """{(policy, opponent): value} of one scenario's figure (a rate as a fraction, the
        return as its IQM)."""
        return {(c[2], c[3]): c[4] for c in self.cells if c[0] == scenario and c[1] == figure}


def _named(policies) -> list:
    """[(name, policy)] from a dict, or from a list of names and callables."""
    if isinstance(policies, dict):
        return [(str(name), policy) for name, policy in policies.items()]
    if isinstance(policies, (str, bytes)) or callable(policies):
        policies = [policies]
    named = []
    for policy in policies:
        name = policy if isinstance(policy, str) else getattr(policy, "__name__", type(policy).__name__)
        named.append((name, policy))
    names = [n for n, _ in named]
    twice = {n for n in names if names.count(n) > 1}
    if twice:
        raise ValueError(f"policies {sorted(twice)} appear twice: pass a dict {{name: policy}} to name them apart")
    return named


def _warn_on_training_seeds(named, seeds) -> None:
    """Warns for each policy that says which seeds it was trained on (``training_seeds``,
    as ``highway_arena.bc.fit`` keeps them from a recorded dataset) and is about to be
    evaluated on some of them."""
    for name, policy in named:
        trained = getattr(policy, "training_seeds", None)
        if not trained:
            continue
        overlap = sorted(set(trained).intersection(seeds))
        if overlap:
            shown = ", ".join(map(str, overlap[:5])) + (", ..." if len(overlap) > 5 else "")
            warnings.warn(
                f"policy {name!r} is evaluated on {len(overlap)} seeds its training data holds ({shown}): "
                f"those episodes are not held out; evaluate from another seed= (record starts at {RECORD_SEED})",
                UserWarning,
                stacklevel=3,
            )


def _act(policy, observation):
    """The action of an external policy: a callable, or an SB3-style model (``predict``
    returning (action, state))."""
    if callable(policy):
        return policy(observation)
    action, _ = policy.predict(observation, deterministic=True)
    return action


def _progress(total, quiet):
    try:
        from tqdm import tqdm
    except ImportError:
        tqdm = None
    if quiet:
        return None
    if tqdm is not None:
        return tqdm(total=total, unit="episode", file=sys.stderr)
    return _Line(total)


class _Line:
    """A one-line progress report on stderr when tqdm is not installed."""

    def __init__(self, total):
        self.total, self.n = total, 0

    def set_description(self, text):
        self.text = text

    def update(self, k):
        self.n += k
        print(f"\r{self.text}: {self.n}/{self.total} episodes", end="", file=sys.stderr, flush=True)

    def close(self):
        print(file=sys.stderr)


def evaluate(
    policies,
    scenarios,
    episodes=20,
    seed=0,
    max_cycles=None,
    connect=None,
    out=None,
    quiet=False,
    reference=None,
    bootstrap=5000,
    league=None,
    rank="return",
    opponents=False,
    **env_kwargs,
) -> Evaluation:
    """Runs each policy for ``episodes`` episodes of each scenario; episode i is reset with
    seed ``seed + i`` for every policy. A policy is a built-in name ('gt:<style>:<game>',
    'expert', 'idm': driven in the server; 'idle', 'random': here), a callable
    observation -> action, or a model with ``predict`` (Stable-Baselines3); ``policies``
    is a list of those or a dict {name: policy}. Every learner of a scenario follows the
    policy. ``out`` writes the tables and plots there (``Evaluation.write``); other
    keyword arguments go to each env (``action_type``, ``overrides``, ...). ``reference``
    names the policy the others are compared with seed by seed (default: the first);
    ``bootstrap`` is the number of resamples of every interval but the rates'. ``league``:
    a league file (JSON) to add the rows to, created if missing, refused (ValueError) when
    its seed, episode count or ``max_cycles`` differ (new scenarios join); league.md, ranked by
    ``rank``, is written beside it (docs/evaluation.md, "League"). ``opponents=True``:
    cross-play, every policy against each driver the AV can be (``gt:<style>:<game>``)
    and IDM in the place of all of the scenario's opponents (docs/evaluation.md,
    "Cross-play"); ``Evaluation.crossplay`` holds the matrices, and ``write`` adds
    crossplay.md and a heatmap per scenario and figure."""
    named = _named(policies)
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, int) or bootstrap < 100:
        raise ValueError(f"bootstrap must be a whole number of resamples, at least 100 (default 5000), not {bootstrap!r}")
    if reference is not None and reference not in [name for name, _ in named]:
        raise ValueError(f"reference {reference!r} is not one of the policies {[name for name, _ in named]}")
    scenarios = [scenarios] if isinstance(scenarios, str) else list(scenarios)
    episodes = int(episodes)
    if episodes < 1:
        raise ValueError(f"episodes must be at least 1, not {episodes}")
    if not scenarios:
        raise ValueError("give at least one scenario")
    if opponents and league is not None:
        raise ValueError("opponents and league cannot be combined: a league ranks policies against each scenario's own opponents")
    _warn_on_training_seeds(named, range(int(seed), int(seed) + episodes))
    cells = _core.crossplay_opponents() if opponents else [(None, [])]
    rows, timed = [], []
    bar = _progress(episodes * len(named) * len(scenarios) * len(cells), quiet)
    try:
        for scenario in scenarios:
            for name, policy in named:
                for opponent, overrides in cells:
                    row = name if opponent is None else f"{name} vs {opponent}"
                    if bar is not None:
                        bar.set_description(f"{scenario} / {row}")
                    kwargs = dict(env_kwargs)
                    if overrides:
                        kwargs["overrides"] = {**(env_kwargs.get("overrides") or {}), **dict(overrides)}
                    done, clock, micros = _run(scenario, row, policy, episodes, seed, max_cycles, connect, kwargs, bar)
                    rows.extend(done)
                    timed.append((scenario, row, clock, micros))
    finally:
        if bar is not None:
            bar.close()
    markdown, csv, differences_csv, episodes_csv, document = _core.eval_report(rows, reference, int(bootstrap))
    budget_markdown, budget_csv, budget = _core.budget_report(timed)
    parsed = json.loads(document)
    crossplay = None
    if opponents:
        table, matrix = _core.crossplay_report(rows, scenarios, [name for name, _ in named], int(bootstrap))
        crossplay = Crossplay(markdown=table, cells=matrix)
    result = Evaluation(
        markdown=markdown,
        summaries=parsed["summaries"],
        episodes=parsed["episodes"],
        figures=parsed["figures"],
        _files={
            "results.md": markdown,
            "results.csv": csv,
            "differences.csv": differences_csv,
            "episodes.csv": episodes_csv,
            "results.json": document,
            "budget.md": budget_markdown,
            "budget.csv": budget_csv,
            **({"crossplay.md": crossplay.markdown} if crossplay else {}),
        },
        crossplay=crossplay,
        budget=[dict(zip(("scenario", "policy", "clock", "steps", "p50_us", "p99_us"), row)) for row in budget],
        budget_markdown=budget_markdown,
    )
    if out is not None:
        result.write(out)
    if league is not None:
        _join_league(league, rows, scenarios, seed, episodes, max_cycles, rank, bootstrap)
    return result


def _join_league(path, rows, scenarios, seed, episodes, max_cycles, rank, bootstrap) -> None:
    """Adds the rows to the league file at ``path`` and writes league.md beside it."""
    text = None
    if os.path.exists(path):
        with open(path, encoding="utf-8") as f:
            text = f.read()
    try:
        updated, table = _core.league_add(
            text, rows, scenarios, int(seed), int(episodes), max_cycles, rank, int(bootstrap)
        )
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    with open(path, "w", encoding="utf-8") as f:
        f.write(updated)
    with open(os.path.join(folder, "league.md"), "w", encoding="utf-8") as f:
        f.write(table)


def _run(scenario, name, policy, episodes, seed, max_cycles, connect, env_kwargs, bar) -> tuple:
    """(policy name, scenario, seed, agent, last info) of each agent's episode; whose clock
    timed the policy ('server' or 'client'); its decision time per agent and step (µs)."""
    # Any other name is the server's to parse: an unknown one raises ValueError listing them.
    built_in = isinstance(policy, str) and policy not in CLIENT_POLICIES
    try:
        env = ParallelEnv(
            scenario, connect=connect, max_cycles=max_cycles, policy=policy if built_in else None, **env_kwargs
        )
    except ValueError as error:
        if built_in and "built-in policy" in str(error):
            # The server's names, plus what evaluate runs here.
            raise ValueError(f"{error}, {', '.join(CLIENT_POLICIES)}, or a callable observation -> action") from None
        raise
    rows, micros = [], []
    try:
        for i in range(episodes):
            episode_seed = seed + i
            observations, _ = env.reset(seed=episode_seed)
            spaces = _seeded_spaces(env, episode_seed)
            while env.agents:
                actions = _actions(policy, built_in, spaces, env.agents, observations, micros)
                observations, _, terminations, truncations, infos = env.step(actions)
                for agent, info in infos.items():
                    if terminations[agent] or truncations[agent]:
                        rows.append((name, scenario, episode_seed, agent, info))
            if bar is not None:
                bar.update(1)
        if built_in:
            micros = [us for kept in env._env.statistics().values() for us in kept]
    finally:
        env.close()
    return rows, "server" if built_in else "client", micros


def _seeded_spaces(env, seed) -> dict:
    """Each agent's action space, seeded from the episode's seed (``random`` draws the
    same actions for the same seed)."""
    spaces = {agent: env.action_space(agent) for agent in env.possible_agents}
    for k, agent in enumerate(env.possible_agents):
        spaces[agent].seed(seed + k)
    return spaces


def _actions(policy, built_in, spaces, agents, observations, micros=None) -> dict:
    """This step's actions of the live ``agents``: none when the server drives them. With
    ``micros`` (a list), each agent's action's wall time (µs) is appended to it."""
    if built_in:
        return {}
    actions = {}
    for a in agents:
        started = time.perf_counter_ns()
        if policy == "idle":
            actions[a] = _idle(spaces[a])
        elif policy == "random":
            actions[a] = spaces[a].sample()
        else:
            actions[a] = _act(policy, observations[a])
        if micros is not None:
            micros.append((time.perf_counter_ns() - started) / 1000.0)
    return actions


def _idle(space):
    """Keep lane and target speed: meta action 1, or no acceleration and the lane's centre."""
    if hasattr(space, "n"):
        return 1
    return np.zeros(space.shape, dtype=space.dtype)
