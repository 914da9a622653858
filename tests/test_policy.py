"""The tanh-squashed Gaussian: bounds, finite log-probs at saturation, the exact density."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sac_jax.policy import deterministic_action, squashed_gaussian_sample

SCALE, BIAS = jnp.array([3.0, 0.5]), jnp.array([0.0, 1.0])  # bounds [-3, 3] and [0.5, 1.5]


@pytest.mark.parametrize("correction", ["exact", "epsilon"])
def test_actions_within_bounds_and_log_probs_finite_at_saturation(correction):
    mean = jnp.array([[50.0, -50.0], [0.0, 0.0], [-1e4, 1e4]])
    log_std = jnp.array([[2.0, 2.0], [-20.0, 2.0], [-5.0, -5.0]])
    noise = jax.random.normal(jax.random.key(0), (64,) + mean.shape)
    action, log_prob = jax.vmap(
        lambda eps: squashed_gaussian_sample(mean, log_std, eps, SCALE, BIAS, correction))(noise)
    low, high = BIAS - SCALE, BIAS + SCALE
    assert bool(jnp.all((action >= low) & (action <= high)))
    assert bool(jnp.all(jnp.isfinite(log_prob))), log_prob
    grads = jax.grad(lambda m: squashed_gaussian_sample(
        m, log_std, noise[0], SCALE, BIAS, correction)[1].sum())(mean)
    assert bool(jnp.all(jnp.isfinite(grads)))


def test_exact_log_prob_is_the_change_of_variables_density():
    """log pi(a) = log N(u) - log|da/du| with da/du = scale (1 - tanh(u)^2), checked in float64
    numpy against the float32 result (tolerance 1e-5 absolute: about ten float32 roundings of
    terms below 4 in magnitude, at most 2.4e-7 each, leave a factor of 4)."""
    mean, log_std = jnp.array([[0.3, -0.2]]), jnp.array([[-0.5, 0.1]])
    noise = jnp.array([[0.7, -1.3]])
    _, log_prob = squashed_gaussian_sample(mean, log_std, noise, SCALE, BIAS, "exact")
    m, s, e = (np.asarray(x, np.float64) for x in (mean, jnp.exp(log_std), noise))
    u = m + s * e
    normal = -0.5 * e ** 2 - np.log(s) - 0.5 * np.log(2 * np.pi)
    jacobian = np.log(np.asarray(SCALE, np.float64) * (1 - np.tanh(u) ** 2))
    np.testing.assert_allclose(log_prob, (normal - jacobian).sum(-1), atol=1e-5)


def test_epsilon_and_exact_agree_away_from_saturation():
    """The actions are the same float32 tanh (1e-6: a few ulps of |a| < 2, 2.4e-7 each); the
    log-probs differ by the 1e-6 inside the epsilon correction's log, divided by
    scale (1 - tanh(u)^2) > 0.45 here, for each of 2 dimensions: under 1e-5."""
    mean, log_std = jnp.zeros((1, 2)), jnp.full((1, 2), -1.0)
    noise = jnp.array([[0.5, -0.5]])
    a1, lp1 = squashed_gaussian_sample(mean, log_std, noise, SCALE, BIAS, "exact")
    a2, lp2 = squashed_gaussian_sample(mean, log_std, noise, SCALE, BIAS, "epsilon")
    np.testing.assert_allclose(a1, a2, atol=1e-6)
    np.testing.assert_allclose(lp1, lp2, atol=1e-5)  # differs by the 1e-6 inside the log


def test_deterministic_action_is_the_squashed_mean():
    mean = jnp.array([[0.0, 100.0]])
    np.testing.assert_allclose(deterministic_action(mean, SCALE, BIAS), [[0.0, 1.5]])
