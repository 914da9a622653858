"""benchmarks/provenance.py: a results file's command pastes back into a shell as the arguments
that ran, and names the commit measured."""

from __future__ import annotations

import re
import shlex
import sys

from benchmarks import provenance


def test_the_command_quotes_each_argument_and_the_commit_is_recorded(monkeypatch):
    argv = ["benchmarks/playground_peer.py", "--variant", '{"tau": 0.01}', "--seeds", "16"]
    monkeypatch.setattr(sys, "argv", argv)
    source = provenance.provenance()
    assert shlex.split(source["command"])[-4:] == argv[1:], source["command"]
    assert re.fullmatch(r"[0-9a-f]{40}", source["commit"]), source["commit"]
    assert isinstance(source["changed"], bool)
