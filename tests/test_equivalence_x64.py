"""The equivalence measurements of test_equivalence_float32.py in float64 (JAX x64, torch
double): every difference, the 200-update run included, is <= 1e-10, so the float32 residuals
are rounding. Bound: float64's 2.2e-16 times the 200 updates' amplification, which stays
linear in float64 (no ReLU unit switches on a 1e-16 difference): measured x1e4 (2.1e-12), so
1e-10 allows x4.5e5, while float32's rounding errors alone reach 6e-8. Runs `python -m tests.equivalence_x64` in a subprocess with JAX_ENABLE_X64=1, so
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
