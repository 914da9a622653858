"""sac_jax's presets against the PyTorch references of their seeds, float32, same weights,
batches (B = 64) and injected noise. See docs/equivalence.md for the table of measured errors.

Asserted (each loosened bound has its reason next to it; float64 in test_equivalence_x64.py
brings every one of these to <= 1e-10, which shows the float32 residuals are rounding):
    actions                       max abs <= 1e-6
    log-probs                     max abs <= 1e-6 + 2^-22 * sum_i |d/dy log(scale(1-y^2)+1e-6)|
                                  per sample (raw max abs measured up to 6e-6): XLA's float32
                                  tanh is off by up to 4 ulp (PyTorch's by < 1), and the
                                  seeds' epsilon correction divides that by 1 - tanh(u)^2
    losses                        relative <= 1e-5 (measured <= 2.6e-6): the actor and alpha
                                  losses are means of log pi, which carries the tanh error above
    critic, value, alpha grads    relative <= 1e-5 (per tensor max|diff| / max|ref|)
    actor grads                   relative <= 3e-5 (measured <= 9.3e-6): d log pi / d u carries
                                  the same tanh error through 2y / (1 - y^2)
    parameters after one update   max abs <= 1e-5 (measured <= 1.9e-6), alpha <= 1e-6: Adam's
                                  first step is lr * g / (|g| + 1e-8), so elements with |g|
                                  near 1e-8 turn a small relative gradient error into an
                                  absolute one of order lr
    200 updates                   alpha relative <= 1e-4; parameters relative <= 1 only (see
                                  test_200_updates): float32 trajectories fan out
"""

from __future__ import annotations

import pytest

from tests.equivalence_harness import FAMILIES, measure


@pytest.fixture(scope="module", params=list(FAMILIES))
def errors(request):
    return request.param, measure(request.param, "float32")


def test_actions_and_log_probs(errors):
    family, e = errors
    assert e["action"] <= 1e-6, e
    assert e["log_prob_conditioned"] <= 1.0, e


def test_losses(errors):
    family, e = errors
    names = ["critic_loss", "actor_loss"] + (["value_loss"] if family == "v1" else []) + (
        [] if family == "v1" else ["alpha_loss"])
    for name in names:
        assert e[name] <= 1e-5, (name, e)


def test_gradients(errors):
    family, e = errors
    names = ["critic_grad"] + (["value_grad"] if family == "v1" else ["alpha_grad"])
    for name in names:
        assert e[name] <= 1e-5, (name, e)
    assert e["actor_grad"] <= 3e-5, e


def test_one_update(errors):
    family, e = errors
    assert e["step_params"] <= 1e-5, e
    assert e["step_alpha"] <= 1e-6 and e["step_log_alpha"] <= 1e-6, e


def test_200_updates(errors):
    """alpha stays within 1e-4. The parameters do not stay within 1e-4: measured per-tensor
    relative differences after up to 200 updates are 0.43 (cleanrl), 0.13 (pendulum) and
    6e-3 (v1). The cause is float32 rounding carried by the training dynamics (ReLU units
    switching on one sample, Adam normalising near-zero gradient elements), not an algorithmic
    difference: the same run in float64 agrees to <= 1e-11 (test_equivalence_x64.py). The
    controls in `errors` compare each float32 run with the float64 reference run. This test
    guards against blow-ups only; the float64 test carries the exact check."""
    family, e = errors
    assert e["run_alpha"] <= 1e-4, e
    assert e["run_params"] <= 1.0, e
    assert e["run_params_jax32_vs_torch64"] <= 1.0, e
