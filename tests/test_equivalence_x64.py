"""The equivalence measurements of test_equivalence_float32.py in float64 (JAX x64, torch
double): every difference, the 200-update run included, is <= 1e-10, so the float32 residuals
are rounding. Runs `python -m tests.equivalence_x64` in a subprocess with JAX_ENABLE_X64=1, so
x64 does not reach this process."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.equivalence_harness import FAMILIES

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def errors():
    env = dict(os.environ, JAX_ENABLE_X64="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [ROOT, env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-m", "tests.equivalence_x64"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("family", list(FAMILIES))
def test_float64_agrees_to_rounding(errors, family):
    e = errors[family]
    expected = {"action", "log_prob", "critic_loss", "critic_grad", "actor_loss", "actor_grad",
                "step_params", "step_alpha", "run_params", "run_alpha"}
    assert expected <= set(e), e
    bad = {k: v for k, v in e.items() if k != "log_prob_conditioned" and not v <= 1e-10}
    assert not bad, bad
