"""What the package promises beyond PettingZoo's and Gymnasium's checks: clear errors
on bad input that never hang past the timeout, fresh arrays, idempotent close, timing."""

import inspect
import pathlib
import pickle
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import highway_arena
from conftest import SCENARIOS
from highway_arena._server import _free_port, find_server_binary

REPO = pathlib.Path(__file__).resolve().parents[2]


def test_no_server_at_the_address_raises_after_the_connect_timeout_naming_it_with_advice():
    # Lower bounds only (a loaded machine only adds to a wait): the client waits the connect
    # timeout it is given, and a longer one waits longer; it never waits the 10 s request
    # timeout (the upper bound leaves a loaded machine 5 s of slack).
    def waited(**options):
        started = time.monotonic()
        with pytest.raises(highway_arena.ServerNotFoundError, match="tcp/127.0.0.1:1 .*launch_server") as raised:
            highway_arena.parallel_env("merge", connect="tcp/127.0.0.1:1", **options)
        assert raised.value.code == "NoServer" and isinstance(raised.value, ConnectionError)
        return time.monotonic() - started

    assert 1.0 <= waited() < 6.0, "the default connect timeout, 1 s"
    assert 3.0 <= waited(connect_timeout=3.0) < 8.0, "connect_timeout sets the wait"
    with pytest.raises(ValueError, match="connect_timeout must be a positive number"):
        highway_arena.parallel_env("merge", connect="tcp/127.0.0.1:1", connect_timeout=-1)


def test_a_server_that_dies_gives_an_error_naming_it_at_once_and_close_stays_quiet():
    with highway_arena.launch_server() as doomed:
        env = highway_arena.parallel_env("merge", connect=doomed.endpoint)
        env.reset(seed=0)
        server_id = env.server
        doomed.process.send_signal(signal.SIGKILL)
        doomed.process.wait()
        started = time.monotonic()
        with pytest.raises(highway_arena.ServerGoneError, match=f"arena-server {server_id} is gone") as raised:
            env.step({"ec_0": 1})
        waited = time.monotonic() - started
        assert waited < 5.0, "not the whole 10 s timeout"
        reported = float(str(raised.value).split(" in ")[1].split(" s")[0])
        assert abs(reported - waited) < 0.5, (reported, waited)
        env.close()
        env.close()


def test_malformed_or_unusable_addresses_are_refused_with_the_form_to_use():
    with pytest.raises(highway_arena.InvalidEndpointError, match="e.g. tcp/127.0.0.1:7447"):
        highway_arena.parallel_env("merge", connect="not an endpoint", timeout=1.0)
    # Well formed, but this build of Zenoh speaks TCP only; no source paths in the message.
    with pytest.raises(ValueError, match=r"^cannot open a Zenoh session to udp/127.0.0.1:7447: [^/]*udp[^/]*; "):
        highway_arena.parallel_env("merge", connect="udp/127.0.0.1:7447", timeout=1.0)


def test_a_server_that_stops_answering_times_out_within_the_timeout_without_holding_the_gil():
    with highway_arena.launch_server() as stopped:
        # Each attempt waits `timeout`, and a call that got no reply is resent `retries`
        # times: the Rust client's and the CLI's meaning of both.
        env = highway_arena.parallel_env("merge", connect=stopped.endpoint, timeout=0.5, retries=2)
        env.reset(seed=0)
        stopped.process.send_signal(signal.SIGSTOP)
        try:
            outcome = {}

            def step():
                started = time.monotonic()
                try:
                    env.step({"ec_0": 1})
                except highway_arena.ArenaTimeoutError as error:
                    outcome["error"] = error
                outcome["waited"] = time.monotonic() - started

            stepper = threading.Thread(target=step)
            stepper.start()
            # While the step waits on the network, this thread keeps running Python.
            spins = 0
            while stepper.is_alive():
                spins += 1
                time.sleep(0.001)
            assert spins > 100
            assert isinstance(outcome.get("error"), TimeoutError), outcome
            assert "no reply" in str(outcome["error"])
            # Three attempts of 0.5 s, not a fourth (a loaded machine only adds to a wait).
            assert 3 * 0.5 <= outcome["waited"] < 4 * 0.5, outcome["waited"]
        finally:
            stopped.process.send_signal(signal.SIGCONT)
        env.close()


def test_unknown_scenario_names_the_ones_there_are():
    with pytest.raises(highway_arena.ScenarioError, match="merge, merge-ac, merge-duo, merge-random, merge-random-1hz, merge-random-1hz-v2, overtake"):
        highway_arena.parallel_env("nowhere")


def test_bad_override_is_refused_with_the_vehicle_named():
    with pytest.raises(highway_arena.ScenarioError, match="vehicle 'ec_0' is on lane 9"):
        highway_arena.parallel_env("merge", vehicle__ec_0__lane=9)


def test_an_override_key_that_once_crashed_the_server_is_refused_and_the_server_serves_on():
    # 15 000 parts, about 30 KB: on 07e7a7d this overflowed the server's stack.
    key = "a." * 15000 + "a"
    with pytest.raises(highway_arena.RequestTooLargeError, match="override key 'a.a.a"):
        highway_arena.parallel_env("merge", overrides={key: 1})
    env = highway_arena.parallel_env("merge")
    env.reset(seed=0)
    with pytest.raises(highway_arena.RequestTooLargeError, match="reset override key"):
        env.reset(seed=0, options={"overrides": {key: 1}})
    env.step({"ec_0": 1})
    env.close()


def test_inline_scenario_text_is_validated_like_a_file():
    with pytest.raises(highway_arena.ScenarioError, match="mine.toml"):
        highway_arena.parallel_env("mine.toml", scenario_text='name = "x"\n[road]\nlanes = 0\n')


def test_actions_outside_the_space_or_for_finished_agents_raise_value_errors():
    env = highway_arena.parallel_env("highway", max_cycles=3)
    env.reset(seed=0)
    # 7 is the server's to refuse, -1 the extension's (no u32 carries it): the same words.
    outside = "meta action {} is outside Discrete\\(5\\): use 0..=4"
    refused = [(7, outside.format(7)), (-1, outside.format(-1)), (1.5, "an int"), ("1", "an int"), (True, "an int")]
    refused.append(([1, [2, 3]], "an int"))
    for bad, message in refused:
        with pytest.raises(highway_arena.InvalidActionError, match=f"agent 'ego_0': .*{message}"):
            env.step({"ego_0": bad})
    with pytest.raises(highway_arena.InvalidActionError, match="^no agent named 'nobody'; the agents are: ego_0$"):
        env.step({"nobody": 1})
    # Ints of every kind: Python, numpy scalars, one-element numpy arrays.
    env.step({"ego_0": np.int64(1)})
    env.step({"ego_0": np.array([1], dtype=np.int32)})
    env.step({"ego_0": 1})
    assert env.agents == []
    with pytest.raises(highway_arena.InvalidActionError, match="env.agents") as raised:
        env.step({"ego_0": 1})
    assert raised.value.code == "AgentNotLive" and isinstance(raised.value, ValueError)
    env.close()


def test_continuous_actions_accept_lists_and_arrays_and_refuse_out_of_range():
    env = highway_arena.parallel_env("merge", action_type="continuous")
    env.reset(seed=0)
    env.step({"ec_0": [1.0, 0.0]})
    env.step({"ec_0": np.array([0.5, -0.5], dtype=np.float32)})
    env.step({"ec_0": (np.float64(0.1), 0)})
    with pytest.raises(highway_arena.InvalidActionError, match=r"has 3 components, but the space has shape \[2\]"):
        env.step({"ec_0": [0.0, 0.0, 0.0]})
    with pytest.raises(highway_arena.InvalidActionError, match="expected numbers"):
        env.step({"ec_0": "fast"})
    with pytest.raises(highway_arena.InvalidActionError, match="expected numbers"):
        env.step({"ec_0": [1.0, [2.0, 3.0]]})
    with pytest.raises(highway_arena.InvalidActionError, match=r"agent 'ec_0': component 0 is 50, outside \[-1, 1\]"):
        env.step({"ec_0": np.array([50.0, 0.0])})
    with pytest.raises(highway_arena.InvalidActionError, match="component 0 is NaN; it must be a finite number"):
        env.step({"ec_0": [float("nan"), 0.0]})
    env.close()


def test_a_batch_is_told_of_an_agent_its_env_does_not_have_by_the_server():
    batch = highway_arena.batch_env("merge", num_envs=2)
    batch.reset(seed=0)
    with pytest.raises(highway_arena.InvalidActionError, match="^no agent named 'nobody'; the agents are: ec_0$") as raised:
        batch.step([{"ec_0": 1}, {"nobody": 1}])
    assert raised.value.code == "UnknownAgent"
    batch.close()


def test_observations_are_fresh_arrays_and_spaces_are_cached():
    env = highway_arena.parallel_env("merge")
    first, _ = env.reset(seed=3)
    again, _ = env.reset(seed=3)
    assert first["ec_0"] is not again["ec_0"]
    first["ec_0"][:] = 9.0  # writable, and changing it changes nothing else
    assert np.array_equal(again["ec_0"], env.reset(seed=3)[0]["ec_0"])
    assert env.observation_space("ec_0") is env.observation_space("ec_0")
    assert env.action_space("ec_0") is env.action_space("ec_0")
    env.close()


def test_close_is_idempotent_and_timing_is_exposed():
    env = highway_arena.parallel_env("highway")
    assert env.dt == 1.0 and env.metadata["render_fps"] == 1
    env.close()
    env.close()
    with pytest.raises(highway_arena.EnvClosedError, match="closed"):
        env.reset(seed=0)
    aec = highway_arena.env("merge")
    assert aec.dt == pytest.approx(0.1) and aec.metadata["render_fps"] == 10 and aec.max_cycles == 200
    aec.close()
    aec.close()
    merge = highway_arena.gym_env("merge")
    assert merge.dt == pytest.approx(0.1) and merge.metadata["render_fps"] == 10
    merge.close()
    merge.close()


def test_expert_infos_carry_the_built_in_avs_choice():
    env = highway_arena.parallel_env("merge", expert="stackelberg")
    _, infos = env.reset(seed=0)
    assert infos["ec_0"]["expert_action"] in range(5)
    assert infos["ec_0"]["expert_sigma"] in (-1, 0)
    env.close()


def test_a_pickled_env_rebuilds_its_own_connection():
    env = highway_arena.parallel_env("merge")
    copy = pickle.loads(pickle.dumps(env))
    a, _ = env.reset(seed=5)
    b, _ = copy.reset(seed=5)
    assert np.array_equal(a["ec_0"], b["ec_0"])
    env.close()
    copy.close()


def test_batch_env_matches_single_envs():
    batch = highway_arena.batch_env("highway", num_envs=3)
    starts = batch.reset(seed=10)
    single = highway_arena.parallel_env("highway")
    first, first_infos = single.reset(seed=11)
    assert len(starts) == 3 and all(len(start) == 2 for start in starts), "(observations, infos) per env"
    assert np.array_equal(starts[1][0]["ego_0"], first["ego_0"]) and starts[1][1] == first_infos
    results = batch.step([{"ego_0": 3}] * 3)
    expected = single.step({"ego_0": 3})
    assert np.array_equal(results[1][0]["ego_0"], expected[0]["ego_0"])
    assert results[1][1:] == expected[1:]
    batch.close()
    single.close()


def test_threads_sharing_an_env_take_turns():
    env = highway_arena.parallel_env("highway")
    env.reset(seed=0)
    errors = []

    def run(call, times):
        try:
            for _ in range(times):
                call()
        except Exception as error:  # reported below
            errors.append(error)

    threads = [threading.Thread(target=run, args=(lambda: env.step({"ego_0": 1}), 10))]
    threads += [threading.Thread(target=run, args=(env.state, 100)) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    assert not any(thread.is_alive() for thread in threads) and not errors
    env.close()


def test_a_batch_naming_one_env_twice_is_refused():
    batch = highway_arena.batch_env("merge", num_envs=1)
    batch.reset(seed=0)
    env = batch._envs[0]
    with pytest.raises(ValueError, match="twice"):
        batch._connection.client.step_batch([env, env], [{}, {}])
    batch.close()


def test_launch_server_reports_a_missing_binary(monkeypatch):
    named = "binary= '/nonexistent/arena-server' is not an executable file"
    with pytest.raises(FileNotFoundError, match=named), highway_arena.launch_server(binary="/nonexistent/arena-server"):
        pass
    monkeypatch.setenv("ARENA_SERVER", "/nonexistent/arena-server")
    with pytest.raises(FileNotFoundError, match=r"\$ARENA_SERVER '/nonexistent/arena-server' is not an executable"):
        highway_arena.find_server_binary()


def test_connection_defaults_are_the_protocol_crates():
    from highway_arena import _connection, _core

    assert (_core.DEFAULT_CONNECT, _core.DEFAULT_PREFIX, _core.DEFAULT_TIMEOUT) == ("tcp/127.0.0.1:7447", "arena", 10.0)
    assert _connection.DEFAULT_CONNECT is _core.DEFAULT_CONNECT
    assert _connection.DEFAULT_TIMEOUT is _core.DEFAULT_TIMEOUT
    defaults = highway_arena.CONNECTION_KEYWORDS
    assert defaults["prefix"] is _core.DEFAULT_PREFIX and defaults["timeout"] is _core.DEFAULT_TIMEOUT
    assert defaults["connect_timeout"] is _core.DEFAULT_CONNECT_TIMEOUT


def test_reset_options_set_scenario_keys_for_one_episode_and_unknown_keys_are_refused():
    env = highway_arena.parallel_env("merge")
    _, infos = env.reset(seed=0, options={"overrides": {"vehicle.ec_0.speed": 23.0}})
    assert infos["ec_0"]["speed"] == 23.0
    _, infos = env.reset(seed=0)
    assert infos["ec_0"]["speed"] == 20.0
    with pytest.raises(highway_arena.ScenarioError, match="overides"):
        env.reset(seed=0, options={"overides": {"vehicle.ec_0.speed": 23.0}})
    with pytest.raises(highway_arena.ScenarioError, match="nobody"):
        env.reset(seed=0, options={"overrides": {"vehicle.nobody.speed": 23.0}})
    env.close()


def test_diagnostics_on_request_count_every_game_theoretic_cars_plans():
    env = highway_arena.parallel_env("highway-gt", diagnostics=True, max_cycles=3)
    _, infos = env.reset(seed=1)
    _, _, _, _, infos = env.step({})
    info = infos["ego_0"]
    cars = sorted({key.split(".")[1] for key in info if key.startswith("gt.")})
    assert len(cars) == 8, cars  # highway-gt's eight game-theoretic cars
    # One env step is one simulated second: ten control periods, one plan each.
    assert all(info[f"gt.{car}.plans"] == 10 for car in cars), info
    # Interior-point iterations: 0 for a QP solved directly (no bound active, lane keeping).
    assert all(info[f"gt.{car}.qp_iterations_total"] >= info[f"gt.{car}.qp_iterations"] >= 0 for car in cars)
    assert all(info[f"gt.{car}.fallbacks"] == 0 for car in cars), info
    env.close()
    plain = highway_arena.parallel_env("highway-gt", max_cycles=3)
    _, infos = plain.reset(seed=1)
    assert not any(key.startswith("gt.") for key in infos["ego_0"])
    plain.close()


def _start(args, banner_has):
    """An arena-server process started from the repository's root (deploy/ paths are
    relative to it), once its banner says ``banner_has``."""
    process = subprocess.Popen([find_server_binary(None), *args], cwd=REPO, stdout=subprocess.PIPE, text=True)
    banner = process.stdout.readline()
    if banner_has not in banner:
        _stop(process)
        raise AssertionError(f"{args}: {banner!r}")
    return process


def _stop(process):
    process.kill()
    process.wait()
    process.stdout.close()


def test_a_deployment_with_credentials_serves_only_who_logs_in():
    router = f"tcp/127.0.0.1:{_free_port()}"
    route = ["--mode", "router", "--route-only", "--zenoh-config", "deploy/auth/router.json5", "--listen", router]
    serve = ["--mode", "client", "--connect", router, "--zenoh-config", "deploy/auth/server.json5"]
    processes = [_start(route, "routing only")]
    try:
        processes.append(_start(serve, "serving through"))
        client_config = REPO / "deploy/auth/client.json5"
        env = highway_arena.parallel_env(
            "merge", connect=router, mode="client", zenoh_config=client_config, connect_timeout=5.0
        )
        observations, _ = env.reset(seed=0)
        assert list(observations) == ["ec_0"]
        env.close()
        with pytest.raises(highway_arena.ServerNotFoundError, match="credentials .*zenoh_config="):
            highway_arena.parallel_env("merge", connect=router, mode="client")
        with pytest.raises(ValueError, match="zenoh_config .*nowhere.json5 is not a file"):
            highway_arena.parallel_env("merge", connect=router, zenoh_config="nowhere.json5")
        with pytest.raises(ValueError, match="mode must be peer, client or router"):
            highway_arena.parallel_env("merge", connect=router, mode="relay")
    finally:
        for process in processes:
            _stop(process)


def test_a_vector_env_through_a_router_spreads_over_every_server_with_the_same_results():
    router = f"tcp/127.0.0.1:{_free_port()}"
    processes = [_start(["--mode", "router", "--route-only", "--listen", router], "routing only")]
    try:
        for _ in range(3):
            processes.append(_start(["--mode", "client", "--connect", router], "serving through"))
        watcher = highway_arena._core.Client([router], mode="client")
        deadline = time.monotonic() + 10
        while len(watcher.servers()) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        watcher.close()
        spread = highway_arena.vector_env("merge-random", num_envs=6, connect=router, mode="client", connect_timeout=5.0)
        assert len(set(spread.servers)) == 3, spread.servers
        assert sorted(spread.servers.count(s) for s in set(spread.servers)) == [2, 2, 2]
        local = highway_arena.vector_env("merge-random", num_envs=6)
        assert len(set(local.servers)) == 1
        seeds = list(range(10, 16))
        for env in (spread, local):
            env.action_space.seed(3)
        a, _ = spread.reset(seed=seeds)
        b, _ = local.reset(seed=seeds)
        np.testing.assert_array_equal(a, b)
        for _ in range(20):
            actions = spread.action_space.sample()
            a, ra, ta, ua, _ = spread.step(actions)
            b, rb, tb, ub, _ = local.step(actions)
            np.testing.assert_array_equal(a, b)
            np.testing.assert_array_equal(ra, rb)
            np.testing.assert_array_equal(ta, tb)
            np.testing.assert_array_equal(ua, ub)
        spread.close()
        local.close()
    finally:
        for process in processes:
            _stop(process)


def test_an_unknown_keyword_is_refused_naming_it_and_the_valid_ones():
    with pytest.raises(TypeError, match=r"\['expret'\].*its keywords are .*max_cycles.*vehicle__ac__speed"):
        highway_arena.parallel_env("merge", expret=0.5)
    with pytest.raises(TypeError, match=r"\['episode'\]"):
        highway_arena.evaluate(["idle"], "merge", episodes=1, episode=2, quiet=True)
    # The documented override forms still reach the scenario.
    env = highway_arena.parallel_env("merge", vehicle__ec_0__speed=23.0, overrides={"vehicle.ac.speed": 16.0})
    _, infos = env.reset(seed=0)
    assert infos["ec_0"]["speed"] == 23.0
    env.close()


# Every public constructor, with what it needs besides keywords; the name its errors give;
# one keyword of its own its list of valid keywords must show.
CONSTRUCTORS = {
    "parallel_env": (lambda tmp, **kw: highway_arena.parallel_env("merge", **kw), "parallel_env", "render_mode"),
    "env": (lambda tmp, **kw: highway_arena.env("merge", **kw), "parallel_env", "max_cycles"),
    "gym_env": (lambda tmp, **kw: highway_arena.gym_env("merge", **kw), "gym_env", "agent"),
    "batch_env": (lambda tmp, **kw: highway_arena.batch_env("merge", num_envs=2, **kw), "batch_env", "num_envs"),
    "vector_env": (
        lambda tmp, **kw: highway_arena.vector_env("merge", num_envs=2, **kw),
        "vector_env",
        "autoreset_mode",
    ),
    "ParallelEnv": (lambda tmp, **kw: highway_arena.ParallelEnv("merge", **kw), "parallel_env", "seed"),
    "GymEnv": (lambda tmp, **kw: highway_arena.GymEnv("merge", **kw), "gym_env", "agent"),
    "BatchEnv": (lambda tmp, **kw: highway_arena.BatchEnv("merge", num_envs=2, **kw), "batch_env", "scenario_text"),
    "VectorEnv": (lambda tmp, **kw: highway_arena.VectorEnv("merge", num_envs=2, **kw), "vector_env", "agent"),
    "record": (
        lambda tmp, **kw: highway_arena.record("merge", 1, path=tmp, progress=False, **kw),
        "record",
        "episodes",
    ),
}
ENVS = [name for name in CONSTRUCTORS if name != "record"]


@pytest.mark.parametrize("name", CONSTRUCTORS)
def test_every_constructor_refuses_an_unknown_keyword_before_connecting_naming_it_and_the_valid_ones(name, tmp_path):
    build, reported, own = CONSTRUCTORS[name]
    # Nothing listens at this endpoint: the keyword is refused before any connection.
    with pytest.raises(TypeError) as raised:
        build(tmp_path, connect="tcp/127.0.0.1:1", connect_timeout=0.3, expret=0.5)
    message = str(raised.value)
    assert message.startswith(f"{reported}() got unexpected keyword argument(s) ['expret']; its keywords are "), message
    valid = message.split("its keywords are ")[1].split(";")[0].split(", ")
    assert own in valid and set(highway_arena.CONNECTION_KEYWORDS) <= set(valid), valid


@pytest.mark.parametrize("name", ["batch_env", "vector_env"])
def test_batch_and_vector_envs_take_both_override_forms(name):
    build, _, _ = CONSTRUCTORS[name]
    envs = build(None, vehicle__ec_0__speed=23.0, overrides={"vehicle.ac.speed": 16.0})
    if name == "batch_env":
        speeds = [infos["ec_0"]["speed"] for _, infos in envs.reset(seed=0)]
    else:
        speeds = list(envs.reset(seed=0)[1]["speed"])
    assert speeds == [23.0, 23.0]
    envs.close()


# One wrong value for each connection keyword, and the error that shows the value reached
# the connection (had the keyword been dropped, the env would connect to the suite's server).
WRONG_CONNECTION = {
    "connect": ("tcp/127.0.0.1:1", highway_arena.ServerNotFoundError, r"^no arena-server answered at tcp/127.0.0.1:1 "),
    "prefix": ("nowhere", highway_arena.ServerNotFoundError, r"\(prefix 'nowhere'\)"),
    "timeout": (0, ValueError, r"^timeout must be a positive number of seconds"),
    "retries": (-1, ValueError, r"^retries must be a whole number"),
    "connect_timeout": (-1, ValueError, r"^connect_timeout must be a positive number of seconds"),
    "zenoh_config": ("nowhere.json5", ValueError, r"^zenoh_config nowhere.json5 is not a file"),
    "mode": ("relay", ValueError, r"^mode must be peer, client or router"),
}


def test_every_connection_keyword_has_a_wrong_value_case():
    assert list(WRONG_CONNECTION) == list(highway_arena.CONNECTION_KEYWORDS)


@pytest.mark.parametrize("keyword", WRONG_CONNECTION)
@pytest.mark.parametrize("name", CONSTRUCTORS)
def test_every_constructor_passes_each_connection_keyword_on(name, keyword, tmp_path):
    build, _, _ = CONSTRUCTORS[name]
    value, error, message = WRONG_CONNECTION[keyword]
    quick = {} if keyword == "connect_timeout" else {"connect_timeout": 0.3}
    with pytest.raises(error, match=message):
        build(tmp_path, **{**quick, keyword: value})


@pytest.mark.parametrize("name", ENVS)
def test_every_env_constructor_takes_all_the_connection_keywords_and_shows_them(name, server, tmp_path):
    build, _, _ = CONSTRUCTORS[name]
    parameters = inspect.signature(getattr(highway_arena, name)).parameters
    for keyword, default in highway_arena.CONNECTION_KEYWORDS.items():
        assert parameters[keyword].default == default, (name, keyword)
    config = tmp_path / "peer.json5"
    config.write_text("{}\n")
    settings = dict(
        connect=server.endpoint,
        prefix=highway_arena.CONNECTION_KEYWORDS["prefix"],
        timeout=5.0,
        retries=1,
        connect_timeout=2.0,
        zenoh_config=config,
        mode="peer",
    )
    assert set(settings) == set(highway_arena.CONNECTION_KEYWORDS)
    env = build(tmp_path, **settings)
    env.reset(seed=0)
    env.close()


def test_a_learner_that_runs_into_the_slow_car_is_told_whom_it_hit_and_that_it_was_at_fault():
    # overtake: idle (keep lane, keep speed) drives ec_0 into the slow car lc. Named
    # vehicles are indexed by name: ac1 0, ac2 1, ec_0 2, lc 3 (docs/protocol.md).
    env = highway_arena.parallel_env("overtake")
    _, infos = env.reset(seed=0)
    assert (infos["ec_0"]["collision_with"], infos["ec_0"]["at_fault"]) == (-1, 0)
    while env.agents:
        _, _, _, _, infos = env.step({"ec_0": 1})
    info = infos["ec_0"]
    assert highway_arena.END_REASONS[info["end_reason"]] == "collision"
    assert (info["collision_with"], info["at_fault"]) == (3, 1)
    env.close()


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_every_agents_infos_keep_one_schema_of_numbers_from_reset_to_the_last_step(scenario):
    # What TorchRL and Tianshou need (scripts/test-ecosystem runs them): the keys, types
    # and order of reset's infos on every step, scalars only, never NaN.
    env = highway_arena.parallel_env(scenario, max_cycles=30, expert="nash")
    _, infos = env.reset(seed=1)
    first = {agent: [(key, type(value)) for key, value in info.items()] for agent, info in infos.items()}
    for agent, keys in first.items():
        assert [key for key, _ in keys[: len(highway_arena.INFO_KEYS)]] == highway_arena.INFO_KEYS, agent
    ended = {}
    while env.agents:
        _, _, terminations, truncations, infos = env.step({a: 1 for a in env.agents})
        for agent, info in infos.items():
            assert [(key, type(value)) for key, value in info.items()] == first[agent], agent
            assert all(isinstance(v, (bool, int, float)) and v == v for v in info.values() if not isinstance(v, list))
            reason = highway_arena.END_REASONS[info["end_reason"]]
            done = terminations[agent] or truncations[agent]
            assert info["episode_done"] == done and (reason != "running") == done, (agent, reason)
            if done:
                ended[agent] = reason
    assert set(ended) == set(env.possible_agents)
    env.close()


SUMMARY = ["end_reason", "episode_done", "episode_success", "episode_return"]


def test_info_keys_keep_only_the_named_keys_on_every_step_and_the_default_keeps_the_schema():
    sparse = highway_arena.vector_env("merge", num_envs=2, max_cycles=5, info_keys=list(reversed(SUMMARY)))
    full = highway_arena.vector_env("merge", num_envs=2, max_cycles=5)
    # In the schema's order, whatever the order asked; Gymnasium adds each key's mask.
    named = SUMMARY + [f"_{key}" for key in SUMMARY]
    _, infos = sparse.reset(seed=0)
    assert sorted(infos) == sorted(named), list(infos)
    _, full_infos = full.reset(seed=0)
    assert [key for key in full_infos if not key.startswith("_")][: len(highway_arena.INFO_KEYS)] == (
        highway_arena.INFO_KEYS
    )
    for _ in range(5):
        _, _, _, _, infos = sparse.step(np.array([1, 1]))
        _, _, _, _, full_infos = full.step(np.array([1, 1]))
        assert [key for key in infos if not key.startswith("_")] == SUMMARY
        for key in SUMMARY:
            assert np.array_equal(infos[key], full_infos[key]), key
    assert infos["episode_done"].all() and (infos["episode_return"] > 0).all()
    sparse.close()
    full.close()


def test_the_env_options_are_the_protocols_create_options_but_the_two_taken_their_own_way():
    assert list(highway_arena.ENV_OPTIONS) == [
        "action_type",
        "observation",
        "max_cycles",
        "render_size",
        "expert",
        "policy",
        "diagnostics",
        "explain",
        "render_window",
        "info_keys",
    ]
    assert highway_arena.ENV_OPTIONS["max_cycles"] is None and highway_arena.ENV_OPTIONS["explain"] is False


# One wrong value for each env option that is not a flag, and the error that shows the
# value reached the extension or the server (had the keyword been dropped, the env would
# be made). The flags are shown by what they do (diagnostics, explain: their own tests).
WRONG_OPTION = {
    "action_type": ("sideways", ValueError, r"^action_type: unknown action type 'sideways': use one of meta, continuous"),
    "observation": ("pixels", ValueError, r"^observation: unknown observation 'pixels'"),
    "max_cycles": (0, highway_arena.ScenarioError, r"max_cycles must be at least 1"),
    "render_size": ((8, 8), highway_arena.ScenarioError, r"render_size \(8, 8\) must be within 16..=4096"),
    "expert": ("pareto", ValueError, r"^expert: unknown game 'pareto': use one of nash, stackelberg"),
    "policy": ("calm", ValueError, r"^policy: unknown built-in policy 'calm'"),
    "render_window": (5, highway_arena.ScenarioError, r"render_window 5 must be within 10..=10000 \(m\)"),
    "info_keys": (["sped"], highway_arena.ScenarioError, r"info_keys: no info key 'sped'; the keys are speed, lane"),
}


def test_every_env_option_but_the_flags_has_a_wrong_value_case():
    flags = [name for name, default in highway_arena.ENV_OPTIONS.items() if default is False]
    assert flags == ["diagnostics", "explain"]
    assert list(WRONG_OPTION) == [name for name in highway_arena.ENV_OPTIONS if name not in flags]


@pytest.mark.parametrize("option", WRONG_OPTION)
@pytest.mark.parametrize("name", ENVS)
def test_every_env_constructor_passes_each_env_option_on_and_shows_it(name, option, tmp_path):
    build, _, _ = CONSTRUCTORS[name]
    constructor = getattr(highway_arena, name)
    assert inspect.signature(constructor).parameters[option].default is None, (name, option)
    assert f"- ``{option}`` (" in constructor.__doc__, (name, option)
    value, error, message = WRONG_OPTION[option]
    with pytest.raises(error, match=message):
        build(tmp_path, **{option: value})


def test_a_create_option_of_the_wrong_type_is_refused_naming_it():
    with pytest.raises(TypeError, match=r"^render_size takes two whole numbers, not str"):
        highway_arena.parallel_env("merge", render_size="large")
    with pytest.raises(ValueError, match=r"^max_cycles: -1 is not a whole number from 0 to 4294967295"):
        highway_arena.parallel_env("merge", max_cycles=-1)


def test_the_python_readme_lists_the_env_options_as_the_protocols_table_says():
    readme = (REPO / "clients" / "python" / "README.md").read_text()
    begin = "<!-- env options: written from highway_arena.ENV_OPTIONS, checked by tests/python/test_client.py -->\n"
    listed = readme.split(begin)[1].split("<!-- end of the env options -->")[0]
    expected = "".join(
        f"  - `{name}` ({takes}): {doc}\n"
        for name, _, takes, doc in highway_arena._core.CREATE_OPTIONS
        if name in highway_arena.ENV_OPTIONS
    )
    assert listed == expected, f"clients/python/README.md's env options should be:\n{expected}"
