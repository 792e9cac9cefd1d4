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


# What a summary reads: the metadata, the episodes, the vehicles and the lanes (not the
# agents' rows, plots or explanations, most of a file).
SUMMARY_CONTENT = ["/meta", "/episode", "/world/vehicles/**", "/world/road/**"]


def _summary_chunks(path):
    """The chunks of the file's recording that a summary reads, as rerun-sdk's own
    reader streams them (its native module: the SDK's Python layer, the viewer's
    blueprint types and the dataframe engine, which take longer to import than a summary
    to read, are not needed)."""
    _rerun_bindings = _bindings()
    try:
        stream = _rerun_bindings.RrdReaderInternal(os.fspath(path)).stream(store=None)
        stream = stream.filter(content=SUMMARY_CONTENT, has_timeline=None, is_static=None, components=None)
        yield from stream
    except (ValueError, OSError, RuntimeError) as error:
        raise NotARecording(f"{path}: not a Rerun recording this rerun-sdk reads ({error})") from error


def _bindings():
    try:
        import rerun_bindings
    except ImportError:
        _rerun()  # says which package to install
        raise
    return rerun_bindings


def _first(batch, column):
    """The first value of a static component column (a list), or None."""
    if column not in batch.schema.names or batch.num_rows == 0:
        return None
    return batch.column(column)[0].as_py()


def _present(column):
    """Which rows of a list column hold a value (from its offsets: no pyarrow.compute,
    whose import brings pandas)."""
    import numpy as np

    wide = str(column.type).startswith("large_")
    offsets = np.frombuffer(column.buffers()[1], dtype=np.int64 if wide else np.int32)[column.offset : column.offset + len(column) + 1]
    return np.diff(offsets) > 0


def _times(column):
    """A duration timeline's values in nanoseconds, from its buffer."""
    import numpy as np

    return np.frombuffer(column.buffers()[1], dtype=np.int64)[column.offset : column.offset + len(column)]


def summary(path) -> dict:
    """What a recording holds: ``format_version``, ``protocol``, ``scenario``,
    ``agents``, ``vehicles`` (every vehicle entity's name), ``lanes``, ``episodes``,
    ``frames`` (time points with vehicles) and ``duration`` (simulated seconds). Reads
    only those entities' chunks (``SUMMARY_CONTENT``)."""
    import numpy as np

    meta = {}
    vehicles, lanes = set(), set()
    episodes = 0
    times = []
    for chunk in _summary_chunks(path):
        entity = chunk.entity_path
        if entity == "/meta" and chunk.is_static:
            batch = chunk.to_record_batch()
            meta.update({key: _first(batch, key) for key in batch.schema.names if not key.startswith("rerun.")})
        elif entity == "/episode":
            batch = chunk.to_record_batch()
            if "index" in batch.schema.names:
                episodes += batch.num_rows - batch.column("index").null_count
        elif entity.startswith("/world/vehicles/") and entity.count("/") == 3 and not chunk.is_static:
            batch = chunk.to_record_batch()
            if "x" in batch.schema.names and TIMELINE in batch.schema.names:
                vehicles.add(entity.removeprefix("/world/vehicles/"))
                times.append(_times(batch.column(TIMELINE))[_present(batch.column("x"))])
        elif entity.startswith("/world/road/lane_") and entity.count("/") == 3:
            lanes.add(entity)
    if (meta.get("format") or [None])[0] != FORMAT:
        raise NotARecording(f"{path}: not a {FORMAT} (no /meta entity saying so)")
    version = int(meta["format_version"][0])
    if version > FORMAT_VERSION:
        raise NotARecording(
            f"{path}: a {FORMAT} of format version {version}; this highway_arena reads up to {FORMAT_VERSION}"
        )
    # sim_time is a duration timeline, in nanoseconds.
    frames = np.unique(np.concatenate(times)) if times else np.zeros(0, dtype=np.int64)
    return {
        "format_version": version,
        "protocol": int((meta.get("protocol") or [0])[0]),
        "scenario": str((meta.get("scenario") or [""])[0]),
        "agents": [str(a) for a in meta.get("agents") or []],
        "vehicles": sorted(vehicles),
        "lanes": len(lanes),
        "episodes": episodes,
        "frames": len(frames),
        "duration": float(frames[-1] - frames[0]) / 1e9 if len(frames) else 0.0,
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
