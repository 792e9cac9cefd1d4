"""highway_arena.evaluate against the live server: the same figures as `arena eval` for
the same policies and seeds, an external callable measured exactly as the built-in it
imitates, files and plots written, and bad input refused by name."""

import os
import pathlib
import subprocess

import pytest

import highway_arena


def _arena_binary():
    """The `arena` CLI built beside the server the suite runs (cargo builds both)."""
    path = pathlib.Path(highway_arena.find_server_binary()).with_name("arena")
    assert path.exists(), f"{path} is missing: build the workspace (cargo test --workspace --no-run)"
    return path


def test_the_same_policies_and_seeds_give_the_table_arena_eval_prints(server, tmp_path):
    policies = ["expert", "idm", "idle"]
    ours = highway_arena.evaluate(policies, ["merge-random"], episodes=3, seed=5, quiet=True)
    command = [str(_arena_binary()), "eval", "--connect", server.endpoint, "--out", str(tmp_path)]
    command += ["--scenario", "merge-random", "--episodes", "3", "--seed", "5"]
    for policy in policies:
        command += ["--policy", policy]
    cli = subprocess.run(command, capture_output=True, text=True, check=True)
    assert ours.markdown in cli.stdout, f"python:\n{ours.markdown}\ncli:\n{cli.stdout}"
    assert ours.summary("merge-random", "expert")["success"]["n"] == 3


def test_an_external_policy_gets_the_figures_of_the_built_in_it_imitates():
    def keep_lane(observation):
        return 1

    result = highway_arena.evaluate(
        {"idle": "idle", "callable": keep_lane}, ["merge-random", "highway"], episodes=2, max_cycles=30, quiet=True
    )
    for scenario in ("merge-random", "highway"):
        built_in, external = result.summary(scenario, "idle"), result.summary(scenario, "callable")
        assert built_in == external, scenario
    k = [key for key, *_ in result.figures].index("return")
    returns = [e["figures"][k] for e in result.episodes]
    assert all(r is not None for r in returns) and len(returns) == 8


def test_results_are_written_with_plots(tmp_path):
    result = highway_arena.evaluate(["expert", "random"], "merge", episodes=2, out=tmp_path, quiet=True)
    names = sorted(os.listdir(tmp_path))
    assert names == [
        "budget.csv", "budget.md", "costs_merge.png", "differences.csv", "episodes.csv", "rates_merge.png",
        "results.csv", "results.json", "results.md",
    ]
    assert (tmp_path / "costs_merge.png").read_bytes().startswith(b"\x89PNG")
    assert result.summary("merge", "expert")["success"]["mean"] == 1.0, "the AV merges"
    assert len((tmp_path / "episodes.csv").read_text().splitlines()) == 1 + 4


def test_a_deterministic_scenario_gets_values_without_intervals_marks_or_probabilities(tmp_path):
    # merge has no randomness: every seed gives each built-in driver the same episode.
    result = highway_arena.evaluate(["expert", "idm"], "merge", episodes=5, bootstrap=200, out=tmp_path, quiet=True)
    differences = result.difference("merge", "idm")
    # One distinct pair, or none where a figure does not apply (IDM changes no lane).
    assert all(d["distinct"] in (0, 1) and not d["significant"] for d in differences.values()), differences
    assert all(d["improvement"] is None for d in differences.values()), differences
    assert differences["return"]["difference"]["low"] == differences["return"]["difference"]["high"]
    assert "| merge | idm | 5 (deterministic: 1 distinct pair) |" in result.markdown, result.markdown
    assert "| **" not in result.markdown, result.markdown
    success = result.summary("merge", "expert")["success"]
    assert (success["low"], success["high"]) == (1.0, 1.0), "no Wilson interval from one distinct episode"
    # IDM stops short of merge's lane end: no crash, no success, and the rates plot shows it.
    summary = next(s for s in result.summaries if s["policy"] == "idm")
    assert dict(summary["outcomes"]) == {
        "success": 0.0, "collision": 0.0, "off_road": 0.0, "lane_end": 0.0, "no_success": 1.0,
    }, summary["outcomes"]


def test_each_policy_is_timed_by_the_clock_of_the_process_that_runs_it():
    calls = []

    def keep_lane(observation):
        calls.append(observation)
        return 1

    result = highway_arena.evaluate(
        {"expert": "expert", "mine": keep_lane}, "merge", episodes=2, max_cycles=20, quiet=True
    )
    budget = {row["policy"]: row for row in result.budget}
    assert budget["expert"]["clock"] == "server" and budget["mine"]["clock"] == "client"
    # One sample per agent and step: merge has one learner, 20 steps an episode.
    assert budget["expert"]["steps"] == 40 and budget["mine"]["steps"] == len(calls) == 40
    assert 0 < budget["expert"]["p50_us"] <= budget["expert"]["p99_us"]
    assert "| expert | server | 40 |" in result.budget_markdown
    # Wall time stays out of the figures: a second run prints the same table.
    again = highway_arena.evaluate({"expert": "expert", "mine": keep_lane}, "merge", episodes=2, max_cycles=20, quiet=True)
    assert again.markdown == result.markdown


def test_differences_are_against_the_reference_seed_by_seed():
    result = highway_arena.evaluate(
        {"idle": "idle", "expert": "expert", "same": "idle"},
        ["merge-random"],
        episodes=4,
        reference="idle",
        bootstrap=500,
        quiet=True,
    )
    same = result.difference("merge-random", "same")
    assert same["return"]["difference"] == {"value": 0.0, "low": 0.0, "high": 0.0}, same["return"]
    assert same["return"]["improvement"]["value"] == 0.5
    # idle runs into merge's lane end; the AV merges: success is higher on every seed.
    expert = result.difference("merge-random", "expert")
    assert expert["success"]["difference"]["value"] == 1.0, expert["success"]
    assert expert["return"]["difference"]["low"] > 0, expert["return"]
    assert result.difference("merge-random", "idle") == {}, "the reference has no difference from itself"
    assert "Paired differences from `idle`" in result.markdown
    iqm = result.summary("merge-random", "expert")["return"]["iqm"]
    assert iqm["low"] <= iqm["value"] <= iqm["high"], iqm


def test_a_league_gathers_python_policies_and_refuses_other_seeds(tmp_path):
    league = tmp_path / "league.json"
    common = dict(episodes=2, max_cycles=20, league=str(league), bootstrap=200, quiet=True)
    highway_arena.evaluate({"idle": "idle"}, "merge-random", **common)
    highway_arena.evaluate({"keep": lambda observation: 1}, "merge-random", **common)
    table = (tmp_path / "league.md").read_text()
    assert "| idle |" in table and "| keep |" in table, table
    before = league.read_text()
    with pytest.raises(ValueError, match="first seed 3, not the league's 0"):
        highway_arena.evaluate({"random": "random"}, "merge-random", seed=3, **common)
    assert league.read_text() == before


def test_cross_play_gives_the_matrices_arena_eval_writes(server, tmp_path):
    def keep_lane(observation):
        return 1

    ours = highway_arena.evaluate({"keep": keep_lane}, ["merge"], episodes=1, opponents=True, quiet=True)
    command = [str(_arena_binary()), "eval", "--connect", server.endpoint, "--out", str(tmp_path)]
    command += ["--scenario", "merge", "--episodes", "1", "--policy", "idle", "--opponents"]
    subprocess.run(command, capture_output=True, text=True, check=True)
    cli = (tmp_path / "crossplay.md").read_text()
    # The CLI's idle and this keep-lane callable drive alike: the same matrices.
    assert ours.crossplay.markdown.replace("| keep |", "| idle |") in cli, f"python:\n{ours.crossplay.markdown}"
    success = ours.crossplay.matrix("merge", "success")
    assert len(success) == 7 and set(success.values()) == {0.0}, success
    # Every cell equals the best (0 %, one distinct episode each): all are near it.
    assert all(c[8] for c in ours.crossplay.cells if c[1] == "success"), ours.crossplay.cells
    written = ours.write(tmp_path / "py")
    assert str(tmp_path / "py" / "crossplay_merge_return.png") in written
    with pytest.raises(ValueError, match="no opponents"):
        highway_arena.evaluate(["idle"], ["highway"], episodes=1, opponents=True, quiet=True)


def test_bad_input_is_refused_by_name():
    with pytest.raises(ValueError, match="bootstrap must be a whole number of resamples, at least 100"):
        highway_arena.evaluate(["idle"], ["merge"], episodes=1, bootstrap=10, quiet=True)
    with pytest.raises(ValueError, match="reference 'ppo' is not one of the policies"):
        highway_arena.evaluate(["idle"], ["merge"], episodes=1, reference="ppo", quiet=True)
    with pytest.raises(ValueError, match="unknown built-in policy 'gt:calm:nash'"):
        highway_arena.evaluate(["gt:calm:nash"], ["merge"], episodes=1, quiet=True)
    with pytest.raises(ValueError, match="episodes must be at least 1"):
        highway_arena.evaluate(["idle"], ["merge"], episodes=0, quiet=True)
    with pytest.raises(ValueError, match="appear twice"):
        highway_arena.evaluate([lambda o: 1, lambda o: 2], ["merge"], episodes=1, quiet=True)
