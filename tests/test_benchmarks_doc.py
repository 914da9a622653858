"""BENCHMARKS.md's generated tables are what benchmarks/results/*.json hold: a figure cannot be
edited by hand away from the run that produced it (`python -m benchmarks.tables` rewrites them)."""

from benchmarks import tables


def test_generated_tables_match_the_results_files():
    with open(tables.DOC) as f:
        text = f.read()
    assert len(tables.BLOCK.findall(text)) == len(tables.TABLES)
    assert tables.render(text) == text, "run: python -m benchmarks.tables"
