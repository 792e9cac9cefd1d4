"""What the package promises beyond PettingZoo's and Gymnasium's checks: clear errors
on bad input that never hang past the timeout, fresh arrays, idempotent close, timing."""

import pickle
import time

import numpy as np
import pytest

import highway_arena


def test_no_server_at_the_address_raises_quickly_with_advice():
    started = time.monotonic()
    with pytest.raises(highway_arena.ServerNotFoundError, match="arena-server"):
        highway_arena.parallel_env("merge", connect="tcp/127.0.0.1:1", timeout=1.0)
    assert time.monotonic() - started < 10.0


def test_malformed_address_is_refused():
    with pytest.raises(highway_arena.ArenaError):
        highway_arena.parallel_env("merge", connect="not an endpoint", timeout=1.0)


def test_unknown_scenario_names_the_ones_there_are():
    with pytest.raises(highway_arena.ScenarioError, match="merge, overtake"):
        highway_arena.parallel_env("nowhere")


def test_bad_override_is_refused_with_the_vehicle_named():
    with pytest.raises(highway_arena.ScenarioError, match="vehicle 'ec_0' is on lane 9"):
        highway_arena.parallel_env("merge", vehicle__ec_0__lane=9)


def test_inline_scenario_text_is_validated_like_a_file():
    with pytest.raises(highway_arena.ScenarioError, match="mine.toml"):
        highway_arena.parallel_env("mine.toml", scenario_text='name = "x"\n[road]\nlanes = 0\n')


def test_actions_outside_the_space_or_for_finished_agents_raise_value_errors():
    env = highway_arena.parallel_env("highway", max_cycles=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="outside Discrete"):
        env.step({"ego_0": 7})
    with pytest.raises(ValueError, match="expected an int"):
        env.step({"ego_0": 1.5})
    with pytest.raises(ValueError, match="no agent named"):
        env.step({"nobody": 1})
    env.step({"ego_0": 1})
    env.step({"ego_0": 1})
    assert env.agents == []
    with pytest.raises(highway_arena.InvalidActionError, match="env.agents"):
        env.step({"ego_0": 1})
    env.close()


def test_continuous_actions_accept_lists_and_arrays_and_refuse_out_of_range():
    env = highway_arena.parallel_env("merge", action_type="continuous")
    env.reset(seed=0)
    env.step({"ec_0": [1.0, 0.0]})
    env.step({"ec_0": np.array([0.5, -0.5], dtype=np.float32)})
    with pytest.raises(highway_arena.InvalidActionError, match="outside"):
        env.step({"ec_0": np.array([50.0, 0.0])})
    with pytest.raises(highway_arena.InvalidActionError, match="finite"):
        env.step({"ec_0": [float("nan"), 0.0]})
    env.close()


def test_observations_are_fresh_arrays_and_spaces_are_cached():
    env = highway_arena.parallel_env("merge")
    first, _ = env.reset(seed=3)
    again, _ = env.reset(seed=3)
    assert first["ec_0"] is not again["ec_0"]
    first["ec_0"][:] = 9.0  # writable, and changing it changes nothing else
    assert np.array_equal(again["ec_0"], env.reset(seed=3)[0]["ec_0"])
    assert env.observation_space("ec_0") is env.observation_space("ec_0")
    assert env.action_space("ec_0") is env.action_space("ec_0")
    env.close()


def test_close_is_idempotent_and_timing_is_exposed():
    env = highway_arena.parallel_env("highway")
    assert env.dt == 1.0 and env.metadata["render_fps"] == 1
    env.close()
    env.close()
    merge = highway_arena.gym_env("merge")
    assert merge.dt == pytest.approx(0.1) and merge.metadata["render_fps"] == 10
    merge.close()
    merge.close()


def test_expert_infos_carry_the_built_in_avs_choice():
    env = highway_arena.parallel_env("merge", expert="stackelberg")
    _, infos = env.reset(seed=0)
    assert infos["ec_0"]["expert_action"] in range(5)
    assert infos["ec_0"]["expert_sigma"] in (-1, 0)
    env.close()


def test_a_pickled_env_rebuilds_its_own_connection():
    env = highway_arena.parallel_env("merge")
    copy = pickle.loads(pickle.dumps(env))
    a, _ = env.reset(seed=5)
    b, _ = copy.reset(seed=5)
    assert np.array_equal(a["ec_0"], b["ec_0"])
    env.close()
    copy.close()


def test_batch_env_matches_single_envs():
    batch = highway_arena.batch_env("highway", num_envs=3)
    starts = batch.reset(seed=10)
    single = highway_arena.parallel_env("highway")
    first, _ = single.reset(seed=11)
    assert np.array_equal(starts[1]["ego_0"], first["ego_0"])
    results = batch.step([{"ego_0": 3}] * 3)
    expected = single.step({"ego_0": 3})
    assert np.array_equal(results[1][0]["ego_0"], expected[0]["ego_0"])
    assert results[1][1] == expected[1]
    batch.close()
    single.close()


def test_launch_server_reports_a_missing_binary():
    with pytest.raises(FileNotFoundError), highway_arena.launch_server(binary="/nonexistent/arena-server"):
        pass
