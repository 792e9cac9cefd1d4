"""A wheel built by scripts/build-wheel, installed into a fresh venv outside the
repository, starts its own bundled arena-server with launch_server() and serves an env."""

import os
import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]

USE = """
import pathlib, highway_arena
from highway_arena import _server
binary = highway_arena.find_server_binary()
assert pathlib.Path(binary) == _server.BUNDLED_SERVER, binary
assert "site-packages" in binary, binary
with highway_arena.launch_server() as server:
    env = highway_arena.parallel_env("merge", connect=server.endpoint)
    observations, infos = env.reset(seed=0)
    assert set(observations) == {"ec_0"}
    env.step({"ec_0": 1})
    env.close()
print("served by", binary)
"""


def test_launch_server_works_from_a_wheel_installed_into_a_fresh_venv_outside_the_repository(tmp_path):
    maturin = pathlib.Path(sys.executable).with_name("maturin")
    env = {**os.environ, "MATURIN": str(maturin)}
    # The server the suite runs (scripts/test-python builds it) goes into the wheel, and
    # the extension is built in the profile of that build (release), reusing its crates.
    server = env.pop("ARENA_SERVER")
    subprocess.run(
        [REPO / "scripts" / "build-wheel", "--profile", "release", "--out", tmp_path / "wheels", "--server", server],
        check=True,
        env=env,
        capture_output=True,
    )
    (wheel,) = (tmp_path / "wheels").glob("highway_arena-*.whl")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", venv], check=True)
    python = venv / "bin" / "python"
    subprocess.run(
        [python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", wheel], check=True, capture_output=True
    )
    # Outside the repository, with no arena-server on PATH and no $ARENA_SERVER.
    clean = {key: value for key, value in env.items() if key not in ("ARENA_SERVER", "VIRTUAL_ENV")}
    clean["PATH"] = f"{venv / 'bin'}:/usr/bin:/bin"
    run = subprocess.run([python, "-c", USE], cwd=tmp_path, env=clean, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "served by" in run.stdout
