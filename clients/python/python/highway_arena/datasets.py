"""Minari datasets of the built-in game-theoretic AV driving in a learner's place.

    import highway_arena
    dataset = highway_arena.record("merge-random", episodes=30, expert="gt:normal:stackelberg")
    dataset.recover_environment()          # gymnasium.make("highway_arena/merge-random-v0", ...)

Episode ``i`` is reset with seed ``seed + i`` (by default from ``RECORD_SEED``, one
million, so that evaluation on seeds 0.. is held out) and driven by the AV itself, in the
server (the env's ``policy``, as ``arena eval`` and ``evaluate`` drive their
``gt:<style>:<game>`` and ``expert`` rows): the episodes are the ones those rows score.
Each step's action is the AV's own, in the learner's action space, as the server
labels it (``expert_action``: for continuous actions its acceleration and preview
point; for meta actions the meta action closest to its decision). The dataset holds
T + 1 observations and T actions, rewards, terminations and truncations per episode. The dataset's ``env_spec`` is the registered Gymnasium id
``highway_arena/<scenario>-v0`` with the creation options the recording used (action
type, expert game, style override, ``max_cycles``) and no endpoint: the recovered env
connects where ``$HIGHWAY_ARENA_CONNECT`` (else tcp/127.0.0.1:7447) says.

Episodes are written with ``minari.create_dataset_from_buffers``, not through
``minari.DataCollector``: the collector appends each step with jax (``minari[create]``),
which this package does not need for flat observations.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
import warnings
from dataclasses import dataclass

import gymnasium
import numpy as np
from gymnasium.envs.registration import EnvSpec

from . import _core
from ._connection import keywords, split, takes_connection_keywords
from .parallel import refuse_unknown

# The protocol's names (arena-protocol writes each once).
STYLES = tuple(_core.STYLES)
GAMES = tuple(_core.GAMES)

# The first seed ``record`` uses by default: far from ``evaluate``'s and ``arena eval``'s
# default (0), so that the documented record -> clone -> evaluate path tests a cloned
# policy on episodes it was not trained on (on seeds 0-49 it scored 80 % where held-out
# seeds gave 74 %). ``evaluate`` warns when it plays a policy on its training seeds.
RECORD_SEED = 1_000_000


def training_seeds(dataset) -> list:
    """The reset seeds of a Minari dataset's episodes, in episode order (``record`` stores
    each episode's seed; an episode without one is left out)."""
    metadata = dataset.storage.get_episode_metadata(dataset.episode_indices)
    return [int(m["seed"]) for m in metadata if m.get("seed") is not None]
ENTRY_POINT = "highway_arena.single:GymEnv"
# The end reasons of a failed episode, as the protocol says (`EndReason::failed`): the
# learner crashed or left the road; road_end and time_limit are not failures. Infos carry
# an end reason as its index.
FAILURES = tuple(_core.FAILED_END_REASONS)


def end_reason(info: dict) -> str:
    """The name of the end reason an info carries (``END_REASONS[info["end_reason"]]``)."""
    return _core.END_REASONS[int(info["end_reason"])]


@dataclass(frozen=True)
class Expert:
    """A parsed ``expert=`` string: the AV's ``game``, and the ``style`` it drives in
    (None: the learner's own style in the scenario file)."""

    game: str
    style: str | None

    @property
    def name(self) -> str:
        return f"gt-{self.style or 'scenario'}-{self.game}"

    @property
    def policy(self) -> str:
        """The server's name of this driver (the env's ``policy``, ``arena eval``'s row)."""
        return f"gt:{self.style}:{self.game}" if self.style else "expert"


def parse_expert(expert: str) -> Expert:
    """``"gt:<style>:<game>"`` (style aggressive|normal|conservative, game
    nash|stackelberg), or ``"expert"``: the learner's own style, Stackelberg; read as the
    server reads a built-in policy."""
    try:
        kind, style, game = _core.builtin_policy(expert)
    except (TypeError, ValueError):
        kind = None
    if kind != "gt":
        raise ValueError(
            f"expert={expert!r} is not an expert: write 'gt:<style>:<game>' with style one of "
            f"{'|'.join(STYLES)} and game one of {'|'.join(GAMES)} (e.g. 'gt:normal:stackelberg'), "
            "or 'expert' (the learner's own style, Stackelberg)"
        )
    return Expert(game=game, style=style)


def registered_scenarios() -> list[str]:
    """The scenarios with a registered Gymnasium id ``highway_arena/<scenario>-v0``."""
    prefix, suffix = "highway_arena/", "-v0"
    return sorted(
        env_id[len(prefix) : -len(suffix)]
        for env_id in gymnasium.registry
        if env_id.startswith(prefix) and env_id.endswith(suffix)
    )


def env_spec(scenario: str, **kwargs) -> EnvSpec:
    """The spec of ``gymnasium.make(f"highway_arena/{scenario}-v0", **kwargs)``, with
    the None-valued keyword arguments left out (so the spec's JSON stays small)."""
    kwargs = {"scenario": scenario, **{key: value for key, value in kwargs.items() if value is not None}}
    return EnvSpec(id=f"highway_arena/{scenario}-v0", entry_point=ENTRY_POINT, kwargs=kwargs)


class _Progress:
    """One stderr line, redrawn per episode (Minari has no progress bar of its own and
    tqdm is not among its dependencies)."""

    def __init__(self, enabled: bool, total: int, what: str):
        self.enabled, self.total, self.what = enabled, total, what
        self.started = time.perf_counter()

    def update(self, done: int, steps: int, failures: int) -> None:
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.started
        end = "\n" if done == self.total else ""
        print(
            f"\r{self.what}: {done}/{self.total} episodes, {steps} steps, {failures} failed, {elapsed:.0f} s",
            end=end,
            file=sys.stderr,
            flush=True,
        )


@contextlib.contextmanager
def _datasets_root(path):
    """Minari finds its datasets under $MINARI_DATASETS_PATH; ``path`` sets it for the
    duration of one recording (process-wide: do not record from two threads with
    different paths)."""
    if path is None:
        yield
        return
    previous = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = os.fspath(path)
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = previous


def _action(value, action_space):
    if isinstance(action_space, gymnasium.spaces.Discrete):
        return np.int64(value)
    return np.asarray(value, dtype=action_space.dtype)


@takes_connection_keywords
def record(
    scenario: str,
    episodes: int,
    expert: str = "gt:normal:stackelberg",
    seed: int = RECORD_SEED,
    dataset_id: str | None = None,
    path=None,
    action_type: str = "meta",
    connect=None,
    agent: str | None = None,
    max_cycles: int | None = None,
    overrides: dict | None = None,
    author: str = "highway-arena",
    author_email: str | None = None,
    code_permalink: str | None = None,
    description: str | None = None,
    progress: bool | None = None,
    **kwargs,
):
    """Rolls the built-in AV out in the learner's place on ``episodes`` seeded episodes
    of ``scenario`` (seeds ``seed`` on, by default ``RECORD_SEED``: apart from the seeds
    ``evaluate`` starts at) and writes them as a Minari dataset; returns the
    ``minari.MinariDataset``; ``training_seeds(dataset)`` lists its seeds.

    ``expert``: ``"gt:<style>:<nash|stackelberg>"`` or ``"expert"`` (the learner's own
    style, Stackelberg). ``dataset_id``: Minari's id, by default
    ``highway_arena/<scenario>/gt-<style>-<game>-v0``. ``path``: the Minari datasets
    directory to write in (default $MINARI_DATASETS_PATH, else ~/.minari/datasets).
    ``connect`` and the other connection keywords (below): how to reach the server, for
    recording only (never stored). ``overrides``:
    scenario keys set at creation (stored in the env spec). ``author``, ``author_email``,
    ``code_permalink``, ``description``: Minari's metadata. ``progress``: a progress
    line on stderr (default: when stderr is a terminal).
    """
    connection, unknown = split(kwargs, connect=connect)
    refuse_unknown("record()", unknown, RECORD_KEYWORDS, overrides=False)
    import minari
    from minari.data_collector import EpisodeBuffer

    from .single import GymEnv

    parsed = parse_expert(expert)
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be a whole number >= 1, not {episodes!r}")
    if not 0 <= int(seed) < 2**64 - int(episodes):
        raise ValueError(f"seed must be in [0, 2**64 - episodes), not {seed}")
    scenarios = registered_scenarios()
    if scenario not in scenarios:
        raise ValueError(
            f"unknown scenario {scenario!r}: record needs one registered as highway_arena/<scenario>-v0 "
            f"(so the dataset can recover its env); those are {scenarios}"
        )
    if action_type not in _core.ACTION_TYPES:
        raise ValueError(f"action_type must be one of {', '.join(_core.ACTION_TYPES)}, not {action_type!r}")
    dataset_id = dataset_id or f"highway_arena/{scenario}/{parsed.name}-v0"

    probe = GymEnv(scenario, agent=agent, action_type=action_type, max_cycles=max_cycles, **connection)
    learner = probe.agent
    probe.close()
    overrides = dict(overrides or {})
    if parsed.style is not None:
        # The AV the expert stands for drives in the learner vehicle's style.
        overrides[f"vehicle.{learner}.driver.style"] = parsed.style
    options = {
        "agent": agent,
        "action_type": action_type,
        "expert": parsed.game,
        "max_cycles": max_cycles,
        "overrides": overrides or None,
    }
    # The AV drives in the server; the dataset's env (below) is the learner's, without it.
    env = GymEnv(scenario, **{**options, "overrides": overrides}, policy=parsed.policy, **connection)
    # The dataset's env_spec: the registered id and creation options, no endpoint.
    env.spec = env_spec(scenario, **options)

    if progress is None:
        progress = sys.stderr.isatty()
    bar = _Progress(bool(progress), int(episodes), f"recording {dataset_id}")
    buffers, steps, failures = [], 0, 0
    try:
        for i in range(int(episodes)):
            observation, info = env.reset(seed=int(seed) + i)
            observations, actions, rewards, terminations, truncations = [observation], [], [], [], []
            while True:
                action = _action(info["expert_action"], env.action_space)
                observation, reward, terminated, truncated, info = env.step(None)
                observations.append(observation)
                actions.append(action)
                rewards.append(reward)
                terminations.append(terminated)
                truncations.append(truncated)
                if terminated or truncated:
                    break
            steps += len(actions)
            failures += end_reason(info) in FAILURES
            buffers.append(
                EpisodeBuffer(
                    id=i,
                    seed=int(seed) + i,
                    observations=observations,
                    actions=actions,
                    rewards=rewards,
                    terminations=terminations,
                    truncations=truncations,
                )
            )
            bar.update(i + 1, steps, failures)

        style = parsed.style or "the learner's own (scenario file)"
        with _datasets_root(path), warnings.catch_warnings():
            # Minari nudges for contact metadata it cannot check; record() leaves it to
            # the caller (author_email, code_permalink), so only those nudges are muted.
            for key in ("author_email", "code_permalink"):
                warnings.filterwarnings("ignore", message=rf"`{key}` is set to None", category=UserWarning)
            dataset = minari.create_dataset_from_buffers(
                dataset_id,
                buffers,
                env=env,
                eval_env=env,
                algorithm_name=f"highway-arena built-in game-theoretic AV ({parsed.game}, {style} style)",
                author=author,
                author_email=author_email,
                code_permalink=code_permalink,
                description=description
                or (
                    f"{episodes} episodes of {scenario} (seeds {seed}..{int(seed) + int(episodes) - 1}) with "
                    f"{learner} driven by the built-in game-theoretic AV ({parsed.game}, {style} style), "
                    f"{action_type} actions (the expert_action infos)"
                ),
            )
    finally:
        env.close()
    return dataset


# Every keyword record takes, connection keywords included.
RECORD_KEYWORDS = keywords(record)


# rollout's name for replaying each step's ``expert_action`` as the learner's action: the
# AV's labels played by the learner's own action space, a driver of its own (for meta
# actions it is not the AV: ``evaluate``'s ``expert`` row is).
EXPERT_REPLAY = "expert-replay"


def rollout(env, policy, episodes: int, seed: int = 0) -> dict:
    """Plays ``policy(observation) -> action`` (for ``policy="expert-replay"``, each
    step's ``expert_action`` info: the env needs ``expert=``; for None, the driver of an
    env made with ``policy=``, the AV for ``policy="expert"``) on ``episodes`` episodes
    of a Gymnasium ``env`` (episode ``i`` reset with ``seed + i``); returns ``returns``
    (one per episode), ``mean_return``, ``end_reasons``, ``failures`` (episodes ended
    by a collision, going off the road or running out of lane) and ``failure_rate``."""
    returns, reasons = [], []
    for i in range(int(episodes)):
        observation, info = env.reset(seed=int(seed) + i)
        total = 0.0
        while True:
            if policy is None:
                action = None
            elif isinstance(policy, str) and policy == EXPERT_REPLAY:
                action = info["expert_action"]
            else:
                action = policy(observation)
            observation, reward, terminated, truncated, info = env.step(action)
            total += reward
            if terminated or truncated:
                break
        returns.append(total)
        reasons.append(end_reason(info))
    failures = sum(reason in FAILURES for reason in reasons)
    return {
        "returns": returns,
        "end_reasons": reasons,
        "failures": failures,
        "failure_rate": failures / max(1, len(reasons)),
        "mean_return": float(np.mean(returns)) if returns else float("nan"),
    }
