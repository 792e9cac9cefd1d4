"""Episode recordings: what a recording env's replies carry (the road's geometry, every
vehicle at every control period, collisions), with every agent's action, reward and
infos, written as a Rerun recording (an ``.rrd`` file, a live desktop viewer, or a web
viewer) with rerun-sdk. The file is the recording: self-describing (``meta``: format,
version, protocol, scenario, step and control periods, agents), and it replays without a
server (``python -m highway_arena.view FILE``; docs/viewing.md lists every entity).

Entities, on the timelines ``sim_time`` (simulated seconds since the recording began:
episodes follow one another) and ``step`` (env steps since it began):

- ``meta`` (static): ``format`` = ``FORMAT``, ``format_version``, ``protocol``,
  ``scenario``, ``step_dt``, ``agents``.
- ``episode``: at each reset, ``index`` and ``seed``.
- ``world/road/lane_<i>``: the lane as a grey strip along its centre line (``end_s``,
  ``ends_early``, ``speed_limit``), its edges as white lines (``.../edges``);
  ``world/road/lane_<i>/end``: a red bar where a lane ends before the road.
- ``world/follow``: at every control period, a transform on the followed car (``follow``,
  else the first learner), the world mirrored; the road view's origin, so it follows it.
- ``world/vehicles/<name>``: at every control period, its oriented body (a strip of the
  car's width along its axis: a box with rounded corners) coloured by driver, and its
  state (``x``, ``y``, ``heading``, ``s``, ``d``, ``speed``, ``accel``, ``lane``,
  ``target_lane``, ``end``: an ``END_REASONS`` code, 0 while it drives); ``driver``,
  ``style``, ``game``, ``role``, ``learner`` at the episode's start.
- ``agents/<agent>``: at every step, its ``action`` (float64), ``reward``,
  ``terminated``, ``truncated`` and every info key as ``info.<key>`` (numbers as float64,
  bools as bools).
- ``plots/speed/<agent>`` (every control period), ``plots/reward/<agent>``,
  ``plots/cost/<agent>/{safety,comfort,efficiency}`` (every step).
- With ``explain=True`` (docs/viewing.md, "The AV explained"), at each game-theoretic
  decision: ``world/vehicles/<name>/plan``, the car's own predicted path at the
  equilibrium it played (a line strip, with ``game``, ``role``, ``ec`` (the game's EC
  by name), ``sigma``, ``accel``, ``games_accel``, ``exact``, ``safety``,
  ``fallback``), and ``world/vehicles/<name>/prediction``, the path it predicted for
  the other player; ``explain/<name>``: the game as a markdown document
  (``explained_markdown``: cars by name, each side's table row by row with AC's best
  reply and both costs there, and the played row's cost the game minimised, named) and
  ``explain/<name>/<left|right>``: each side's full game (``ac``, its AC by name, "-"
  for none; ``rows``, ``cols``, ``ec_accel``, ``ec_sigma``, ``ac_accel``, ``ec_costs``
  and ``ac_costs`` row-major with NaN where the search skipped a cell, ``pruned``,
  ``row``, ``col``, ``exact``, ``chosen``).
- ``events/collisions``: a red point where and when each collision happened, labelled
  with both cars and who was at fault; ``events/ends/<agent>``: where and why an agent's
  episode ended; ``events/log``: both as text.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import urllib.parse
import uuid

import numpy as np

from . import _convert
from ._core import END_REASONS, PALETTE

FORMAT = "highway-arena recording"
FORMAT_VERSION = 2  # 2: the AV's decisions explained (explain=True)
TIMELINE = "sim_time"
# The road view's frame: the followed car's position, the world mirrored (Y up).
FOLLOW = "world/follow"
STEP_TIMELINE = "step"

# Colours, the protocol's palette (the server's frames paint with it too): learners green
# (whoever drives them: with `policy` the AV does), the game-theoretic AV blue by style
# (darker is bolder), IDM yellow, a crashed car red, one that left the road or ended its
# lane grey.
LEARNER = PALETTE["learner"]
GT = PALETTE["gt"]
IDM = PALETTE["idm"]
CRASHED = PALETTE["crashed"]
GONE = PALETTE["gone"]
ENDED = PALETTE["ended"]
ASPHALT = PALETTE["asphalt"]
MARKING = PALETTE["marking"]
LANE_END = PALETTE["lane_end"]
PLAN = PALETTE["plan"]
PREDICTION = PALETTE["prediction"]

VEHICLE_COLUMNS = ("x", "y", "heading", "s", "d", "speed", "accel", "lane", "target_lane", "end")


def _rerun():
    try:
        import rerun
    except ImportError as error:  # the optional extra
        raise ImportError(
            "recordings need rerun-sdk: pip install 'highway-arena[view]' (or rerun-sdk==0.41.0)"
        ) from error
    return rerun


def _stop(process):
    """Stops a viewer this module started (by its own handle)."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()


def _frames(raw: dict) -> dict:
    """The extension's frame columns as numpy arrays (collisions stay a list)."""
    return {key: (value if key == "collisions" else _convert.tensor(value)) for key, value in raw.items()}


def _colour(driver: dict, end: int) -> tuple:
    if end == _convert.EndReason.COLLISION:
        return CRASHED
    if end != 0:
        return GONE
    if driver["learner"]:
        return LEARNER
    if driver["driver"] == "gt":
        return GT[driver["style"]]
    return IDM


def vehicle_name(vehicles, index) -> str:
    """The name of vehicle ``index`` (``vehicles``: the episode's vehicle dicts or names),
    "-" for none."""
    if index is None or not 0 <= index < len(vehicles):
        return "-"
    vehicle = vehicles[index]
    return vehicle if isinstance(vehicle, str) else vehicle["name"]


def _criterion(e, t) -> tuple:
    """What the game minimised in the row played: (in words, in short for the table)."""
    if e["ec"] != e["vehicle"]:
        return "its best reply to the leader's action", "best reply"
    # A follower with no leader in play is the EC of its own lane's game, a Nash game.
    if e["game"] == "stackelberg" and e["role"] == "leader":
        return "EC's worst case over AC's near-best replies, least over the rows", "worst case"
    if t["exact"]:
        return "the Nash equilibrium (AC's best reply)", "equilibrium"
    return "no pure equilibrium: EC's best row against AC's best replies", "best vs replies"


def explained_markdown(e, names=None) -> str:
    """A decision (the extension's dict) as markdown, vehicles by name (``names``: the
    episode's vehicle names in index order; by default the dict's own ``vehicle_name``,
    ``ec_name`` and tables' ``adjacent_name``): the text of a recording's panel. Per side, one line per EC action still in
    play: AC's best reply to it and both costs there; and, for the row played, the cost
    the game minimised: a Stackelberg leader's worst case over AC's near-best replies
    (at least the best reply's cost, so it may read higher than other rows' best-reply
    costs), a Nash game's equilibrium (AC's best reply: the same cell)."""

    if names is None:
        named = {e["vehicle"]: e.get("vehicle_name"), e["ec"]: e.get("ec_name")}
        named.update({t["adjacent"]: t.get("adjacent_name") for t in e["tables"] if t["adjacent"] is not None})

        def name(index):
            return named.get(index) or "-"
    else:

        def name(index):
            return vehicle_name(names, index)

    me = name(e["vehicle"])
    follows = e["ec"] != e["vehicle"]
    lines = [
        f"### {me} at t = {e['time']:.2f} s: {e['game']}, {e['role']}",
        f"EC (leader) **{name(e['ec'])}**"
        + (f", {me} answers as its AC" if follows else "")
        + f"; commanded a = {e['accel']:+.2f} m/s² (games: {e['games_accel']:+.2f}), sigma = {e['sigma']:+d}"
        + (", **safety override**" if e["safety"] else "")
        + (", **MPC fallback**" if e["fallback"] else ""),
    ]
    for at, t in enumerate(e["tables"]):
        rows, cols = len(t["ec_actions"]), len(t["ac_actions"])
        ec = np.asarray(t["ec_costs"], dtype=np.float64).reshape(rows, cols)
        ac = np.asarray(t["ac_costs"], dtype=np.float64).reshape(rows, cols)
        chosen = " (chosen)" if e["chosen"] == at else ""
        skipped = int(np.isnan(ec).sum() + np.isnan(ac).sum())
        criterion, short = _criterion(e, t)
        # A follower is the AC: it minimised its own cost.
        played_header = "played: AC a, J_AC minimised" if follows else "played: AC a, J_EC minimised"
        who, costs, played_cost = ("AC", ac, ac[t["row"], t["col"]]) if follows else ("EC", ec, t["cost"])
        lines += [
            "",
            f"#### {'left' if t['side'] < 0 else 'right'} side{chosen}: AC {name(t['adjacent'])}, "
            f"{rows} x {cols}, played ({t['row']}, {t['col']}): {criterion}; J_{who} there = {played_cost:.4g}; "
            f"{skipped} of {2 * rows * cols} cells skipped, {sum(t['pruned'])} rows pruned",
            "",
            f"| EC a | sigma | AC best reply a | J_EC at best reply | J_AC at best reply | {played_header} |",
            "|---:|---:|---:|---:|---:|:---|",
        ]
        for r, (a, sigma) in enumerate(t["ec_actions"]):
            if t["pruned"][r]:
                continue
            known = np.where(np.isnan(ac[r]), np.inf, ac[r])
            c = int(np.argmin(known))
            cells = [f"{a:+.2f}", f"{sigma:+d}", f"{t['ac_actions'][c]:+.2f}", f"{ec[r, c]:.4g}", f"{ac[r, c]:.4g}"]
            if r == t["row"]:
                played = f"{t['ac_actions'][t['col']]:+.2f}, {costs[r, t['col']]:.4g} ({short})"
                cells = [f"**{cell}**" for cell in cells + [played]]
            else:
                cells.append("")
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


class Recording:
    """A Rerun recording stream fed from an env's replies.

    ``path``: write an ``.rrd`` file there; ``spawn``: stream to a desktop viewer it
    starts; ``serve``: serve a web viewer on 127.0.0.1 (its address is ``url``). Any
    combination; at least one. ``meta``: what the file says about itself (scenario, step
    and control periods, agents). ``compact``: on ``close``, rewrite the file with its
    chunks merged (Rerun's own optimiser: about 40 % smaller, half a second a minute of
    highway-gt). ``follow``: the vehicle the road view follows (its scenario name, an
    agent's name for a learner); by default, and in an episode without it, the first
    learner (else the first vehicle)."""

    def __init__(
        self,
        path=None,
        *,
        spawn=False,
        serve=False,
        web_port=9090,
        grpc_port=9876,
        meta=None,
        compact=True,
        follow=None,
    ):
        rr = _rerun()
        if path is None and not spawn and not serve:
            raise ValueError("a recording needs somewhere to go: a path, spawn=True or serve=True")
        self._rr = rr
        self.path = None if path is None else os.fspath(path)
        self.url = None
        self.live = bool(spawn or serve)
        self._compact = bool(compact)
        self._recording_id = str(uuid.uuid4())
        self.stream = rr.RecordingStream("highway-arena", recording_id=self._recording_id)
        # Simulated time is the recording's clock: no wall-clock timeline in the file.
        self.stream.set_log_time_enabled(False)
        sinks = []
        if self.path is not None:
            sinks.append(rr.FileSink(self.path))
        if spawn:
            rr.spawn(connect=False)
            sinks.append(rr.GrpcSink())
        self.viewer = None
        if serve:
            # Rerun's own server, bound to 127.0.0.1 for both the page and the data (the
            # SDK's serve_web_viewer would bind the page to every interface); it stays up
            # for viewing after the recording stops, until this Python process exits.
            from .view import rerun_binary

            data = f"rerun+http://127.0.0.1:{int(grpc_port)}/proxy"
            self.viewer = subprocess.Popen(
                [*rerun_binary(), "--serve-web", "--bind", "127.0.0.1"]
                + ["--web-viewer-port", str(int(web_port)), "--port", str(int(grpc_port))],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            atexit.register(_stop, self.viewer)
            sinks.append(rr.GrpcSink(data))
            self.url = f"http://127.0.0.1:{int(web_port)}/?url={urllib.parse.quote(data, safe='')}"
        self.stream.set_sinks(*sinks)
        self._meta = dict(meta or {})
        self._offset = 0.0  # sim_time where the current episode began
        self._end = 0.0  # the latest sim_time written
        self._steps = 0
        self._episodes = 0
        self._vehicles = []  # this episode's vehicle descriptions
        self._agents = {}  # agent name -> vehicle index
        self._pending = []  # frame columns not yet written
        self._last_position = {}  # vehicle name -> its (x, y) at the last frame written
        self._labelled = set()  # vehicles whose name and width are written
        self._closed = False
        if follow is not None and not isinstance(follow, str):
            raise TypeError(f"follow must be a vehicle's name (str), not {follow!r}")
        self._follow = follow
        self._followed = None  # the vehicle this episode's road view follows
        self._explained = []  # names of the cars with an explanation panel, in order
        self._blueprint_sent = False
        # World coordinates have Y to the left of the road's start (up); Rerun's 2D
        # views draw Y down, so the scene is mirrored back once, here.
        for root in ("world", "events"):
            self._log(root, rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        self._log(
            "meta",
            rr.AnyValues(
                format=FORMAT,
                format_version=FORMAT_VERSION,
                **{key: value for key, value in self._meta.items() if value is not None},
            ),
            static=True,
        )

    def _blueprint(self):
        """The layout: the road following a car (``FOLLOW``'s frame: 30 m behind it to
        90 m ahead, 25 m to either side), the plots beside it, and below them one tab per
        explained car with its whole decision."""
        rrb = self._rr.blueprint
        road = rrb.Spatial2DView(
            name="road",
            origin=f"/{FOLLOW}",
            contents=["/world/**", "/events/**"],
            visual_bounds=rrb.VisualBounds2D(x_range=[-30.0, 90.0], y_range=[-25.0, 25.0]),
        )
        plots = rrb.Vertical(
            rrb.TimeSeriesView(name="speed (m/s)", origin="/plots/speed"),
            rrb.TimeSeriesView(name="reward", origin="/plots/reward"),
            rrb.TimeSeriesView(name="costs", origin="/plots/cost"),
            rrb.TextLogView(name="events", origin="/events/log"),
        )
        top = rrb.Horizontal(road, plots, column_shares=[3, 2])
        if self._explained:
            # A text view shows one document: one per car, as tabs.
            explained = [
                rrb.TextDocumentView(name=f"{name} explained", origin=f"/explain/{name}", contents="$origin")
                for name in self._explained
            ]
            layout = rrb.Vertical(top, rrb.Tabs(*explained, name="the AV explained"), row_shares=[1, 2])
        else:
            layout = top
        return rrb.Blueprint(
            layout,
            rrb.BlueprintPanel(state="collapsed"),
            rrb.SelectionPanel(state="collapsed"),
            rrb.TimePanel(state="collapsed", timeline=TIMELINE),
        )

    def _send_blueprint(self):
        """Sends the layout, once the recording has data on its timeline (a layout naming
        a timeline the viewer has not seen yet is refused with 'Timeline not found')."""
        self._blueprint_sent = True
        self.stream.send_blueprint(self._blueprint())

    def _log(self, path, *archetypes, static=False):
        self.stream.log(path, *archetypes, static=static)

    def _at(self, time: float):
        self.stream.set_time(TIMELINE, duration=time)
        self.stream.set_time(STEP_TIMELINE, sequence=self._steps)

    def begin_episode(self, start: dict, seed=None, infos=None):
        """A reset: the road and vehicles of ``start`` (the extension's start dict), its
        first frame, and the agents' first infos."""
        rr = self._rr
        self._flush()
        if self._episodes:
            # The next episode begins one env step after the last one ended.
            self._offset = self._end + float(self._meta.get("step_dt") or 0.1)
        self._episodes += 1
        self._vehicles = list(start["vehicles"])
        self._agents = {v["name"]: i for i, v in enumerate(self._vehicles) if v["learner"]}
        self._followed = self._pick_followed()
        first = _frames(start["frame"])
        # Begun mid-episode, the recording's first frame is the world's time then.
        self._at(self._offset + float(first["time"][0]))
        self._log("episode", rr.AnyValues(index=self._episodes - 1, seed=-1 if seed is None else int(seed)))
        self._log("world/vehicles", rr.Clear(recursive=True))
        self._log("events", rr.Clear(recursive=True))
        road = start["road"]
        width = float(road["lane_width"])
        for i, lane in enumerate(road["lanes"]):
            centre = _convert.tensor(lane["centre"])
            edges = [_convert.tensor(lane["left"]), _convert.tensor(lane["right"])]
            self._log(
                f"world/road/lane_{i}",
                rr.LineStrips2D([centre], radii=width / 2, colors=[ASPHALT], draw_order=-10.0),
                rr.AnyValues(
                    end_s=float(lane["end"]),
                    ends_early=bool(lane["ends_early"]),
                    speed_limit=float(lane["speed_limit"]),
                ),
            )
            self._log(
                f"world/road/lane_{i}/edges",
                rr.LineStrips2D(edges, radii=0.12, colors=[MARKING], draw_order=-9.0),
            )
            if lane["ends_early"]:
                bar = np.array([edges[0][-1], edges[1][-1]])
                self._log(
                    f"world/road/lane_{i}/end",
                    rr.LineStrips2D([bar], radii=0.6, colors=[LANE_END], labels=["lane end"], draw_order=-8.0),
                )
        for vehicle in self._vehicles:
            self._log(
                f"world/vehicles/{vehicle['name']}",
                rr.AnyValues(
                    driver=vehicle["driver"],
                    style=vehicle["style"],
                    game=vehicle["game"] or "",
                    role=vehicle["role"] or "",
                    learner=bool(vehicle["learner"]),
                ),
            )
        self._add_frames(first)
        self._write_frames()
        if not self._blueprint_sent:
            self._send_blueprint()
        for agent, info in (infos or {}).items():
            self._agent_row(agent, None, 0.0, False, False, info)

    def add_step(self, frames: dict | None, actions, rewards, terminations, truncations, infos):
        """A step: its frames (the extension's frame columns, None if it brought none)
        and every agent's action, reward, ends and info."""
        rr = self._rr
        self._steps += 1
        if frames is not None:
            self._add_frames(_frames(frames))
        if self.live or sum(len(f["time"]) for f in self._pending) >= 4096:
            self._write_frames()
        self._at(self._end)
        for agent in rewards:
            action = actions.get(agent) if actions else None
            self._agent_row(agent, action, rewards[agent], terminations[agent], truncations[agent], infos[agent])
            end = int(infos[agent].get("end_reason", 0))
            if end != 0:
                reason = END_REASONS[end]
                place = self._last_position.get(agent, (0.0, 0.0))
                self._log(
                    f"events/ends/{agent}",
                    rr.Points2D(
                        [place],
                        radii=1.5,
                        colors=[CRASHED if end == _convert.EndReason.COLLISION else ENDED],
                        labels=[f"{agent}: {reason}"],
                    ),
                )
                text = f"t = {self._end - self._offset:.2f} s: {agent} ended: {reason}"
                self._log("events/log", rr.TextLog(text, level="INFO"))

    def add_explanations(self, explanations):
        """A step's explained decisions (the extension's dicts): each car's own predicted
        path and the other player's as line strips under the car, its game as a markdown
        document and its cost tables as tensors, at the decision's time."""
        rr = self._rr
        if not explanations:
            return
        for e in explanations:
            if e["vehicle"] >= len(self._vehicles):
                continue
            name = self._vehicles[e["vehicle"]]["name"]
            if name not in self._explained:
                self._explained.append(name)
                self._send_blueprint()
            self.stream.set_time(TIMELINE, duration=self._offset + float(e["time"]))
            self.stream.set_time(STEP_TIMELINE, sequence=self._steps)
            follows = e["ec"] != e["vehicle"]
            own, other = (e["predicted"], e["planned"]) if follows else (e["planned"], e["predicted"])
            self._log(
                f"world/vehicles/{name}/plan",
                rr.LineStrips2D([[(x, y) for _, x, y, _ in own]] if own else [], radii=0.25, colors=[PLAN]),
                rr.AnyValues(
                    game=e["game"],
                    role=e["role"],
                    ec=self._name(e["ec"]),
                    sigma=int(e["sigma"]),
                    accel=float(e["accel"]),
                    games_accel=float(e["games_accel"]),
                    exact=all(t["exact"] for t in e["tables"]),
                    safety=bool(e["safety"]),
                    fallback=bool(e["fallback"]),
                ),
            )
            self._log(
                f"world/vehicles/{name}/prediction",
                rr.LineStrips2D([[(x, y) for _, x, y, _ in other]] if other else [], radii=0.2, colors=[PREDICTION]),
            )
            self._log(f"explain/{name}", rr.TextDocument(self._explained_markdown(e), media_type="text/markdown"))
            for t in e["tables"]:
                side = "left" if t["side"] < 0 else "right"
                self._log(
                    f"explain/{name}/{side}",
                    rr.AnyValues(
                        ac=self._name(t["adjacent"]),
                        rows=len(t["ec_actions"]),
                        cols=len(t["ac_actions"]),
                        ec_accel=np.asarray([a for a, _ in t["ec_actions"]], dtype=np.float64),
                        ec_sigma=np.asarray([sigma for _, sigma in t["ec_actions"]], dtype=np.float64),
                        ac_accel=np.asarray(t["ac_actions"], dtype=np.float64),
                        ec_costs=np.asarray(t["ec_costs"], dtype=np.float64),
                        ac_costs=np.asarray(t["ac_costs"], dtype=np.float64),
                        pruned=np.asarray(t["pruned"], dtype=bool),
                        row=int(t["row"]),
                        col=int(t["col"]),
                        exact=bool(t["exact"]),
                        chosen=e["chosen"] is not None and e["tables"][e["chosen"]] is t,
                    ),
                )
        self._at(self._end)

    def _name(self, index):
        return vehicle_name(self._vehicles, index)

    def _explained_markdown(self, e) -> str:
        return explained_markdown(e, [v["name"] for v in self._vehicles])

    def _pick_followed(self):
        """The index of the vehicle the road view follows this episode: ``follow``,
        else the first learner, else the first vehicle (None without vehicles)."""
        names = [v["name"] for v in self._vehicles]
        if self._follow in names:
            return names.index(self._follow)
        learner = next((i for i, v in enumerate(self._vehicles) if v["learner"]), None)
        return learner if learner is not None else (0 if names else None)

    def _add_frames(self, frames: dict):
        """Keeps frames to write, and where each vehicle was at the last of them."""
        frames["step"] = np.full(len(frames["time"]), self._steps, dtype=np.int64)
        self._pending.append(frames)
        self._end = self._offset + float(frames["time"][-1])
        for i, vehicle in enumerate(self._vehicles[: frames["x"].shape[1]]):
            self._last_position[vehicle["name"]] = (float(frames["x"][-1, i]), float(frames["y"][-1, i]))

    def _agent_row(self, agent, action, reward, terminated, truncated, info):
        rr = self._rr
        # One type per name in a Rerun process, whatever the env's options: info numbers
        # as float64 (lists too: a meta agent's expert_action is an int, a continuous
        # one's two floats), bools as bools, actions as float64 lists.
        values = {}
        for key, value in info.items():
            if isinstance(value, (bool, np.bool_)):
                values[f"info.{key}"] = bool(value)
            else:
                values[f"info.{key}"] = np.asarray(value, dtype=np.float64).reshape(-1)
        if action is not None:
            values["action"] = np.asarray(action, dtype=np.float64).reshape(-1)
        self._log(
            f"agents/{agent}",
            rr.AnyValues(reward=float(reward), terminated=bool(terminated), truncated=bool(truncated), **values),
        )
        self._log(f"plots/reward/{agent}", rr.Scalars(float(reward)))
        for part in ("safety", "comfort", "efficiency"):
            key = f"cost_{part}"
            if key in info:
                self._log(f"plots/cost/{agent}/{part}", rr.Scalars(float(info[key])))

    def _write_frames(self):
        """Writes the pending frames, one batch of columns per vehicle."""
        rr = self._rr
        if not self._pending:
            return
        frames = {
            key: np.concatenate([f[key] for f in self._pending])
            for key in ("time", "step", *VEHICLE_COLUMNS)
        }
        collisions = [c for f in self._pending for c in f["collisions"]]
        self._pending = []
        times = self._offset + frames["time"]
        self._end = max(self._end, float(times[-1]))
        index = [
            rr.TimeColumn(TIMELINE, duration=times),
            rr.TimeColumn(STEP_TIMELINE, sequence=frames["step"]),
        ]
        for i, vehicle in enumerate(self._vehicles[: frames["x"].shape[1]]):
            x, y, heading = frames["x"][:, i], frames["y"][:, i], frames["heading"][:, i]
            half = max(float(vehicle["length"]) - float(vehicle["width"]), 0.0) / 2.0
            dx, dy = half * np.cos(heading), half * np.sin(heading)
            strips = np.stack([np.stack([x - dx, y - dy], axis=1), np.stack([x + dx, y + dy], axis=1)], axis=1)
            ends = frames["end"][:, i]
            colours = np.array([_colour(vehicle, int(e)) for e in ends], dtype=np.uint8)
            name = vehicle["name"]
            columns = [
                *rr.LineStrips2D.columns(strips=strips, colors=colours).partition(np.ones(len(times), np.int64)),
                *rr.AnyValues.columns(**{key: frames[key][:, i] for key in VEHICLE_COLUMNS}),
            ]
            self.stream.send_columns(f"world/vehicles/{name}", indexes=index, columns=columns)
            if vehicle["learner"]:
                self.stream.send_columns(
                    f"plots/speed/{name}", indexes=index, columns=rr.Scalars.columns(scalars=frames["speed"][:, i])
                )
        if self._followed is not None and self._followed < frames["x"].shape[1]:
            # The road view's frame: on the followed car, mirrored as the world is.
            at = np.stack(
                [frames["x"][:, self._followed], frames["y"][:, self._followed], np.zeros(len(times))], axis=1
            )
            columns = rr.Transform3D.columns(translation=at, scale=np.tile([1.0, -1.0, 1.0], (len(times), 1)))
            self.stream.send_columns(FOLLOW, indexes=index, columns=columns)
        # Static: a vehicle's name and width do not change within an episode.
        for vehicle in self._vehicles:
            if vehicle["name"] not in self._labelled:
                self._labelled.add(vehicle["name"])
                self._log(
                    f"world/vehicles/{vehicle['name']}",
                    rr.LineStrips2D.from_fields(
                        radii=[float(vehicle["width"]) / 2.0],
                        labels=[vehicle["name"]],
                        show_labels=bool(vehicle["learner"] or vehicle["driver"] == "gt"),
                    ),
                    static=True,
                )
        for event in collisions:
            rear, front = self._vehicles[event["rear"]]["name"], self._vehicles[event["front"]]["name"]
            self.stream.set_time(TIMELINE, duration=self._offset + event["time"])
            text = f"collision {rear} / {front} (at fault: {event['at_fault']})"
            point = rr.Points2D([[event["x"], event["y"]]], radii=2.0, colors=[CRASHED], labels=[text])
            self._log("events/collisions", point)
            self._log("events/log", rr.TextLog(f"t = {event['time']:.2f} s: {text}", level="WARN"))
        self._at(self._end)

    def _flush(self):
        self._write_frames()

    def close(self):
        """Writes what is pending and closes the stream (the file is complete then)."""
        if self._closed:
            return
        self._closed = True
        self._write_frames()
        self.stream.flush()
        # Everything is with the sinks now (a viewer keeps what it got; a served one
        # keeps it for late browsers): let go of them.
        self.stream.disconnect()
        if self.path is not None and self._compact:
            self._rewrite_compacted()

    def _rewrite_compacted(self):
        """Rewrites the file with its chunks merged (many small chunks of per-step rows
        and per-episode frames become a few large ones), the blueprint with them."""
        rr = self._rr
        store = rr.chunk.RrdReader(self.path).stream().collect(optimize=rr.chunk.OptimizationProfile.OBJECT_STORE)
        temporary = f"{self.path}.compacting"
        stream = rr.RecordingStream("highway-arena", recording_id=self._recording_id)
        stream.set_log_time_enabled(False)
        stream.set_sinks(rr.FileSink(temporary))
        rr.send_chunks(store.stream(), recording=stream)
        # After the data, as while recording: the layout names the timeline.
        stream.send_blueprint(self._blueprint())
        stream.flush()
        stream.disconnect()
        os.replace(temporary, self.path)


__all__ = ["FORMAT", "FORMAT_VERSION", "Recording", "TIMELINE", "STEP_TIMELINE"]
