"""Tianshou 2.0's DQN on the Gymnasium env highway_arena/merge-v0, built as Tianshou's own
example does (examples/discrete/discrete_dqn.py): a Net (MLP, which flattens the
kinematics observation) as Q-network, DiscreteQLearningPolicy with epsilon-greedy
exploration, the DQN algorithm with an Adam optimizer factory, and a Collector with a
VectorReplayBuffer over a DummyVectorEnv of two envs.

Tianshou stores every step's info dict in the buffer: a key that a step has and another
step lacks (or a string) leaves NaN in the buffer's info column. Tianshou's trainer checks
the buffer after every collection step ("MalformedBufferError: Encountered NaNs in
buffer"); a bare Collector checks it only when asked (raise_on_nan_in_buffer=True, off by
default: tianshou.config.ENABLE_VALIDATION), so the first test asks, and the second runs
the trainer as the example does."""

import gymnasium
import numpy as np
import torch

import highway_arena  # noqa: F401  (registers highway_arena/merge-v0)
from tianshou.algorithm import DQN
from tianshou.algorithm.modelfree.dqn import DiscreteQLearningPolicy
from tianshou.algorithm.optim import AdamOptimizerFactory
from tianshou.data import Collector, CollectStats, VectorReplayBuffer
from tianshou.env import DummyVectorEnv
from tianshou.trainer import OffPolicyTrainerParams
from tianshou.utils.net.common import Net
from tianshou.utils.space_info import SpaceInfo
from tianshou.utils.torch_utils import policy_within_training_step

TASK = "highway_arena/merge-v0"
STEPS = 2000
NUM_ENVS = 2


def dqn():
    torch.manual_seed(0)
    np.random.seed(0)
    env = gymnasium.make(TASK)
    assert isinstance(env.action_space, gymnasium.spaces.Discrete)
    space_info = SpaceInfo.from_env(env)
    net = Net(
        state_shape=space_info.observation_info.obs_shape,
        action_shape=space_info.action_info.action_shape,
        hidden_sizes=[64, 64],
    )
    policy = DiscreteQLearningPolicy(model=net, action_space=env.action_space, eps_training=0.1, eps_inference=0.1)
    env.close()
    return DQN(
        policy=policy, optim=AdamOptimizerFactory(lr=1e-3), gamma=0.9, n_step_return_horizon=3, target_update_freq=320
    )


def make_envs():
    return DummyVectorEnv([lambda: gymnasium.make(TASK) for _ in range(NUM_ENVS)])


def test_dqn_collects_2000_steps_without_nan_and_learns_from_them():
    algorithm = dqn()
    envs = make_envs()
    buffer = VectorReplayBuffer(total_size=2 * STEPS, buffer_num=NUM_ENVS)
    collector = Collector[CollectStats](
        algorithm, envs, buffer, exploration_noise=True, raise_on_nan_in_buffer=True
    )
    try:
        collector.reset()
        stats = collector.collect(n_step=STEPS)
        assert stats.n_collected_steps == STEPS
        assert len(buffer) == STEPS
        # merge ends within max_cycles (200) steps: 2000 steps hold finished episodes.
        assert stats.n_collected_episodes > 0
        data = buffer[np.arange(len(buffer))]
        assert not data.hasnull(), data.isnull().apply_values_transform(np.sum)
        assert np.isfinite(data.rew).all()
        # Every step's info reached the buffer, one value per transition and key.
        assert len(data.info.keys()) > 0
        for key in data.info.keys():
            assert len(data.info[key]) == STEPS, key
        # DQN learns from the buffer: its n-step targets read rewards, dones and obs_next.
        with policy_within_training_step(algorithm.policy):
            for _ in range(10):
                result = algorithm.update(buffer=buffer, sample_size=64)
                assert np.isfinite(result.loss), result
    finally:
        envs.close()


def test_dqn_trains_with_tianshous_off_policy_trainer():
    algorithm = dqn()
    envs = make_envs()
    buffer = VectorReplayBuffer(total_size=STEPS, buffer_num=NUM_ENVS)
    collector = Collector[CollectStats](algorithm, envs, buffer, exploration_noise=True)
    try:
        result = algorithm.run_training(
            OffPolicyTrainerParams(
                training_collector=collector,
                max_epochs=1,
                epoch_num_steps=STEPS // 2,
                collection_step_num_env_steps=100,
                batch_size=64,
                update_step_num_gradient_steps_per_sample=0.1,
                show_progress=False,
                verbose=False,
            )
        )
        assert len(buffer) >= STEPS // 2
        assert not buffer[np.arange(len(buffer))].hasnull()
        assert result.train_step >= STEPS // 2
    finally:
        envs.close()
