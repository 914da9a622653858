"""The Python examples of the README and of docs/ run as written. A block fenced ```python is a
complete example and runs; one fenced ```python fragment (an excerpt of a module, a signature,
a two-process script) is shown only."""

import glob
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAGES = ["README.md"] + sorted(os.path.relpath(p, ROOT)
                               for p in glob.glob(os.path.join(ROOT, "docs", "*.md")))


def examples(page: str) -> list:
    with open(os.path.join(ROOT, page)) as f:
        return re.findall(r"```python\n(.*?)```", f.read(), re.S)


def test_the_readme_and_the_docs_with_examples_have_them():
    assert len(examples("README.md")) >= 2
    assert {page for page in PAGES if examples(page)} >= {"README.md", "docs/environments.md",
                                                          "docs/parallel.md"}


@pytest.mark.parametrize("page", [p for p in PAGES if examples(p)])
def test_python_examples_run(page, capsys):
    for block in examples(page):
        if "playground" in block:
            pytest.importorskip("mujoco_playground")
        exec(compile(block, os.path.join(ROOT, page), "exec"), {"__name__": "docs"})
    assert "eval" not in capsys.readouterr().err


def test_the_architecture_page_names_every_module_of_the_library():
    with open(os.path.join(ROOT, "docs", "architecture.md")) as f:
        page = f.read()
    modules = {os.path.basename(p) for p in glob.glob(os.path.join(ROOT, "sac_jax", "*.py"))}
    assert sorted(m for m in modules - {"__init__.py"} if f"`{m}`" not in page) == []
