"""The equivalence measurements of test_equivalence_float32.py in float64 (JAX x64, torch
double): every difference, the 200-update run included, is <= 1e-10, so the float32 residuals
are rounding. Runs `python -m tests.equivalence_x64` in a subprocess with JAX_ENABLE_X64=1, so
x64 does not reach this process."""

from __future__ import annotations

import pytest

from tests.equivalence_harness import FAMILIES
from tests.subprocess_json import run_json


@pytest.fixture(scope="module")
def errors():
    return run_json(["-m", "tests.equivalence_x64"], JAX_ENABLE_X64="1")


@pytest.mark.parametrize("family", list(FAMILIES))
def test_float64_agrees_to_rounding(errors, family):
    e = errors[family]
    expected = {"action", "log_prob", "critic_loss", "critic_grad", "actor_loss", "actor_grad",
                "step_params", "step_alpha", "run_params", "run_alpha"}
    assert expected <= set(e), e
    bad = {k: v for k, v in e.items() if k != "log_prob_conditioned" and not v <= 1e-10}
    assert not bad, bad
