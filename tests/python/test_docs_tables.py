"""scripts/docs-tables: the committed docs are what their raw results render, and a figure
changed in a raw result (or in a doc) is caught by --check."""

import importlib.machinery
import importlib.util
import json
import pathlib
import shutil

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def load_renderer():
    loader = importlib.machinery.SourceFileLoader("docs_tables", str(REPO / "scripts" / "docs-tables"))
    spec = importlib.util.spec_from_loader("docs_tables", loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


@pytest.fixture
def copy(tmp_path, monkeypatch):
    """The renderer working on a copy of the repository's docs, results, scenarios and published.toml."""
    renderer = load_renderer()
    for folder in ["docs", "server/paper", "scenarios"]:
        shutil.copytree(REPO / folder, tmp_path / folder, ignore=shutil.ignore_patterns("*.png", "src", "tests"))
    for readme in ["README.md", "clients/python/README.md"]:
        (tmp_path / readme).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(REPO / readme, tmp_path / readme)
    monkeypatch.setattr(renderer, "ROOT", tmp_path)
    return renderer, tmp_path


def test_the_committed_docs_are_what_their_results_render(copy):
    renderer, _ = copy
    assert renderer.render_all(check=True) == 0


def test_a_changed_figure_in_a_raw_result_fails_the_check(copy, capsys):
    renderer, root = copy
    source = root / "docs/results/paper.json"
    records = json.loads(source.read_text())
    run = next(r for r in records if (r["scenario"], r["style"], r["game"]) == ("A", "normal", "nash"))
    run["t_c"] += 0.1
    source.write_text(json.dumps(records, indent=2))
    assert renderer.render_all(check=True) == 1
    diff = capsys.readouterr().out
    assert "-| normal | t_c (s) | 6.50 |" in diff and "+| normal | t_c (s) | 6.60 |" in diff
    # Without --check it rewrites the doc, after which the check passes.
    assert renderer.render_all(check=False) == 0
    assert "| normal | t_c (s) | 6.60 |" in (root / "docs/paper-reproduction.md").read_text()
    assert renderer.render_all(check=True) == 0


def test_a_figure_edited_by_hand_in_a_doc_fails_the_check(copy):
    renderer, root = copy
    doc = root / "docs/paper-reproduction.md"
    text = doc.read_text()
    assert "| aggressive | safety | 30.547 |" in text
    doc.write_text(text.replace("| aggressive | safety | 30.547 |", "| aggressive | safety | 30.548 |", 1))
    assert renderer.render_all(check=True) == 1


def test_a_marker_without_its_end_or_renderer_is_an_error(copy):
    renderer, root = copy
    doc = root / "docs/rewards.md"
    marker = "<!-- table: no-such-table source: docs/results/paper.json command: arena paper commit: 0000000 -->"
    doc.write_text(doc.read_text() + "\n" + marker + "\n<!-- /table -->\n")
    with pytest.raises(renderer.DocError, match="no renderer named"):
        renderer.render_all(check=True)
    doc.write_text(doc.read_text().replace("no-such-table", "paper-table-iv").replace("<!-- /table -->\n", ""))
    with pytest.raises(renderer.DocError, match="no closing"):
        renderer.render_all(check=True)


def test_recomputed_results_compare_to_the_last_bits_a_libm_may_change():
    renderer = load_renderer()
    assert renderer.same({"t_c": 3.4, "rms": [30.54683337835351]}, {"t_c": 3.4, "rms": [30.54683337835352]})
    assert not renderer.same({"t_c": 3.4}, {"t_c": 3.5})
    assert not renderer.same({"rms": [30.546833]}, {"rms": [30.546834]})
    assert renderer.same([["merge", "0.5"]], [["merge", "0.5000000000000001"]])
    assert not renderer.same([["merge", "0.5"]], [["merge", "0.51"]])
    assert not renderer.same([["merge", "left"]], [["merge", "keep"]])
    assert not renderer.same({"collision": False}, {"collision": 0})
    assert renderer.same([["NaN", ""]], [["NaN", ""]])
    assert not renderer.same([["NaN"]], [["0"]])


def test_a_changed_figure_in_an_eval_csv_fails_the_check(copy, capsys):
    renderer, root = copy
    source = root / "docs/results/eval-merge-10.csv"
    text = source.read_text()
    row = next(line for line in text.splitlines() if line.startswith("merge,gt:normal:nash,"))
    fields = row.split(",")
    header = text.splitlines()[0].split(",")
    k = header.index("t_c")
    fields[k] = str(float(fields[k]) + 0.2)
    source.write_text(text.replace(row, ",".join(fields)))
    assert renderer.render_all(check=True) == 1
    assert "+| merge | gt:normal:nash | 10 (1 distinct) | 100 % | 0 % | 6.70 |" in capsys.readouterr().out
