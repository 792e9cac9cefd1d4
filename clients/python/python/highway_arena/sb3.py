"""Stable-Baselines3 over the vector env: ``highway_arena.sb3.vec_env(...)`` is an SB3
``VecEnv`` of ``num_envs`` copies stepped in one round trip per step, for
``PPO("MlpPolicy", vec_env)`` and friends. SB3 resets a finished env within the same
step and wants the episode's last observation in ``infos[i]["terminal_observation"]``;
the vector env's same-step autoreset gives exactly that. Needs stable-baselines3 (and
torch), which the package does not depend on: this module imports them."""

from __future__ import annotations

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from ._connection import takes_connection_keywords
from .vector import VectorEnv


class SB3VecEnv(VecEnv):
    """An SB3 ``VecEnv`` over a same-step-autoreset ``highway_arena.VectorEnv``."""

    def __init__(self, vector: VectorEnv):
        if vector.metadata["autoreset_mode"] != AutoresetMode.SAME_STEP:
            raise ValueError("SB3 needs a vector env with autoreset_mode=AutoresetMode.SAME_STEP")
        self.vector = vector
        self._actions = None
        self._seed = None
        super().__init__(vector.num_envs, vector.single_observation_space, vector.single_action_space)

    def reset(self):
        observations, infos = self.vector.reset(seed=self._seed)
        self._seed = None
        self.reset_infos = self._unbatch(infos, np.zeros(self.num_envs, dtype=np.bool_))
        return observations

    def step_async(self, actions):
        self._actions = actions

    def step_wait(self):
        observations, rewards, terminations, truncations, infos = self.vector.step(self._actions)
        dones = terminations | truncations
        out = self._unbatch(infos, truncations & ~terminations)
        for i in np.flatnonzero(dones):
            out[i]["terminal_observation"] = infos["final_obs"][i]
        return observations, rewards.astype(np.float32), dones, out

    def _unbatch(self, infos, truncated):
        out = [{} for _ in range(self.num_envs)]
        for key, values in infos.items():
            if key.startswith("_") or key in ("final_obs", "final_info"):
                continue
            mask = infos.get(f"_{key}", np.ones(self.num_envs, dtype=np.bool_))
            for i in np.flatnonzero(mask):
                out[i][key] = values[i]
        for i in np.flatnonzero(truncated):
            out[i]["TimeLimit.truncated"] = True
        return out

    def seed(self, seed=None):
        self._seed = seed
        return [None if seed is None else seed + i for i in range(self.num_envs)]

    def close(self):
        self.vector.close()

    def get_attr(self, attr_name, indices=None):
        return [getattr(self.vector, attr_name, None) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name, value, indices=None):
        setattr(self.vector, attr_name, value)

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        raise NotImplementedError("the sub-envs live on the server; call the vector env instead")

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._get_indices(indices)]


@takes_connection_keywords
def vec_env(scenario="highway", num_envs=8, **kwargs) -> SB3VecEnv:
    """An SB3 VecEnv of ``num_envs`` copies of ``scenario`` (``vector_env``'s options)."""
    return SB3VecEnv(VectorEnv(scenario, num_envs=num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **kwargs))


class Sampled:
    """An SB3 model as a policy that samples its actions from the model's own action
    distribution (what it trained with) with a seeded generator, instead of taking the
    most likely action (``predict(deterministic=True)``, what ``evaluate`` does with a
    model). A PPO policy trained with an entropy bonus stays spread, and its most likely
    action can drive differently from the policy it learned: on overtake-random the
    argmax of the league's PPO crashed in every episode while its sampled policy passed
    (docs/baselines.md, "PPO"). The same ``seed`` and the same observations in the same
    order give the same actions. Discrete and Box action spaces."""

    def __init__(self, model, seed: int = 0):
        self.model = model
        self.rng = np.random.default_rng(seed)

    def __call__(self, observation):
        import torch

        policy = self.model.policy
        tensor, _ = policy.obs_to_tensor(observation)
        with torch.no_grad():
            distribution = policy.get_distribution(tensor).distribution
        if isinstance(distribution, torch.distributions.Categorical):
            probs = distribution.probs.cpu().numpy()[0].astype(np.float64)
            return int(self.rng.choice(len(probs), p=probs / probs.sum()))
        mean = distribution.mean.cpu().numpy()[0]
        std = distribution.stddev.cpu().numpy()[0]
        action = self.rng.normal(mean, std).astype(np.float32)
        space = self.model.action_space
        if policy.squash_output:
            return np.tanh(action)
        return np.clip(action, space.low, space.high)


def sampled(model, seed: int = 0) -> Sampled:
    """``model`` (Stable-Baselines3) as a callable observation -> action that samples
    from its action distribution with a generator seeded by ``seed`` (``Sampled``)."""
    return Sampled(model, seed)
