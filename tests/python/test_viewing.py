"""Recordings, read back by Rerun's own loader (``rerun.chunk.RrdReader`` and its
DataFusion reader): a recording of merge-random holds the road, every vehicle at every
control period, every agent's rows, and the values the env reported at a known time;
recording starts mid-episode and stops; episodes follow one another on the timeline;
``python -m highway_arena.view --summary`` reads the file without a server."""

import pathlib
import subprocess
import sys

import numpy as np
import pytest
import rerun as rr

import highway_arena
from highway_arena import recording, view

IDLE = 1


def table(path, index=recording.TIMELINE):
    store = rr.chunk.RrdReader(str(path)).stream().collect()
    return store.reader(index=index).to_pandas()


def present(column):
    """Rows where ``column`` holds a value (a clear leaves an empty list)."""
    return column.map(lambda value: value is not None and len(value) > 0)


def times_of(frame, column):
    """Simulated seconds of the rows where ``column`` holds a value."""
    return frame.loc[present(frame[column]), recording.TIMELINE].dt.total_seconds().to_numpy()


def at(frame, time_s, column):
    """The value of ``column`` in the row at ``time_s`` (simulated seconds)."""
    times = frame[recording.TIMELINE].dt.total_seconds().to_numpy()
    rows = frame[np.isclose(times, time_s) & present(frame[column])]
    assert len(rows) == 1, f"{column} at {time_s}: {len(rows)} rows"
    return rows[column].iloc[0]


def test_a_recording_of_merge_random_holds_the_road_every_vehicle_and_what_the_env_said(tmp_path):
    path = tmp_path / "merge.rrd"
    env = highway_arena.parallel_env("merge-random", record=path)
    observations, infos = env.reset(seed=3)
    said = {0: (infos["ec_0"]["speed"], infos["ec_0"]["s"], None)}
    steps = 0
    end = None
    while env.agents:
        _, rewards, terminations, truncations, infos = env.step({"ec_0": IDLE})
        steps += 1
        said[steps] = (infos["ec_0"]["speed"], infos["ec_0"]["s"], rewards["ec_0"])
        if terminations["ec_0"] or truncations["ec_0"]:
            end = highway_arena.END_REASONS[infos["ec_0"]["end_reason"]]
    env.close()  # closing writes what is pending and ends the file
    assert end is not None

    store = rr.chunk.RrdReader(str(path)).stream().collect()
    static = store.reader(index=None).to_pandas()
    assert static["/meta:format"].iloc[0][0] == recording.FORMAT
    assert static["/meta:format_version"].iloc[0][0] == recording.FORMAT_VERSION
    assert static["/meta:protocol"].iloc[0][0] == highway_arena._core.PROTOCOL_VERSION
    assert list(static["/meta:agents"].iloc[0]) == ["ec_0"]

    frame = table(path)
    columns = set(frame.columns)
    # The road: merge-random's two lanes, the right one ending (its end marked).
    for lane in ("lane_0", "lane_1"):
        assert f"/world/road/{lane}:LineStrips2D:strips" in columns, lane
        assert f"/world/road/{lane}/edges:LineStrips2D:strips" in columns, lane
    assert "/world/road/lane_1/end:LineStrips2D:strips" in columns
    assert "/world/road/lane_0/end:LineStrips2D:strips" not in columns
    # Every vehicle, drawn and with its state, at every control period: the reset's
    # frame and one per step (merge-random steps one 0.1 s control period).
    for vehicle in ("ac", "ec_0"):
        for part in ("LineStrips2D:strips", "x", "y", "heading", "speed", "lane", "end"):
            assert f"/world/vehicles/{vehicle}:{part}" in columns, (vehicle, part)
        assert len(times_of(frame, f"/world/vehicles/{vehicle}:x")) == steps + 1, vehicle
    times = times_of(frame, "/world/vehicles/ec_0:x")
    assert np.allclose(times, np.arange(steps + 1) * 0.1)
    # The step timeline counts env steps: the reset's frame is step 0.
    steps_of = frame.loc[present(frame["/world/vehicles/ec_0:x"]), recording.STEP_TIMELINE].to_numpy()
    assert list(steps_of) == list(range(steps + 1))
    # At a known time the file says what the env said.
    for k in (0, 7, steps):
        speed, s, reward = said[k]
        assert at(frame, k * 0.1, "/world/vehicles/ec_0:speed")[0] == speed
        assert at(frame, k * 0.1, "/world/vehicles/ec_0:s")[0] == s
        if reward is not None:
            assert at(frame, k * 0.1, "/agents/ec_0:reward")[0] == reward
            assert at(frame, k * 0.1, "/plots/reward/ec_0:Scalars:scalars")[0] == reward
    # Every step's action and the paper's three costs, per agent.
    assert len(times_of(frame, "/agents/ec_0:action")) == steps
    assert list(at(frame, 0.5, "/agents/ec_0:action")) == [IDLE]
    assert at(frame, 0.5, "/agents/ec_0:info.speed")[0] == said[5][0]
    for part in ("safety", "comfort", "efficiency"):
        assert len(times_of(frame, f"/plots/cost/ec_0/{part}:Scalars:scalars")) == steps + 1
    # Where and why the episode ended, when it did.
    label = at(frame, steps * 0.1, "/events/ends/ec_0:Points2D:labels")
    assert label[0] == f"ec_0: {end}"


def test_recording_starts_mid_episode_stops_and_episodes_follow_one_another(tmp_path):
    env = highway_arena.parallel_env("merge")
    env.reset(seed=0)
    for _ in range(5):
        env.step({"ec_0": IDLE})
    first = tmp_path / "mid.rrd"
    env.start_recording(first)
    for _ in range(3):
        env.step({"ec_0": IDLE})
    env.reset(seed=1)
    for _ in range(2):
        env.step({"ec_0": IDLE})
    assert env.stop_recording() == str(first)
    env.step({"ec_0": IDLE})  # no longer recorded
    env.close()

    frame = table(first)
    times = times_of(frame, "/world/vehicles/ec_0:x")
    # Episode 1 from t = 0.5 s (the world when recording began) to 0.8 s; episode 2 then
    # starts one step after it on the recording's timeline, and runs 0.2 s.
    assert np.allclose(times, [0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1])
    held = view.summary(first)
    assert held["episodes"] == 2
    assert held["vehicles"] == ["ac", "ec_0"]
    assert held["frames"] == 7
    assert held["lanes"] == 2


def test_highway_gt_records_every_vehicle_every_control_period(tmp_path):
    path = tmp_path / "highway.rrd"
    env = highway_arena.parallel_env("highway-gt", record=path)
    env.reset(seed=0)
    for _ in range(3):
        env.step({"ego_0": IDLE})
    env.close()
    held = view.summary(path)
    assert len(held["vehicles"]) == 51
    assert held["frames"] == 31  # the reset's frame, then 10 per one-second step
    assert held["duration"] == pytest.approx(3.0)


def test_the_view_command_reads_a_recording_without_a_server(tmp_path):
    path = tmp_path / "one.rrd"
    env = highway_arena.parallel_env("overtake", record=path)
    env.reset(seed=0)
    env.step({"ec_0": IDLE})
    env.close()
    done = subprocess.run(
        [sys.executable, "-m", "highway_arena.view", str(path), "--summary"], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "overtake" in done.stdout and "2 frames" in done.stdout
    other = tmp_path / "other.rrd"
    stream = rr.RecordingStream("not-arena")
    stream.save(str(other))
    stream.log("x", rr.Points2D([[0, 0]]), static=True)
    stream.flush()
    del stream
    done = subprocess.run(
        [sys.executable, "-m", "highway_arena.view", str(other), "--summary"], capture_output=True, text=True
    )
    assert done.returncode == 2 and "not a highway-arena recording" in done.stderr


def test_recording_needs_somewhere_to_go():
    with pytest.raises(ValueError, match="somewhere to go"):
        recording.Recording()


def test_continuous_agents_and_expert_infos_record_beside_meta_ones(tmp_path):
    # Rerun keeps one type per value name in a process: a continuous agent's action and
    # expert_action (two floats) must record after a meta agent's (ints) did.
    for action_type, action in (("meta", IDLE), ("continuous", [0.25, 0.0])):
        path = tmp_path / f"{action_type}.rrd"
        env = highway_arena.parallel_env("merge", action_type=action_type, expert="nash", record=path)
        env.reset(seed=0)
        for _ in range(3):
            env.step({"ec_0": action})
        env.close()
        frame = table(path)
        assert list(at(frame, 0.2, "/agents/ec_0:action")) == list(np.asarray(action, dtype=float).reshape(-1))
        assert len(at(frame, 0.2, "/agents/ec_0:info.expert_action")) == (1 if action_type == "meta" else 2)


def test_a_collision_is_recorded_where_and_when_it_happened(tmp_path):
    # overtake, the learner holding "faster" behind the slow car: it runs into it.
    path = tmp_path / "crash.rrd"
    env = highway_arena.parallel_env("overtake", record=path)
    env.reset(seed=0)
    infos = {}
    while env.agents:
        _, _, _, _, infos = env.step({"ec_0": 3})
    env.close()
    assert highway_arena.END_REASONS[infos["ec_0"]["end_reason"]] == "collision"
    frame = table(path)
    when = times_of(frame, "/events/collisions:Points2D:labels")
    assert len(when) == 1
    label = at(frame, when[0], "/events/collisions:Points2D:labels")[0]
    assert label.startswith("collision ec_0 / ") or " / ec_0 " in label, label
    # Between the two frames around it, and where the learner was then.
    frames = times_of(frame, "/world/vehicles/ec_0:x")
    after = frames[frames >= when[0] - 1e-9][0]
    assert after - when[0] < 0.1
    (x, y) = at(frame, when[0], "/events/collisions:Points2D:positions")[0]
    ego = at(frame, after, "/world/vehicles/ec_0:x")[0], at(frame, after, "/world/vehicles/ec_0:y")[0]
    assert np.hypot(x - ego[0], y - ego[1]) < 6.0, ((x, y), ego)


class _Model:
    """A Stable-Baselines3-shaped policy: predict(observation, deterministic) -> (action, state)."""

    def __init__(self):
        self.calls = 0

    def predict(self, observation, deterministic=True):
        self.calls += 1
        return IDLE, None


def test_play_drives_a_trained_policy_into_a_recording_the_same_as_stepping_by_hand(tmp_path):
    model = _Model()
    path = tmp_path / "played.rrd"
    returns = highway_arena.play(model, "merge", episodes=2, seed=4, record=path, max_cycles=12)
    assert model.calls == 24, "the model chose every action of both episodes"
    by_hand = highway_arena.parallel_env("merge", max_cycles=12)
    for played, seed in zip(returns, (4, 5)):
        by_hand.reset(seed=seed)
        total = 0.0
        while by_hand.agents:
            total += by_hand.step({"ec_0": IDLE})[1]["ec_0"]
        assert played == {"ec_0": total}
    by_hand.close()
    held = view.summary(path)
    assert held["episodes"] == 2 and held["vehicles"] == ["ac", "ec_0"]
    # A built-in driver plays in the server; a bad policy is refused.
    assert highway_arena.play("expert", "merge", max_cycles=5)[0]["ec_0"] != 0.0
    with pytest.raises(TypeError, match="policy must be"):
        highway_arena.play(42, "merge")


def test_batch_and_vector_envs_record_each_env_into_its_own_file(tmp_path):
    # merge with max_cycles 4: every env ends its first episode on the 4th step and is
    # reset by the batch (auto-reset), so each file holds two episodes.
    batch = highway_arena.batch_env("merge-random", num_envs=2, max_cycles=4, record=tmp_path / "batch")
    batch.reset(seed=3)
    for _ in range(6):
        batch.step([{"ec_0": IDLE}, {"ec_0": IDLE}])
    paths = batch.stop_recording()
    batch.step([{"ec_0": IDLE}, {"ec_0": IDLE}])  # no longer recorded
    batch.close()
    assert [pathlib.Path(p).name for p in paths] == ["env-000.rrd", "env-001.rrd"]
    for i, path in enumerate(paths):
        held = view.summary(path)
        assert held["episodes"] == 2 and held["vehicles"] == ["ac", "ec_0"]
        # The reset's frame and 4 steps, then the second episode's reset and 2 steps.
        assert held["frames"] == 1 + 4 + 1 + 2, path
        seeds = table(path)["/episode:seed"].dropna().map(lambda v: int(v[0])).tolist()
        assert seeds[0] == 3 + i, "env i is seeded seed + i"

    vector = highway_arena.vector_env("merge-random", num_envs=2, max_cycles=4)
    vector.reset(seed=5)
    vector.start_recording(tmp_path / "vector")
    for _ in range(3):
        vector.step(np.array([IDLE, IDLE]))
    paths = vector.stop_recording()
    vector.close()
    for path in paths:
        held = view.summary(path)
        assert (held["episodes"], held["frames"]) == (1, 1 + 3), "begun after the reset: the world then, 3 steps"


def blueprint_of(path):
    """The file's layout: per view, (class, name, origin); and the time panel's timeline."""
    reader = rr.chunk.RrdReader(str(path))
    (store,) = reader.blueprints()
    views, timeline = [], None
    for chunk in reader.stream(store=store):
        batch = chunk.to_record_batch()
        names = batch.schema.names

        def first(column):
            return batch.column(column)[0].as_py()[0] if column in names else None

        if "ViewBlueprint:class_identifier" in names:
            views.append(
                (
                    first("ViewBlueprint:class_identifier"),
                    first("ViewBlueprint:display_name"),
                    first("ViewBlueprint:space_origin"),
                )
            )
        if "TimePanelBlueprint:timeline" in names:
            timeline = first("TimePanelBlueprint:timeline")
    return views, timeline


def test_the_road_view_follows_a_car_at_every_frame_and_each_explained_car_has_its_panel(tmp_path):
    # Issue 45: a whole-episode recording opened on an empty road (a fixed window where
    # the first frame was); the panel showed one line of its table.
    for follow, followed in ((None, "ac_0"), ("ec", "ec")):
        path = tmp_path / f"merge-ac-{followed}.rrd"
        env = highway_arena.parallel_env("merge-ac", explain=True, record=path, render_follow=follow)
        env.reset(seed=5)
        env.reset(seed=6)  # a second episode follows on the same timeline
        while env.agents:
            env.step({"ac_0": IDLE})
        env.close()
        frame = table(path)
        follows = "/world/follow:Transform3D:translation"
        car = f"/world/vehicles/{followed}"
        # At every frame of both episodes, the view's frame is on the followed car.
        times = times_of(frame, f"{car}:x")
        assert np.array_equal(times_of(frame, follows), times)
        for time_s in times[:: max(1, len(times) // 25)]:
            x, y, _ = np.asarray(at(frame, time_s, follows)[0])
            where = (at(frame, time_s, f"{car}:x")[0], at(frame, time_s, f"{car}:y")[0])
            assert (x, y) == pytest.approx(where, abs=1e-3)  # a transform is float32
        views, timeline = blueprint_of(path)
        assert ("2D", "road", "/world/follow") in views
        # One text view per explained car: a text view shows one document.
        assert ("TextDocument", "ec explained", "/explain/ec") in views
        assert timeline == recording.TIMELINE


def test_the_summary_reads_what_the_whole_file_holds(tmp_path, monkeypatch):
    # The summary reads only the chunks it needs; it must say what a full read of the
    # file (Rerun's DataFusion reader) says, compacted or not, over several episodes.
    def full_read(path):
        static = rr.chunk.RrdReader(str(path)).stream().collect().reader(index=None).to_pandas()
        frame = table(path)
        vehicles = sorted(
            column.split(":")[0].removeprefix("/world/vehicles/")
            for column in frame.columns
            if column.startswith("/world/vehicles/") and column.endswith(":x") and column.count("/") == 3
        )
        with_vehicles = np.zeros(len(frame), dtype=bool)
        for name in vehicles:
            with_vehicles |= present(frame[f"/world/vehicles/{name}:x"]).to_numpy()
        times = frame.loc[with_vehicles, recording.TIMELINE].dt.total_seconds()
        lanes = {c.split(":")[0] for c in frame.columns if c.startswith("/world/road/lane_")}
        return {
            "format_version": int(static["/meta:format_version"].iloc[0][0]),
            "protocol": int(static["/meta:protocol"].iloc[0][0]),
            "scenario": str(static["/meta:scenario"].iloc[0][0]),
            "agents": list(static["/meta:agents"].iloc[0]),
            "vehicles": vehicles,
            "lanes": len([lane for lane in lanes if lane.count("/") == 3]),
            "episodes": int(present(frame["/episode:index"]).sum()),
            "frames": int(with_vehicles.sum()),
            "duration": float(times.max() - times.min()),
        }

    for compact in (True, False):
        if not compact:
            monkeypatch.setattr(recording.Recording, "_rewrite_compacted", lambda self: None)
        path = tmp_path / f"three-{compact}.rrd"
        env = highway_arena.parallel_env("merge-ac", explain=True, record=path)
        for seed in (5, 6, 7):
            env.reset(seed=seed)
            for _ in range(15 * seed):
                if not env.agents:
                    break
                env.step({"ac_0": IDLE})
        env.close()
        held, read = view.summary(path), full_read(path)
        assert held.pop("duration") == pytest.approx(read.pop("duration")), compact
        assert held == read, compact
        assert held["episodes"] == 3 and held["vehicles"] == ["ac_0", "ec"] and held["lanes"] == 2
        assert held["frames"] > 3 * 15


def test_the_view_command_refuses_what_is_not_a_recording(tmp_path):
    text = tmp_path / "notes.rrd"
    text.write_text("not a recording\n")
    done = subprocess.run(
        [sys.executable, "-m", "highway_arena.view", str(text), "--summary"], capture_output=True, text=True
    )
    assert done.returncode == 2 and "not a Rerun recording" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
