"""BENCHMARKS.md's generated tables are what benchmarks/results/*.json hold: a figure cannot be
edited by hand away from the run that produced it (`python -m benchmarks.tables` rewrites them)."""

import glob
import os
import re

from benchmarks import tables


def test_generated_tables_match_the_results_files():
    names = []
    for doc in tables.DOCS:
        with open(doc) as f:
            text = f.read()
        names += [match[1] for match in tables.BLOCK.findall(text)]
        assert tables.render(text) == text, f"{doc}: run python -m benchmarks.tables"
    assert sorted(names) == sorted(tables.TABLES)  # each table on one page, once


def test_a_missing_results_file_names_the_command_that_writes_it(monkeypatch, tmp_path):
    monkeypatch.setattr(tables, "RESULTS", str(tmp_path))
    for name in set(tables.TABLES) - {"targets"}:  # every table (the targets': below)
        text = tables.TABLES[name]()
        assert text.startswith("_not measured yet: run `"), (name, text)
        assert "|" not in text, name  # no table without figures
    rows = tables.targets().splitlines()[2:]
    assert len(rows) == len(tables.TARGETS)
    assert all("_not measured yet_" in row for row in rows)


def test_every_results_file_the_docs_name_is_there():
    """A results file named in BENCHMARKS.md or docs/ (`name.json`; `-part-` abbreviations
    aside) exists: the evidence a page cites is in the repository, not only in git history."""
    root = os.path.dirname(tables.DOC)
    pages = [tables.DOC] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    missing = {}
    for page in pages:
        with open(page) as f:
            names = set(re.findall(r"`([A-Za-z][\w.-]*\.json)`", f.read()))
        missing.update({name: page for name in names
                        if not os.path.exists(os.path.join(tables.RESULTS, name))})
    assert not missing, missing
