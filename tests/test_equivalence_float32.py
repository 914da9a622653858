"""sac_jax's presets against the PyTorch references of their seeds, float32, same weights,
batches (B = 64) and injected noise. See docs/equivalence.md for the table of measured errors.

Asserted: the issue's float32 bounds (`ISSUE`) wherever the measurement meets them, and a
looser bound only where it does not (`LOOSER`, with the measured figure and the reason).
float64 (test_equivalence_x64.py) brings every one of these to <= 1e-10, which shows the
float32 residuals are rounding:
    actions                       max abs <= 1e-6
    log-probs                     max abs <= 1e-6; pendulum and v1 per sample <= 1e-6 +
                                  2^-22 * sum_i |d/dy log(scale(1-y^2)+1e-6)| (raw max abs
                                  measured 6.0e-6 and 1.9e-6): XLA's float32 tanh is off by up to
                                  4 ulp (PyTorch's by < 1), and the seeds' epsilon correction
                                  divides that by 1 - tanh(u)^2
    losses                        relative <= 1e-6; cleanrl's actor and alpha losses <= 1e-5
                                  (measured 2.6e-6, 1.3e-6): means of log pi, which carries the
                                  tanh error above
    gradients                     relative <= 1e-5 (per tensor max|diff| / max|ref|; the actor's
                                  measured up to 9.3e-6)
    parameters after one update   max abs <= 1e-6, alpha <= 1e-6; v1's parameters <= 1e-5
                                  (measured 1.9e-6): Adam's first step is lr * g / (|g| + 1e-8),
                                  so elements with |g| near 1e-8 turn a small relative gradient
                                  error into an absolute one of order lr
    200 updates                   alpha relative <= 1e-4; parameters relative <= 1 only (see
                                  test_200_updates): float32 trajectories fan out
"""

from __future__ import annotations

import pytest

from tests.equivalence_harness import FAMILIES, measure

ISSUE = {"action": 1e-6, "log_prob": 1e-6, "loss": 1e-6, "grad": 1e-5, "step_params": 1e-6,
         "step_alpha": 1e-6, "run_alpha": 1e-4, "run_params": 1e-4}
LOOSER = {  # (family, error name) -> bound asserted instead of the issue's
    ("pendulum", "log_prob"): None,  # per sample (log_prob_conditioned), see the docstring
    ("v1", "log_prob"): None,
    ("cleanrl", "actor_loss"): 1e-5,
    ("cleanrl", "alpha_loss"): 1e-5,
    ("v1", "step_params"): 1e-5,
    ("cleanrl", "run_params"): 1.0,
    ("pendulum", "run_params"): 1.0,
    ("v1", "run_params"): 1.0,
}


def bound(family: str, name: str, kind: str = None) -> float:
    """The bound asserted for error `name` of `family`; `kind` names the issue's bound."""
    return LOOSER.get((family, name), ISSUE[kind or name])


@pytest.fixture(scope="module", params=list(FAMILIES))
def errors(request):
    return request.param, measure(request.param, "float32")


def test_actions_and_log_probs(errors):
    family, e = errors
    assert e["action"] <= bound(family, "action"), e
    if bound(family, "log_prob") is None:
        assert e["log_prob_conditioned"] <= 1.0, e
    else:
        assert e["log_prob"] <= bound(family, "log_prob"), e


def test_losses(errors):
    family, e = errors
    names = ["critic_loss", "actor_loss"] + (["value_loss"] if family == "v1" else []) + (
        [] if family == "v1" else ["alpha_loss"])
    for name in names:
        assert e[name] <= bound(family, name, "loss"), (name, e)


def test_gradients(errors):
    family, e = errors
    names = ["critic_grad", "actor_grad"] + (["value_grad"] if family == "v1" else ["alpha_grad"])
    for name in names:
        assert e[name] <= bound(family, name, "grad"), (name, e)


def test_one_update(errors):
    family, e = errors
    assert e["step_params"] <= bound(family, "step_params"), e
    assert e["step_alpha"] <= bound(family, "step_alpha"), e
    assert e["step_log_alpha"] <= bound(family, "step_log_alpha", "step_alpha"), e


def test_200_updates(errors):
    """alpha stays within 1e-4. The parameters do not stay within 1e-4: measured per-tensor
    relative differences after up to 200 updates are 0.43 (cleanrl), 0.13 (pendulum) and
    6e-3 (v1). The cause is float32 rounding carried by the training dynamics (ReLU units
    switching on one sample, Adam normalising near-zero gradient elements), not an algorithmic
    difference: the same run in float64 agrees to <= 1e-11 (test_equivalence_x64.py), and the
    reference's own float32 run leaves its float64 run by 0.20 for cleanrl (the controls in
    `errors`). This test guards against blow-ups only; the float64 test carries the exact
    check."""
    family, e = errors
    assert e["run_alpha"] <= bound(family, "run_alpha"), e
    assert e["run_params"] <= bound(family, "run_params"), e
    assert e["run_params_jax32_vs_torch64"] <= 1.0, e
