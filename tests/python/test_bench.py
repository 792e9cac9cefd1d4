"""clients/python/bench.py's side-by-side mode: two servers launched, the one env measured
on each in turn, a table of rounds and the median ratio; a bad binary is refused by name."""

import json
import subprocess
import sys

from conftest import REPO
from highway_arena._server import find_server_binary

BENCH = REPO / "clients" / "python" / "bench.py"


def bench(*args):
    return subprocess.run([sys.executable, str(BENCH), *args], capture_output=True, text=True, timeout=120)


def test_vs_measures_both_servers_each_round_and_reports_their_ratio():
    binary = find_server_binary()
    done = bench("--binary", binary, "--vs", binary, "--scenario", "merge", "--seconds", "0.3", "--rounds", "2", "--json")
    assert done.returncode == 0, done.stderr
    figures = json.loads(done.stdout)
    assert figures["binaries"] == {"A": binary, "B": binary}
    assert len(figures["rounds"]) == 2
    for got in figures["rounds"]:
        assert got["A"] > 0 and got["B"] > 0
    ratios = sorted(r["B"] / r["A"] for r in figures["rounds"])
    assert abs(figures["median_ratio"] - (ratios[0] + ratios[1]) / 2) < 1e-9


def test_vs_refuses_a_binary_that_is_not_there_naming_it():
    done = bench("--vs", "/nonexistent/arena-server", "--rounds", "1")
    assert done.returncode == 2
    assert "--vs '/nonexistent/arena-server' is not an executable file" in done.stderr


def test_vs_cannot_be_combined_with_connect():
    done = bench("--vs", find_server_binary(), "--connect", "tcp/127.0.0.1:7447")
    assert done.returncode == 2
    assert "cannot be used with --connect" in done.stderr


def test_a_scenario_the_server_does_not_have_is_refused_by_name_without_a_traceback():
    binary = find_server_binary()
    done = bench("--binary", binary, "--vs", binary, "--scenario", "nope", "--seconds", "0.2", "--rounds", "1")
    assert done.returncode == 2
    assert "no scenario named 'nope'" in done.stderr and "Traceback" not in done.stderr


def test_a_binary_that_is_not_there_or_no_seconds_is_refused_by_name_in_every_mode():
    done = bench("--binary", "/nonexistent/arena-server", "--seconds", "1")
    assert done.returncode == 2
    assert "--binary '/nonexistent/arena-server' is not an executable file" in done.stderr
    done = bench("--seconds", "-1")
    assert done.returncode == 2
    assert "--seconds must be a positive number of wall seconds, not -1.0" in done.stderr
