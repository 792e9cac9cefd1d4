"""One arena-server for the whole ecosystem check, as in tests/python: started from the
repository's build (scripts/test-ecosystem builds it and sets $ARENA_SERVER) on a free
127.0.0.1 port; every env connects to it through $HIGHWAY_ARENA_CONNECT, so the envs
that TorchRL and Tianshou build (gymnasium.make, DummyVectorEnv factories) find it too."""

import os

import pytest

import highway_arena


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
