"""benchmarks/provenance.py: a results file's command pastes back into a shell as the arguments
that ran, and names the commit measured."""

from __future__ import annotations

import re
import shlex
import sys

import pytest

from benchmarks import provenance


def test_the_command_quotes_each_argument_and_the_commit_is_recorded(monkeypatch):
    argv = ["benchmarks/playground_peer.py", "--variant", '{"tau": 0.01}', "--seeds", "16"]
    monkeypatch.setattr(sys, "argv", argv)
    source = provenance.provenance()
    assert shlex.split(source["command"])[-4:] == argv[1:], source["command"]
    assert re.fullmatch(r"[0-9a-f]{40}", source["commit"]), source["commit"]
    assert isinstance(source["changed"], bool)


def test_the_machine_names_the_cpu_beyond_its_model_name(monkeypatch):
    fields = {"model name": "Intel(R) Xeon(R) Processor", "cpu family": "6", "model": "167",
              "stepping": "1", "cpu MHz": "2599.998",
              "flags": "fpu sse4_2 fma avx2 avx512f avx512bw"}
    monkeypatch.setattr(provenance, "_cpuinfo", lambda: fields)
    machine = provenance.provenance()["machine"]
    assert machine["cpu"] == "Intel(R) Xeon(R) Processor"
    assert machine["cpu_id"] == "cpu family 6 model 167 stepping 1"
    assert machine["mhz"] == 2600
    assert machine["vector_extensions"] == ["avx512f", "avx2", "fma", "sse4_2"]
    fields["flags"] = "fpu sse4_2"
    assert provenance.provenance()["machine"]["vector_extensions"] == ["sse4_2"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/cpuinfo")
def test_the_first_processor_is_read_from_proc_cpuinfo():
    info = provenance._cpuinfo()
    assert info["processor"] == "0", info
