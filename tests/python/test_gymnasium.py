"""Gymnasium's own checker on the single-agent env, on every scenario file."""

import pytest
from gymnasium.utils.env_checker import check_env

import highway_arena
from conftest import SCENARIOS


@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("action_type", ["meta", "continuous"])
def test_check_env(scenario, action_type):
    env = highway_arena.gym_env(scenario, action_type=action_type)
    check_env(env, skip_render_check=False)
    env.close()


@pytest.mark.parametrize("render_mode", ["rgb_array", "ansi"])
def test_check_env_renders(render_mode):
    env = highway_arena.gym_env("merge", render_mode=render_mode)
    check_env(env)
    env.reset(seed=0)
    frame = env.render()
    if render_mode == "rgb_array":
        assert frame.shape == (300, 600, 3) and frame.dtype.name == "uint8" and frame.any()
    else:
        assert "ec_0" in frame and "@" in frame
    env.close()
