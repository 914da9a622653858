"""The README's Python examples run as written."""

import os
import re

README = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "README.md")


def test_readme_python_examples_run(capsys):
    blocks = re.findall(r"```python\n(.*?)```", open(README).read(), re.S)
    assert len(blocks) >= 2
    for block in blocks:
        exec(compile(block, README, "exec"), {"__name__": "readme"})
    assert "eval" not in capsys.readouterr().err
