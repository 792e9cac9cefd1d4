"""highway_arena: PettingZoo and Gymnasium envs of a multi-lane highway world whose
vehicles follow the driver + bicycle model of Hang et al., served by an arena-server
over Zenoh.

    import highway_arena
    env = highway_arena.parallel_env("merge")       # pettingzoo.ParallelEnv
    observations, infos = env.reset(seed=0)
    observations, rewards, terminations, truncations, infos = env.step({"ec_0": 1})
    env.close()

``highway_arena.record(scenario, episodes)`` writes a Minari dataset of the built-in
game-theoretic AV driving in the learner's place (``pip install highway-arena[datasets]``);
``highway_arena.bc`` fits a numpy-only behaviour-cloning policy to one.

Every agent's infos have the keys ``INFO_KEYS`` (then the ``expert_*`` ones with
``expert=``), in that order, on reset and on every step, all numbers or bools:
``info["end_reason"]`` is an index into ``END_REASONS`` (0, "running", until the agent's
last step), and the ``episode_*`` figures are zero until ``info["episode_done"]``.
Meta actions are indices into ``META_ACTIONS``; ``STYLES`` and ``GAMES`` name the
built-in AV's driving styles and games (``policy="gt:<style>:<game>"``).

``connect`` defaults to $HIGHWAY_ARENA_CONNECT, else tcp/127.0.0.1:7447 (where
``arena-server`` listens by default); ``launch_server()`` starts one for you. Every
constructor takes the connection keywords ``CONNECTION_KEYWORDS`` (with their defaults;
``help(highway_arena.parallel_env)`` says what each means) and the env options the server
applies, ``ENV_OPTIONS`` (their names and defaults, from the protocol's one table:
``action_type``, ``expert``, ``policy``, ...), and refuses an unknown keyword with a
TypeError naming it and the valid ones.
"""

import gymnasium
from pettingzoo.utils.conversions import parallel_to_aec

from ._errors import (
    ArenaError,
    ArenaTimeoutError,
    EnvClosedError,
    ForkedProcessError,
    InvalidActionError,
    InvalidEndpointError,
    RequestTooLargeError,
    ScenarioError,
    ServerGoneError,
    ServerNotFoundError,
    SnapshotError,
)
from . import _connection
from ._connection import CONNECTION_KEYWORDS, ENV_OPTIONS, default_connect
from ._core import END_REASONS, GAMES, INFO_KEYS, META_ACTIONS, STYLES
from ._server import LocalServer, find_server_binary, launch_server, serving
from .batch import BatchEnv
from .datasets import RECORD_SEED, record, training_seeds
from .evaluation import Evaluation, evaluate
from .parallel import ParallelEnv
from .play import play
from .single import GymEnv
from .vector import VectorEnv

__all__ = [
    "CONNECTION_KEYWORDS",
    "ENV_OPTIONS",
    "END_REASONS",
    "GAMES",
    "INFO_KEYS",
    "META_ACTIONS",
    "RECORD_SEED",
    "STYLES",
    "ArenaError",
    "ArenaTimeoutError",
    "BatchEnv",
    "EnvClosedError",
    "Evaluation",
    "ForkedProcessError",
    "GymEnv",
    "InvalidActionError",
    "InvalidEndpointError",
    "RequestTooLargeError",
    "LocalServer",
    "ParallelEnv",
    "ScenarioError",
    "ServerGoneError",
    "ServerNotFoundError",
    "SnapshotError",
    "VectorEnv",
    "batch_env",
    "default_connect",
    "env",
    "evaluate",
    "find_server_binary",
    "gym_env",
    "launch_server",
    "parallel_env",
    "play",
    "record",
    "serving",
    "training_seeds",
    "vector_env",
]


for _scenario in (
    "merge",
    "merge-ac",
    "merge-duo",
    "overtake",
    "highway",
    "highway-gt",
    "merge-random",
    "overtake-random",
):
    # gymnasium.make("highway_arena/merge-v0", connect=...) builds a GymEnv.
    gymnasium.register(
        f"highway_arena/{_scenario}-v0", entry_point="highway_arena.single:GymEnv", kwargs={"scenario": _scenario}
    )


@_connection.takes_connection_keywords
@_connection.takes_env_options
def parallel_env(scenario="merge", connect=None, render_mode=None, max_cycles=None, **kwargs) -> ParallelEnv:
    """A ``pettingzoo.ParallelEnv`` of ``scenario`` on the server at ``connect``."""
    return ParallelEnv(scenario, connect=connect, render_mode=render_mode, max_cycles=max_cycles, **kwargs)


@_connection.takes_connection_keywords
@_connection.takes_env_options
def env(scenario="merge", connect=None, render_mode=None, max_cycles=None, **kwargs):
    """The AEC version of ``parallel_env`` (PettingZoo's own ``parallel_to_aec``). Its
    ``dt`` is the simulated seconds of one cycle (every live agent acting once)."""
    parallel = parallel_env(scenario, connect, render_mode, max_cycles, **kwargs)
    aec = parallel_to_aec(parallel)
    # PettingZoo's wrappers forward unknown attributes inward only as far as the
    # parallel_to_aec wrapper; give it the timing the parallel env exposes.
    aec.env.dt = parallel.dt
    aec.env.max_cycles = parallel.max_cycles
    return aec


@_connection.takes_connection_keywords
@_connection.takes_env_options
def gym_env(scenario="highway", agent=None, connect=None, render_mode=None, **kwargs) -> GymEnv:
    """A ``gymnasium.Env`` for one learner of ``scenario``."""
    return GymEnv(scenario, agent=agent, connect=connect, render_mode=render_mode, **kwargs)


@_connection.takes_connection_keywords
@_connection.takes_env_options
def batch_env(scenario="highway", num_envs=8, connect=None, **kwargs) -> BatchEnv:
    """``num_envs`` envs stepped in one round trip per step."""
    return BatchEnv(scenario, num_envs=num_envs, connect=connect, **kwargs)


@_connection.takes_connection_keywords
@_connection.takes_env_options
def vector_env(scenario="highway", num_envs=8, agent=None, connect=None, **kwargs) -> VectorEnv:
    """A ``gymnasium.vector.VectorEnv`` of ``num_envs`` copies of one learner's view of
    ``scenario``, stepped in one round trip per step, with next-step autoreset."""
    return VectorEnv(scenario, num_envs=num_envs, agent=agent, connect=connect, **kwargs)
