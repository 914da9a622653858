"""Pure, jit-able SAC updates: each maps (agent, state, data, randomness) to (state, metrics).

Randomness is either a PRNG key or explicit standard-normal noise eps (float array of the shape
the update needs, (B, A)), so tests can replay a reference implementation's noise.
Every update takes one Adam step on its own parameters through `gradient_step` (loss ->
gradient -> device mean -> optimiser) and leaves the rest of the state as is.

Data parallel (`config.data_parallel_axis` set, inside a mapping over that device axis, see
`sac_jax.parallel`): each device holds an equal share B/D of the batch, and each update replaces
its gradient and losses by their mean over the D devices (`jax.lax.pmean`) before the Adam step.
Every objective is a mean over the batch, so with equal shares
grad J(batch) = (1/D) sum_d grad J(share d): the step is the one the whole batch would give, and
parameters and optimiser states stay identical on all devices.
"""

from __future__ import annotations

import math
from typing import Callable, Dict, Tuple, Union

import jax
import jax.numpy as jnp
import optax

from sac_jax import losses
from sac_jax.random_bits import normal_from_bits
from sac_jax.observation_norm import normalize
from sac_jax.agent import Agent, SACState
from sac_jax.replay_buffer import Transition

KeyOrNoise = Union[jax.Array, Dict[str, jax.Array]]
Metrics = Dict[str, jax.Array]


def as_noise(key_or_noise: jax.Array, shape: Tuple[int, ...]) -> jax.Array:
    """Standard-normal noise of `shape`: drawn from a PRNG key, or a float array passed through."""
    if jnp.issubdtype(jnp.asarray(key_or_noise).dtype, jnp.floating):
        if key_or_noise.shape != shape:
            raise ValueError(f"noise has shape {key_or_noise.shape}, expected {shape}")
        return key_or_noise
    return jax.random.normal(key_or_noise, shape)


def mean_over_devices(config, tree):
    """`tree` averaged over the data-parallel device axis `config.data_parallel_axis`;
    unchanged on one device (axis None)."""
    axis = config.data_parallel_axis
    return tree if axis is None else jax.lax.pmean(tree, axis)


def gradient_step(agent: Agent, optimizer: optax.GradientTransformation, objective: Callable,
                  params, opt_state, summarize: Callable = lambda aux: {}):
    """One optimiser step on an objective `objective(params) -> (J, aux)`, the pattern of every
    SAC update: g = grad J(params); J, g and the scalar metrics `summarize(aux)` averaged over
    the data-parallel devices (unchanged on one device); params <- params + optimizer(g).
    Returns (params, opt_state, J, metrics, aux)."""
    (loss, aux), grads = jax.value_and_grad(objective, has_aux=True)(params)
    loss, metrics, grads = mean_over_devices(agent.config, (loss, summarize(aux), grads))
    updates, opt_state = optimizer.update(grads, opt_state, params)
    return optax.apply_updates(params, updates), opt_state, loss, metrics, aux


def polyak_update(target, online, tau: float):
    """theta-bar <- tau theta + (1 - tau) theta-bar, leaf by leaf (`optax.incremental_update`)."""
    return optax.incremental_update(online, target, tau)


def critic_objective(agent: Agent, state: SACState, batch: Transition,
                     key_or_noise: jax.Array) -> Callable:
    """params -> (J_Q(params), Q (N, B)) for a fixed target (see `losses.critic_loss`).

    v2 target: c r + gamma (1 - d)(min_j Q-bar_j(s', a') - alpha log pi(a'|s')),
    a' = f(eps; s'), eps (B, A). v1 target: c r + gamma (1 - d) V-bar(s') (the noise is unused).
    c is `reward_scale`.
    """
    cfg, hp = agent.config, agent.hyperparams
    obs, next_obs = (normalize(state.actor_params, o) for o in (batch.obs, batch.next_obs))
    if cfg.variant == "v2":
        noise = as_noise(key_or_noise, batch.action.shape)
        next_action, next_log_prob = agent.sample_action(state.actor_params, batch.next_obs, noise)
        q_next = agent.critic.apply(state.critic_target_params, next_obs, next_action)
        next_value = jnp.min(q_next, axis=0) - state.alpha * next_log_prob
    else:
        next_value = agent.value.apply(state.value_target_params, next_obs)
    target = jax.lax.stop_gradient(losses.soft_q_target(
        batch.reward, batch.terminated, next_value, hp.gamma, hp.reward_scale))

    def objective(params):
        q = agent.critic.apply(params, obs, batch.action)
        return losses.critic_loss(q, target, hp.loss_coef), q

    return objective


def update_critic(agent: Agent, state: SACState, batch: Transition,
                  key_or_noise: jax.Array) -> Tuple[SACState, Metrics]:
    """One Adam step on J_Q for all N critics at once (see `critic_objective`)."""
    params, opt_state, loss, metrics, _ = gradient_step(
        agent, agent.critic_optimizer, critic_objective(agent, state, batch, key_or_noise),
        state.critic_params, state.critic_opt_state, lambda q: {"q": jnp.mean(q)})
    return (state.replace(critic_params=params, critic_opt_state=opt_state),
            {"critic_loss": loss, **metrics})


def _sampled_q(agent: Agent, state: SACState, actor_params, obs: jax.Array,
               noise: jax.Array) -> Tuple[jax.Array, jax.Array]:
    """(log pi(a~|s) (B,), min_i Q_i(s, a~) (B,)) for a~ = f(eps; s) drawn by `actor_params`
    and the online critics; obs (B, O) raw, eps (B, A)."""
    action, log_prob = agent.sample_action(actor_params, obs, noise)
    q = agent.critic.apply(state.critic_params, normalize(state.actor_params, obs), action)
    return log_prob, jnp.min(q, axis=0)


def actor_objective(agent: Agent, state: SACState, obs: jax.Array,
                    key_or_noise: jax.Array) -> Callable:
    """params -> (J_pi(params), log pi(a~|s) (B,)), J_pi = mean(alpha log pi(a~|s) -
    min_i Q_i(s, a~)), a~ = f_params(eps; s), obs (B, O), eps (B, A)."""
    noise = as_noise(key_or_noise, (obs.shape[0], agent.action_size))

    def objective(params):
        log_prob, q_min = _sampled_q(agent, state, params, obs, noise)
        return losses.actor_loss(log_prob, q_min, state.alpha), log_prob

    return objective


def update_actor(agent: Agent, state: SACState, obs: jax.Array,
                 key_or_noise: jax.Array) -> Tuple[SACState, Metrics]:
    """One Adam step on J_pi (see `actor_objective`). metrics["log_prob"] (B,) is log pi(a~|s)
    before the step (this device's share of the batch)."""
    params, opt_state, loss, metrics, log_prob = gradient_step(
        agent, agent.actor_optimizer, actor_objective(agent, state, obs, key_or_noise),
        state.actor_params, state.actor_opt_state,
        lambda log_prob: {"entropy": -jnp.mean(log_prob)})
    return (state.replace(actor_params=params, actor_opt_state=opt_state),
            {"actor_loss": loss, **metrics, "log_prob": log_prob})


def update_temperature(agent: Agent, state: SACState,
                       log_prob: jax.Array) -> Tuple[SACState, Metrics]:
    """One Adam step on J_alpha over log alpha (see `losses.temperature_loss`), log_prob (B,)
    held constant; afterwards alpha = exp(log alpha)."""
    log_prob = jax.lax.stop_gradient(log_prob)
    objective = lambda log_alpha: (losses.temperature_loss(
        log_alpha, log_prob, agent.hyperparams.target_entropy, agent.config.alpha_loss), None)
    log_alpha, opt_state, loss, _, _ = gradient_step(
        agent, agent.alpha_optimizer, objective, state.log_alpha, state.alpha_opt_state)
    alpha = jnp.exp(log_alpha)
    return (state.replace(log_alpha=log_alpha, alpha=alpha, alpha_opt_state=opt_state),
            {"alpha_loss": loss, "alpha": alpha})


def value_objective(agent: Agent, state: SACState, obs: jax.Array,
                    key_or_noise: jax.Array) -> Callable:
    """params -> J_V(params) (see `losses.value_loss`), target min_i Q_i(s, a~) -
    alpha log pi(a~|s) with a~ = f(eps; s), obs (B, O), eps (B, A)."""
    noise = as_noise(key_or_noise, (obs.shape[0], agent.action_size))
    log_prob, q_min = _sampled_q(agent, state, state.actor_params, obs, noise)
    target = jax.lax.stop_gradient(q_min - state.alpha * log_prob)
    normalized = normalize(state.actor_params, obs)
    return lambda params: losses.value_loss(agent.value.apply(params, normalized), target,
                                            agent.hyperparams.loss_coef)


def update_value(agent: Agent, state: SACState, obs: jax.Array,
                 key_or_noise: jax.Array) -> Tuple[SACState, Metrics]:
    """One Adam step on J_V (see `value_objective`)."""
    objective = value_objective(agent, state, obs, key_or_noise)
    params, opt_state, loss, _, _ = gradient_step(
        agent, agent.value_optimizer, lambda params: (objective(params), None),
        state.value_params, state.value_opt_state)
    return state.replace(value_params=params, value_opt_state=opt_state), {"value_loss": loss}


def _noise_shapes(agent: Agent, batch_size: int) -> Dict[str, Tuple[int, ...]]:
    """{entry: shape} of the noise `agent.config`'s update reads: "critic" and "value" (B, A),
    "actor" and "temperature" (K, B, A) for K = policy_frequency actor steps."""
    k, shape = agent.config.policy_frequency, (batch_size, agent.action_size)
    blocks = {"critic": {"critic": shape}, "value": {"value": shape},
              "actor": {"actor": (k,) + shape, "temperature": (k,) + shape}}
    return {name: s for block in agent.config.update_order for name, s in blocks[block].items()}


def noise_words(agent: Agent, batch_size: int) -> int:
    """How many uint32 words `noise_from_bits` takes: one per number of `sample_noise`."""
    return sum(math.prod(s) for s in _noise_shapes(agent, batch_size).values())


def noise_from_bits(agent: Agent, bits: jax.Array, batch_size: int) -> Dict[str, jax.Array]:
    """`sample_noise`'s dict from `noise_words` uint32 `bits`, in the order of the entries."""
    noise, start = {}, 0
    for name, shape in _noise_shapes(agent, batch_size).items():
        size = math.prod(shape)
        noise[name] = normal_from_bits(bits[start:start + size].reshape(shape))
        start += size
    return noise


def sample_noise(agent: Agent, key: jax.Array, batch_size: int) -> Dict[str, jax.Array]:
    """All standard-normal noise one `sac_update` of `agent.config` reads, from one Threefry
    hash of `key`: "critic", "value" (v1) (B, A); "actor" and "temperature" (K, B, A) for
    K = policy_frequency actor steps."""
    bits = jax.random.bits(key, (noise_words(agent, batch_size),), jnp.uint32)
    return noise_from_bits(agent, bits, batch_size)


def _check_noise(agent: Agent, noise: Dict[str, jax.Array], batch_size: int) -> None:
    """ValueError naming the first entry of `noise` that `agent.config`'s update reads and that
    is missing or not shaped as `sample_noise` draws it."""
    for name, shape in _noise_shapes(agent, batch_size).items():
        if name not in noise:
            raise ValueError(f'noise has no "{name}" entry (it has {sorted(noise)})')
        if tuple(noise[name].shape) != shape:
            raise ValueError(f'noise["{name}"] has shape {tuple(noise[name].shape)}, expected '
                             f"{shape}")


def _actor_block(agent: Agent, state: SACState, obs: jax.Array, noise) -> Tuple[SACState, Metrics]:
    """K actor steps, each followed by a temperature step when alpha is learned; metrics of the
    last step."""
    cfg = agent.config

    def one(state, eps):
        eps_actor, eps_temperature = eps
        state, metrics = update_actor(agent, state, obs, eps_actor)
        log_prob = metrics.pop("log_prob")
        if cfg.learn_alpha:
            if cfg.alpha_log_prob == "resample":
                _, log_prob = agent.sample_action(state.actor_params, obs, eps_temperature)
            state, alpha_metrics = update_temperature(agent, state, log_prob)
            metrics.update(alpha_metrics)
        return state, metrics

    state, metrics = jax.lax.scan(one, state, (noise["actor"], noise["temperature"]))
    return state, jax.tree_util.tree_map(lambda m: m[-1], metrics)


def sac_update(agent: Agent, state: SACState, batch: Transition,
               key_or_noise: KeyOrNoise) -> Tuple[SACState, Metrics]:
    """One SAC gradient update as `agent.config` composes it.

    In `config.update_order`: "critic" (J_Q), "value" (J_V, v1) and the actor block ("actor":
    K = policy_frequency steps of J_pi, each followed by J_alpha if alpha is learned), which runs
    only on every K-th call (CleanRL's delayed policy update). Then, every
    `target_update_period`-th call, Polyak averaging of the critic targets (v2) or of V-bar (v1).
    `key_or_noise` is a PRNG key or a dict as from `sample_noise`. Metrics skipped this call
    (the actor block's when it does not run) are NaN.
    """
    cfg = agent.config
    batch_size = batch.obs.shape[0]
    if isinstance(key_or_noise, dict):
        _check_noise(agent, key_or_noise, batch_size)
        noise = key_or_noise
    else:
        noise = sample_noise(agent, key_or_noise, batch_size)
    count = state.step + 1
    metrics: Metrics = {}
    for name in cfg.update_order:
        if name == "critic":
            state, m = update_critic(agent, state, batch, noise["critic"])
        elif name == "value":
            state, m = update_value(agent, state, batch.obs, noise["value"])
        elif cfg.policy_frequency == 1:
            state, m = _actor_block(agent, state, batch.obs, noise)
        else:
            def skip(state):
                shapes = jax.eval_shape(lambda s: _actor_block(agent, s, batch.obs, noise)[1],
                                        state)
                return state, jax.tree_util.tree_map(
                    lambda s: jnp.full(s.shape, jnp.nan, s.dtype), shapes)

            state, m = jax.lax.cond(count % cfg.policy_frequency == 0,
                                    lambda s: _actor_block(agent, s, batch.obs, noise), skip, state)
        metrics.update(m)
    metrics["alpha"] = state.alpha

    def polyak(state):
        if cfg.variant == "v2":
            return state.replace(critic_target_params=polyak_update(
                state.critic_target_params, state.critic_params, agent.hyperparams.tau))
        return state.replace(value_target_params=polyak_update(
            state.value_target_params, state.value_params, agent.hyperparams.tau))

    if cfg.target_update_period == 1:
        state = polyak(state)
    else:
        state = jax.lax.cond(count % cfg.target_update_period == 0, polyak, lambda s: s, state)
    return state.replace(step=count), metrics
