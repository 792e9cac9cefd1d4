"""One arena-server for the whole Python suite, started from the repository's build
(scripts/test-python builds it) on a free 127.0.0.1 port; every env connects to it
through $HIGHWAY_ARENA_CONNECT, so PettingZoo's module-level tests find it too."""

import os
import pathlib

import pytest

import highway_arena

REPO = pathlib.Path(__file__).resolve().parents[2]
SCENARIOS = sorted(path.stem for path in (REPO / "scenarios").glob("*.toml"))


@pytest.fixture(scope="session", autouse=True)
def server():
    with highway_arena.launch_server() as local:
        previous = os.environ.get("HIGHWAY_ARENA_CONNECT")
        os.environ["HIGHWAY_ARENA_CONNECT"] = local.endpoint
        yield local
        if previous is None:
            os.environ.pop("HIGHWAY_ARENA_CONNECT", None)
        else:
            os.environ["HIGHWAY_ARENA_CONNECT"] = previous
