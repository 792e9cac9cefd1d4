"""Record the built-in game-theoretic AV driving in a learner's place as a Minari dataset.

    python -m highway_arena.record merge-random --episodes 30 --expert gt:normal:stackelberg
    python -m highway_arena.record merge --episodes 5 --launch       # start a local server for it

Episode i is reset with seed SEED + i. The dataset goes under $MINARI_DATASETS_PATH
(else ~/.minari/datasets), or under --path; load it with minari.load_dataset(ID).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import types

from .datasets import FAILURES, GAMES, RECORD_SEED, STYLES, record


def _value(text: str):
    """An override's value as the scenario file would read it: bool, int, float or string."""
    lowered = text.lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _override(text: str) -> tuple[str, object]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"{text!r} is not KEY=VALUE (e.g. vehicle.ac.speed=18.0)")
    return key, _value(value)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m highway_arena.record", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("scenario", help="a registered scenario: merge, merge-ac, overtake, merge-random, ... (highway_arena/<scenario>-v0)")
    p.add_argument("--episodes", type=int, default=10, help="episodes to record (default 10)")
    p.add_argument(
        "--expert",
        default="gt:normal:stackelberg",
        help=f"the AV in the learner's place: gt:<{'|'.join(STYLES)}>:<{'|'.join(GAMES)}>, or 'expert' "
        "(the learner's own style in the scenario file, stackelberg); default gt:normal:stackelberg",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=RECORD_SEED,
        help=f"seed of the first episode; episode i uses SEED + i (default {RECORD_SEED:_}, apart from the seeds "
        "evaluation starts at, 0)",
    )
    p.add_argument("--dataset-id", help="Minari dataset id (default highway_arena/<scenario>/gt-<style>-<game>-v0)")
    p.add_argument("--path", help="Minari datasets directory to write in (default $MINARI_DATASETS_PATH, else ~/.minari/datasets)")
    p.add_argument("--action-type", choices=("meta", "continuous"), default="meta", help="the learner's action space (default meta)")
    p.add_argument("--agent", help="which learner of the scenario to drive (default its first)")
    p.add_argument("--max-cycles", type=int, help="steps before an episode is truncated (default: the scenario's)")
    p.add_argument(
        "--override",
        action="append",
        type=_override,
        default=[],
        metavar="KEY=VALUE",
        help="a scenario key set at creation and stored in the dataset's env spec (repeatable), e.g. vehicle.ac.speed=18.0",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument("--connect", help="endpoint of a running arena-server (default $HIGHWAY_ARENA_CONNECT, else tcp/127.0.0.1:7447)")
    where.add_argument("--launch", action="store_true", help="start a local arena-server for the recording (highway_arena.launch_server)")
    p.add_argument("--author", default="highway-arena", help="the dataset's author in Minari's metadata (default highway-arena)")
    p.add_argument("--author-email", help="contact in Minari's metadata")
    p.add_argument("--code-permalink", help="link to the code that made the dataset, for Minari's metadata")
    p.add_argument("--description", help="the dataset's description (default: scenario, seeds, expert and action type)")
    p.add_argument("--no-progress", action="store_true", help="no progress line on stderr")
    return p


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    with contextlib.ExitStack() as stack:
        connect = args.connect
        if args.launch:
            from ._server import launch_server

            connect = stack.enter_context(launch_server()).endpoint
        try:
            dataset = record(
                args.scenario,
                args.episodes,
                expert=args.expert,
                seed=args.seed,
                dataset_id=args.dataset_id,
                path=args.path,
                action_type=args.action_type,
                connect=connect,
                agent=args.agent,
                max_cycles=args.max_cycles,
                overrides=dict(args.override) or None,
                author=args.author,
                author_email=args.author_email,
                code_permalink=args.code_permalink,
                description=args.description,
                progress=not args.no_progress,
            )
        except ValueError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        returns = [float(episode.rewards.sum()) for episode in dataset.iterate_episodes()]
        failures = sum(r < 0 for r in returns)
        root = args.path or os.environ.get("MINARI_DATASETS_PATH") or "~/.minari/datasets"
        print(
            f"wrote {dataset.spec.dataset_id} under {root}: {dataset.total_episodes} episodes, "
            f"{dataset.total_steps} steps, mean return {sum(returns) / len(returns):.1f}, "
            f"{failures} ended by {'/'.join(FAILURES)}"
        )
    return 0


class _CallableModule(types.ModuleType):
    """``import highway_arena.record`` makes the package's ``record`` attribute this
    module (Python sets a package's attribute to a submodule once imported), so the
    module calls the function: ``highway_arena.record(...)`` works either way."""

    def __call__(self, *args, **kwargs):
        return record(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule

if __name__ == "__main__":
    sys.exit(main())
