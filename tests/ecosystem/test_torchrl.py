"""TorchRL's PettingZooWrapper around highway_arena.parallel_env, as TorchRL's docs use
it (torchrl.envs.PettingZooWrapper, torchrl.envs.utils.check_env_specs, env.rollout, a
collector with a random policy), on merge (one learner, ec_0) and merge-duo (two
learners: ec_0 and ac_0).

TorchRL builds each group's ("info", key) specs from the infos of the first reset
(float32 tensors of each value's shape) and writes every later step's infos into them:
a key that appears only on a step, or a value that is not a number or a bool (a string),
fails inside TorchRL's own _step.

Grouping is TorchRL's default: agents named <group>_<n> share a group, so merge-duo's
ec_0 and ac_0 are two groups of one agent each. use_mask=True adds each group's "mask"
(False for an agent that has finished); with done_on_any=False TorchRL resets only once
every agent is done and keeps sending actions for finished agents in the meantime (the
env must ignore them, drop those agents from its observations and from env.agents)."""

import pytest
import torch

import highway_arena
from torchrl.collectors import Collector
from torchrl.envs import PettingZooWrapper
from torchrl.envs.utils import check_env_specs

FRAMES = 1000
FRAMES_PER_BATCH = 200
# merge-duo: merge with both the ego car (ec_0) and the adjacent car (ac_0) as learners.
SCENARIOS = ["merge", "merge-duo"]
WRAPPINGS = {
    "no-mask": {"use_mask": False},
    "mask": {"use_mask": True},
    # Only with a mask may agents finish at different steps (TorchRL's rule).
    "mask-done-on-all": {"use_mask": True, "done_on_any": False},
}
# The infos every agent carries, on reset and on every step (0 until the last step).
CONTRACT_INFO_KEYS = {"end_reason", "episode_done"}

pytestmark = pytest.mark.filterwarnings("ignore:PettingZoo in TorchRL is tested using version")


def wrap(scenario, **kwargs):
    return PettingZooWrapper(highway_arena.parallel_env(scenario), seed=0, **kwargs)


def reset_info_keys(scenario):
    """Each agent's info keys as the env itself returns them from reset."""
    env = highway_arena.parallel_env(scenario)
    try:
        _, infos = env.reset(seed=0)
    finally:
        env.close()
    return {agent: set(info) - {"action_mask"} for agent, info in infos.items()}


def assert_no_nan(td):
    for key, value in td.items(include_nested=True, leaves_only=True):
        if torch.is_tensor(value) and value.is_floating_point():
            assert not torch.isnan(value).any(), f"NaN in {key}"


def assert_frames(td, wrapped, scenario):
    assert td.numel() == FRAMES
    assert_no_nan(td)
    infos = reset_info_keys(scenario)
    assert set(infos) == set(wrapped.possible_agents)
    # Episodes last at most max_cycles (200) steps, so 1000 frames cross episode ends.
    assert td["next", "done"].any()
    for group, agents in wrapped.group_map.items():
        expected = set().union(*(infos[agent] for agent in agents))
        assert CONTRACT_INFO_KEYS <= expected, (group, sorted(expected))
        for root in ((group, "info"), ("next", group, "info")):
            assert set(td[root].keys()) == expected, (root, sorted(td[root].keys()), sorted(expected))
        info = td["next", group, "info"]
        episode_done = info["episode_done"] != 0
        done = td["next", group, "done"].squeeze(-1)
        # The flag marks an episode's last step, which every agent in it ends.
        assert episode_done.any(), group
        assert not (episode_done & ~done).any(), group


@pytest.mark.parametrize("wrapping", list(WRAPPINGS))
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_check_env_specs(scenario, wrapping):
    wrapped = wrap(scenario, **WRAPPINGS[wrapping])
    try:
        check_env_specs(wrapped)
        if WRAPPINGS[wrapping]["use_mask"]:
            for group in wrapped.group_map:
                assert (group, "mask") in wrapped.observation_spec.keys(True)
    finally:
        wrapped.close()


@pytest.mark.parametrize("wrapping", list(WRAPPINGS))
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_rollout_of_1000_frames(scenario, wrapping):
    wrapped = wrap(scenario, **WRAPPINGS[wrapping])
    try:
        # No policy: TorchRL samples random actions from the action spec; envs that are
        # done are reset in place, so one rollout crosses several episodes.
        td = wrapped.rollout(max_steps=FRAMES, break_when_any_done=False)
        assert td.batch_size == torch.Size([FRAMES])
        assert_frames(td, wrapped, scenario)
    finally:
        wrapped.close()


@pytest.mark.parametrize("wrapping", list(WRAPPINGS))
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_collector_of_1000_frames(scenario, wrapping):
    # torchrl 0.14's single-process synchronous collector (formerly SyncDataCollector);
    # policy=None is TorchRL's RandomPolicy over the env's action spec.
    wrapped = wrap(scenario, **WRAPPINGS[wrapping])
    collector = Collector(wrapped, policy=None, frames_per_batch=FRAMES_PER_BATCH, total_frames=FRAMES)
    try:
        batches = [batch.clone() for batch in collector]
    finally:
        collector.shutdown()
        wrapped.close()
    assert [batch.numel() for batch in batches] == [FRAMES_PER_BATCH] * (FRAMES // FRAMES_PER_BATCH)
    assert_frames(torch.cat(batches), wrapped, scenario)
