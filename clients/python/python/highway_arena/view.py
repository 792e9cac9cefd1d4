"""``python -m highway_arena.view FILE``: opens a recording (``env.start_recording`` or
``parallel_env(..., record=FILE)``) in Rerun's viewer: the desktop viewer, or with
``--web`` the web viewer served on 127.0.0.1 for a browser. ``--summary`` prints what the
file holds instead (its format and version, scenario, episodes, vehicles and simulated
time), read with Rerun's own loader; no viewer, no server needed."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import urllib.parse

from .recording import FORMAT, FORMAT_VERSION, TIMELINE, _rerun


class NotARecording(ValueError):
    """The file is not a highway-arena recording this version can read."""


def summary(path) -> dict:
    """What a recording holds: ``format_version``, ``protocol``, ``scenario``,
    ``agents``, ``vehicles`` (every vehicle entity's name), ``lanes``, ``episodes``,
    ``frames`` (time points with vehicles) and ``duration`` (simulated seconds)."""
    rr = _rerun()
    store = rr.chunk.RrdReader(os.fspath(path)).stream().collect()
    static = store.reader(index=None).to_pandas()
    if "/meta:format" not in static.columns or static["/meta:format"].iloc[0][0] != FORMAT:
        raise NotARecording(f"{path}: not a {FORMAT} (no /meta entity saying so)")
    version = int(static["/meta:format_version"].iloc[0][0])
    if version > FORMAT_VERSION:
        raise NotARecording(
            f"{path}: a {FORMAT} of format version {version}; this highway_arena reads up to {FORMAT_VERSION}"
        )

    def meta(key, default=None):
        column = f"/meta:{key}"
        return static[column].iloc[0] if column in static.columns else default

    table = store.reader(index=TIMELINE).to_pandas()
    entities = {column.split(":")[0] for column in table.columns if ":" in column}
    vehicles = sorted(
        entity.removeprefix("/world/vehicles/")
        for entity in entities
        if entity.startswith("/world/vehicles/") and f"{entity}:x" in table.columns
    )
    lanes = [entity for entity in entities if entity.startswith("/world/road/lane_") and entity.count("/") == 3]
    def present(column):
        return table[column].map(lambda value: value is not None and len(value) > 0)

    with_vehicles = table.index < 0
    for name in vehicles:
        with_vehicles = with_vehicles | present(f"/world/vehicles/{name}:x")
    times = table.loc[with_vehicles, TIMELINE]
    episodes = table.loc[present("/episode:index"), "/episode:index"] if "/episode:index" in table.columns else []
    return {
        "format_version": version,
        "protocol": int(meta("protocol", [0])[0]),
        "scenario": str(meta("scenario", [""])[0]),
        "agents": [str(a) for a in meta("agents", [])],
        "vehicles": vehicles,
        "lanes": len(lanes),
        "episodes": len(episodes),
        "frames": int(with_vehicles.sum()),
        "duration": float((times.max() - times.min()).total_seconds()) if len(times) else 0.0,
    }


def rerun_binary() -> list:
    """rerun-sdk's own viewer binary, found as ``python -m rerun_cli`` finds it, run
    directly (so that stopping it stops the viewer: the module runs it as a child)."""
    import rerun_cli

    binary = os.environ.get("RERUN_CLI_PATH") or os.path.join(os.path.dirname(rerun_cli.__file__), "rerun")
    if sys.platform.startswith("win") and not binary.endswith(".exe"):
        binary += ".exe"
    return [binary] if os.path.isfile(binary) else [sys.executable, "-m", "rerun_cli"]


def viewer_command(path, web=False, bind="127.0.0.1", web_port=9090, grpc_port=9876) -> list:
    """The ``rerun`` command that opens ``path``: the desktop viewer, or the web viewer
    served (and no browser opened: the address is printed)."""
    command = [*rerun_binary(), os.fspath(path)]
    if web:
        command += ["--serve-web", "--bind", bind, "--web-viewer-port", str(web_port), "--port", str(grpc_port)]
    return command


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m highway_arena.view", description=__doc__.split("\n\n")[0])
    parser.add_argument("file", help="a recording (.rrd) written by highway_arena")
    parser.add_argument("--web", action="store_true", help="serve the web viewer on --bind:--web-port for a browser")
    parser.add_argument("--bind", default="127.0.0.1", help="address the web viewer listens on (default 127.0.0.1)")
    parser.add_argument("--web-port", type=int, default=9090, help="web viewer's HTTP port (default 9090)")
    parser.add_argument("--grpc-port", type=int, default=9876, help="port the viewer's data server uses (default 9876)")
    parser.add_argument("--summary", action="store_true", help="print what the file holds and exit")
    args = parser.parse_args(argv)
    if not os.path.isfile(args.file):
        parser.error(f"no file {args.file!r}")
    try:
        held = summary(args.file)
    except NotARecording as error:
        print(f"highway_arena.view: {error}", file=sys.stderr)
        return 2
    print(
        f"{args.file}: {held['scenario']} (protocol {held['protocol']}, format {held['format_version']}), "
        f"{held['episodes']} episode(s), {len(held['vehicles'])} vehicles, {held['frames']} frames, "
        f"{held['duration']:.1f} s simulated"
    )
    if args.summary:
        return 0
    command = viewer_command(args.file, args.web, args.bind, args.web_port, args.grpc_port)
    if args.web:
        data = urllib.parse.quote(f"rerun+http://{args.bind}:{args.grpc_port}/proxy", safe="")
        print(f"web viewer: http://{args.bind}:{args.web_port}/?url={data} (Ctrl-C stops it)")
    sys.stdout.flush()
    if os.name == "posix":
        # The viewer takes this process's place: stopping it (Ctrl-C, a signal to this
        # pid) stops the viewer, with no child left behind.
        os.execv(command[0], command)
    try:
        return subprocess.call(command)
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    sys.exit(main())
