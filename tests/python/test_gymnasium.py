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


def test_record_video_writes_the_episode_as_docs_viewing_says(tmp_path):
    """docs/viewing.md's video recipe: Gymnasium's RecordVideo over an rgb_array env
    (moviepy writes the MP4); every step of the episode is a frame of the video."""
    from gymnasium.wrappers import RecordVideo
    from moviepy import VideoFileClip

    env = RecordVideo(
        highway_arena.gym_env("merge", render_mode="rgb_array", render_follow="ac", max_cycles=30),
        str(tmp_path / "videos"),
        episode_trigger=lambda episode: True,
        disable_logger=True,
    )
    env.reset(seed=0)
    steps = 0
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(1)
        steps += 1
        done = terminated or truncated
    env.close()
    [video] = list((tmp_path / "videos").glob("*.mp4"))
    clip = VideoFileClip(str(video))
    try:
        assert clip.size == [600, 300]
        # The reset's frame and one per step.
        assert round(clip.duration * clip.fps) == steps + 1
    finally:
        clip.close()


def test_frames_follow_the_named_vehicle():
    env = highway_arena.gym_env("merge", render_mode="rgb_array", render_follow="ac")
    env.reset(seed=0)
    # The frame's centre is the followed car: AC, drawn blue, not the green learner.
    assert env.render()[150, 300].tolist() == [60, 120, 235]
    env.unwrapped.render_follow = None
    assert env.render()[150, 300].tolist() == [50, 200, 80]
    env.unwrapped.render_follow = "nobody"
    with pytest.raises(highway_arena.ArenaError, match="no vehicle named 'nobody'"):
        env.render()
    env.close()


def test_the_render_window_is_the_metres_across_a_frame():
    def learner_pixels(**options):
        env = highway_arena.parallel_env("merge", render_mode="rgb_array", **options)
        env.reset(seed=0)
        frame = env.render()
        env.close()
        # Above the legend, whose swatch is learner green too.
        return int((frame[:270] == [50, 200, 80]).all(axis=2).sum())

    default = learner_pixels()
    assert default == learner_pixels(render_window=120)
    # Twice the metres across: the learner's car (5 x 2 m) takes a quarter of the pixels.
    assert 3.5 < default / learner_pixels(render_window=240) < 4.5
    assert 0.2 < default / learner_pixels(render_window=60) < 0.3
    with pytest.raises(highway_arena.ScenarioError, match=r"render_window 20 makes frames 600 pixels wide draw more "):
        highway_arena.parallel_env("merge", render_window=20)
    # The default's 120 m is never refused, however wide the frame; fewer metres than that are
    # on a frame that would draw more than 20 pixels a metre.
    highway_arena.parallel_env("merge", render_size=(16, 4096), render_window=120).close()
    with pytest.raises(highway_arena.ScenarioError, match=r"ask for at least 120 m, or smaller frames"):
        highway_arena.parallel_env("merge", render_size=(16, 4096), render_window=119)
