"""Snapshots from Python: a ParallelEnv's snapshot restored into a fresh env on another
server steps bit for bit as the original; the Gymnasium env does the same; a snapshot of
another scenario, or a damaged one, raises SnapshotError and the env steps on."""

import pickle

import numpy as np
import pytest

import highway_arena

CYCLE = [1, 3, 1, 4, 1, 1, 0, 1, 1, 1, 4, 1, 2, 1]


def run(env, steps, offset=0):
    """Steps ``env`` with a fixed cycle of meta actions; every result, pickled (bytes)."""
    results = []
    for k in range(steps):
        if not env.agents:
            results.append(b"done")
            continue
        action = CYCLE[(k + offset) % len(CYCLE)]
        outcome = env.step({agent: action for agent in env.agents})
        results.append(pickle.dumps(outcome))
    return results


@pytest.mark.parametrize("scenario", ["highway-gt", "merge-random"])
def test_a_snapshot_restored_on_another_server_steps_bit_for_bit(scenario):
    original = highway_arena.parallel_env(scenario, max_cycles=150)
    original.reset(seed=27)
    run(original, 50)
    snapshot = original.snapshot()
    assert isinstance(snapshot, bytes) and snapshot.startswith(b"ARENASNP")
    live = list(original.agents)
    a = run(original, 50, offset=50)
    assert sum(result != b"done" for result in a) >= 30

    with highway_arena.launch_server() as other:
        fresh = highway_arena.parallel_env(scenario, max_cycles=150, connect=other.endpoint)
        observations, infos = fresh.restore(snapshot)
        assert fresh.agents == live and set(observations) == set(live) == set(infos)
        b = run(fresh, 50, offset=50)
        fresh.close()
    assert len(a) == len(b)
    for k, (x, y) in enumerate(zip(a, b)):
        assert x == y, f"{scenario}: step {k} after the snapshot differs"
    original.close()


def test_the_gymnasium_env_restores_its_agent():
    env = highway_arena.gym_env("merge")
    env.reset(seed=3)
    for _ in range(10):
        env.step(1)
    snapshot = env.snapshot()
    after = [env.step(3) for _ in range(5)]
    observation, info = env.restore(snapshot)
    assert observation.shape == env.observation_space.shape and "cost" in info
    again = [env.step(3) for _ in range(5)]
    for x, y in zip(after, again):
        assert np.array_equal(x[0], y[0]) and x[1:4] == y[1:4] and x[4] == y[4]
    env.close()


def test_a_snapshot_of_another_scenario_or_damaged_is_refused():
    merge = highway_arena.parallel_env("merge")
    merge.reset(seed=1)
    snapshot = merge.snapshot()
    highway = highway_arena.parallel_env("highway-gt")
    highway.reset(seed=1)
    with pytest.raises(highway_arena.SnapshotError, match="scenario 'merge'.*scenario 'highway-gt'"):
        highway.restore(snapshot)
    with pytest.raises(highway_arena.SnapshotError, match="truncated"):
        merge.restore(snapshot[:-5])
    other = highway_arena._core.PROTOCOL_VERSION + 1
    with pytest.raises(highway_arena.SnapshotError, match=f"protocol version {other}"):
        merge.restore(snapshot[:8] + other.to_bytes(2, "little") + snapshot[10:])
    for env in (merge, highway):
        env.step({agent: 1 for agent in env.agents})
        env.close()


def test_an_env_of_a_batch_or_vector_env_restores_bit_for_bit():
    batch = highway_arena.batch_env("merge-random", num_envs=2)
    batch.reset(seed=0)
    for _ in range(10):
        batch.step([{"ec_0": 3}, {"ec_0": 1}])
    saved = batch.snapshot(1)
    after = [pickle.dumps(batch.step([{"ec_0": 1}, {"ec_0": a}])[1]) for a in (3, 1, 0, 1, 4)]
    batch.restore(1, saved)
    again = [pickle.dumps(batch.step([{"ec_0": 1}, {"ec_0": a}])[1]) for a in (3, 1, 0, 1, 4)]
    assert after == again
    with pytest.raises(IndexError, match="env index 2 out of range"):
        batch.snapshot(2)
    batch.close()

    vector = highway_arena.vector_env("merge-random", num_envs=2)
    vector.reset(seed=0)
    vector.step(np.array([1, 3]))
    saved = vector.snapshot(0)
    first = [vector.step(np.array([a, 1]))[0][0].tobytes() for a in (3, 1, 4)]
    observation, _ = vector.restore(0, saved)
    second = [vector.step(np.array([a, 1]))[0][0].tobytes() for a in (3, 1, 4)]
    assert first == second and observation.shape == vector.single_observation_space.shape
    vector.close()
