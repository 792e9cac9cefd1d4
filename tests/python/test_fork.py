"""Envs in processes made by fork() from one that had opened envs: Zenoh's runtime
threads stay in the parent, so the child connects through a fresh copy of the extension
(highway_arena/_fork.py), and the extension itself refuses at once where it cannot
work. Each case runs in its own interpreter under a deadline, so a hang fails the test
without holding up the suite."""

import os
import signal
import subprocess
import sys
import textwrap

DEADLINE = 120


def run(script: str) -> str:
    """``script``'s standard output; fails on its exit status or past the deadline."""
    process = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(script)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        out, err = process.communicate(timeout=DEADLINE)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)  # the script and any child it forked
        process.communicate()
        raise AssertionError(f"hung for {DEADLINE} s") from None
    assert process.returncode == 0, err
    return out


def test_async_vector_env_with_the_default_start_method_steps_envs_after_the_parent_opened_one():
    out = run(
        """
        import multiprocessing
        import gymnasium
        import numpy as np
        import highway_arena

        make = lambda: highway_arena.gym_env("merge-random")
        parent = make()  # the parent opened an env (and keeps it) before forking
        parent.reset(seed=0)
        forked = gymnasium.vector.AsyncVectorEnv([make, make])  # the default context
        alone = gymnasium.vector.SyncVectorEnv([make, make])
        seen = [forked.reset(seed=[3, 4])[0], alone.reset(seed=[3, 4])[0]]
        for _ in range(20):
            actions = np.array([3, 1])
            seen += [forked.step(actions)[0], alone.step(actions)[0]]
        # The forked envs played exactly what the same envs do in this process.
        assert all(np.array_equal(a, b) for a, b in zip(seen[::2], seen[1::2]))
        assert not np.array_equal(seen[-2][0], seen[-2][1])  # two envs, not one twice
        forked.close()
        alone.close()
        parent.step(1)
        parent.close()
        print(multiprocessing.get_start_method())
        """
    )
    assert out.split() == ["fork"], out


def test_in_a_forked_child_the_extension_refuses_at_once_and_inherited_envs_fail_without_waiting():
    out = run(
        """
        import gc
        import os
        import time
        import highway_arena
        from highway_arena import _core

        kept = highway_arena.parallel_env("merge")
        kept.reset(seed=0)
        child = os.fork()
        if child == 0:
            started = time.monotonic()
            try:
                _core.Client([os.environ["HIGHWAY_ARENA_CONNECT"]])
                os._exit(3)
            except _core.ArenaError as error:
                code, message = error.args
                if code != "Forked" or "'spawn'" not in message:
                    os._exit(4)
            try:
                kept.step({"ec_0": 1})
                os._exit(5)
            except highway_arena.ForkedProcessError as error:
                if "spawn" not in str(error):
                    os._exit(6)
            del kept  # dropping the parent's env here must not wait on the parent's threads
            gc.collect()
            os._exit(0 if time.monotonic() - started < 5 else 7)
        _, status = os.waitpid(child, 0)
        kept.step({"ec_0": 1})  # the parent's env still works
        kept.close()
        print(os.waitstatus_to_exitcode(status))
        """
    )
    assert out.split() == ["0"], out
