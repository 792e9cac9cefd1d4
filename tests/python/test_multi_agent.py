"""Scenarios with more than one learner: the built-in ones have one, so this file turns
merge.toml's adjacent car (a game-theoretic follower) into a second learner and sends the text to the server."""

import pathlib

from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

import highway_arena

TWO = (
    (pathlib.Path(__file__).resolve().parents[2] / "scenarios" / "merge.toml")
    .read_text()
    .replace('name = "ac"', 'name = "ec_1"')
    .replace(
        'driver = { kind = "gt", style = "normal", game = "stackelberg", role = "follower" }',
        'driver = { kind = "agent", style = "normal" }',
    )
)
assert TWO.count('kind = "agent"') == 2


def two(**kwargs):
    return highway_arena.parallel_env("two.toml", scenario_text=TWO, **kwargs)


def test_every_learner_is_an_agent_with_its_own_cached_spaces():
    env = two(observation="kinematics_with_mask")
    assert env.possible_agents == ["ec_0", "ec_1"]
    observations, infos = env.reset(seed=0)
    assert sorted(observations) == sorted(infos) == ["ec_0", "ec_1"]
    assert infos["ec_1"]["speed"] == 15.0
    assert env.observation_space("ec_1") is env.observation_space("ec_1")
    assert env.observation_space("ec_0").contains(observations["ec_0"])
    env.close()


def test_parallel_and_aec_api_with_two_learners():
    env = two()
    parallel_api_test(env, num_cycles=300)
    env.close()
    parallel_seed_test(two, num_cycles=100)
    aec = highway_arena.env("two.toml", scenario_text=TWO)
    api_test(aec, num_cycles=300)
    aec.close()


def test_gym_env_for_either_learner_drives_the_other_by_idm():
    for agent in ("ec_0", "ec_1"):
        env = highway_arena.gym_env("two.toml", agent=agent, scenario_text=TWO)
        assert env.agent == agent and env._parallel.possible_agents == [agent]
        check_env(env)
        env.close()
