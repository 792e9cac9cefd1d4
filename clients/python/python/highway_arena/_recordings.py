"""Recordings and snapshots of envs made of several (``batch_env``, ``vector_env``): one
Rerun file per env, ``<folder>/env-<i>.rrd``, fed from that env's replies exactly as a
``ParallelEnv``'s recording is (docs/viewing.md), and each env's snapshot by its index."""

from __future__ import annotations

import os

from . import _core
from ._errors import translated


class EnvRecordings:
    """The recordings of ``envs`` (the extension's envs, in index order) into ``folder``.
    Turns recording on in each; ``reset``, ``restore`` and ``step`` pass each env's replies
    on; ``close`` ends every file and returns their paths."""

    def __init__(self, envs, folder, meta):
        from .recording import Recording  # rerun-sdk is an optional extra

        os.makedirs(folder, exist_ok=True)
        self._envs = list(envs)
        self.paths = [os.path.join(os.fspath(folder), f"env-{i:03d}.rrd") for i in range(len(self._envs))]
        self._recordings = []
        try:
            for i, (env, path) in enumerate(zip(self._envs, self.paths)):
                recording = Recording(path, meta={**meta, "env_index": i})
                self._recordings.append(recording)
                start = translated(env.record)(True)
                if start is not None:
                    recording.begin_episode(start)
        except BaseException:
            self.close()
            raise

    def reset(self, i, seed=None, infos=None):
        """Env ``i`` was reset (or restored): its new episode begins."""
        start, _ = self._envs[i].take_world()
        if start is not None:
            self._recordings[i].begin_episode(start, seed=seed, infos=infos)

    def step(self, i, actions, rewards, terminations, truncations, infos):
        """Env ``i`` stepped with ``actions`` (the wire's {agent: action})."""
        _, frames = self._envs[i].take_world()
        recording = self._recordings[i]
        recording.add_step(frames, actions, rewards, terminations, truncations, infos)
        recording.add_explanations(self._envs[i].take_explanations())

    def close(self, envs_open=True) -> list:
        """Ends every file (and, with ``envs_open``, tells each env's server to stop sending
        the world); returns the files' paths."""
        for env, recording in zip(self._envs, self._recordings):
            try:
                if envs_open:
                    translated(env.record)(False)
            finally:
                recording.close()
        return list(self.paths)


def recording_meta(scenario, dt, agents) -> dict:
    """What every recording of an env says about itself."""
    return {"protocol": _core.PROTOCOL_VERSION, "scenario": scenario, "step_dt": float(dt), "agents": list(agents)}
