"""SACConfig validation: every rule raises ValueError naming the field; presets are valid."""

import dataclasses

import pytest

from sac_jax import PRESETS, SACConfig

BAD_VALUES = [
    ("env", "CartPole-v9", "unknown environment"),
    ("env", 3, "must be an environment's name"),
    ("env", None, "must be an environment's name"),
    ("actor_hidden", 256, r"must be a tuple, e\.g\. \(256, 256\)"),
    ("update_order", "critic", r"must be a tuple, e\.g\. \('critic', 'actor'\)"),
    ("variant", "v3", "must be one of"),
    ("num_envs", 0, "positive integer"),
    ("num_envs", 2.5, "positive integer"),
    ("batch_size", -1, "positive integer"),
    ("total_steps", True, "positive integer"),
    ("updates_per_step", 0, "positive integer"),
    ("buffer_size", 0, "positive integer"),
    ("eval_episodes", 0, "positive integer"),
    ("confirm_episodes", 0, "positive integer"),
    ("policy_frequency", 0, "positive integer"),
    ("num_critics", 0, "positive integer"),
    ("stop_measurements", 0, "positive integer"),
    ("tau", 0.0, r"\(0, 1\]"),
    ("tau", 1.5, r"\(0, 1\]"),
    ("gamma", 1.01, r"\[0, 1\]"),
    ("actor_lr", 0.0, "> 0"),
    ("critic_lr", float("nan"), "finite"),
    ("alpha_init", -1.0, "> 0"),
    ("reward_scale", 0.0, "> 0"),
    ("actor_hidden", (), "non-empty"),
    ("critic_hidden", (256, 0), "positive integers"),
    ("init", "he", "must be one of"),
    ("log_std_mode", "softplus", "must be one of"),
    ("log_prob_correction", "none", "must be one of"),
    ("alpha_loss", "beta", "must be one of"),
    ("alpha_log_prob", "cached", "must be one of"),
    ("hidden_dtype", "float16", "must be one of"),
    ("log_std_min", 3.0, "below log_std_max"),
    ("last_layer_init", -0.1, "> 0"),
    ("target_entropy", float("inf"), "finite"),
    ("update_order", ("actor", "value"), "must be one of"),
    ("data_parallel_axis", "", "non-empty axis name"),
    ("data_parallel_axis", 0, "non-empty axis name"),
    ("critic_layer_norm", 1, "True or False"),
    ("env_impl", "warp", "only MuJoCo Playground tasks"),
    ("learn_alpha", "yes", "True or False"),
    ("eval_alongside", 1, "True or False"),
]


@pytest.mark.parametrize("field, value, rule", BAD_VALUES,
                         ids=[f"{f}={v!r}" for f, v, _ in BAD_VALUES])
def test_bad_value_raises_naming_field_and_rule(field, value, rule):
    with pytest.raises(ValueError, match=rf"SACConfig\.{field}=.*{rule}"):
        SACConfig(**{field: value})


def test_eval_alongside_is_refused_in_a_data_parallel_run():
    with pytest.raises(ValueError, match=r"SACConfig\.eval_alongside=True: .*data-parallel"):
        SACConfig(eval_alongside=True, data_parallel_axis="data")


def test_batch_larger_than_capacity():
    with pytest.raises(ValueError, match=r"SACConfig\.batch_size=512: must not exceed buffer_size"):
        SACConfig(batch_size=512, buffer_size=256, learning_starts=512)


def test_learning_starts_smaller_than_batch():
    with pytest.raises(ValueError, match=r"SACConfig\.learning_starts=100: must be at least batch"):
        SACConfig(learning_starts=100, batch_size=256)


def test_sizes_must_divide_into_whole_iterations():
    with pytest.raises(ValueError, match=r"SACConfig\.learning_starts=.*multiple of num_envs"):
        SACConfig(num_envs=3, learning_starts=1000)
    with pytest.raises(ValueError, match=r"SACConfig\.eval_every=.*multiple of num_envs"):
        SACConfig(num_envs=4, learning_starts=1000, eval_every=1001)
    with pytest.raises(ValueError, match=r"SACConfig\.buffer_size=.*multiple of num_envs"):
        SACConfig(num_envs=4, learning_starts=1000, eval_every=1000, buffer_size=1001)


def test_total_steps_must_reach_one_evaluation():
    with pytest.raises(ValueError, match=r"SACConfig\.total_steps=.*learning_starts \+ eval_every"):
        SACConfig(total_steps=5000, learning_starts=5000, eval_every=1000)


def test_total_steps_must_fit_the_int32_step_count():
    with pytest.raises(ValueError,
                       match=r"SACConfig\.total_steps=2147483648: must be below 2\*\*31"):
        SACConfig(total_steps=2 ** 31)
    assert SACConfig(total_steps=2 ** 31 - 1).total_steps == 2 ** 31 - 1


@pytest.mark.parametrize("field,value", [("gamma", "0.9"), ("gamma", True), ("tau", None),
                                         ("target_entropy", "x"), ("actor_lr", float("inf"))])
def test_real_fields_refuse_what_is_not_a_finite_number(field, value):
    with pytest.raises(ValueError, match=rf"SACConfig\.{field}=.*: must be a finite number"):
        SACConfig(**{field: value})


def test_v1_rejects_a_learned_temperature():
    with pytest.raises(ValueError, match=r"SACConfig\.learn_alpha=True"):
        SACConfig(variant="v1", update_order=("value", "actor", "critic"))


def test_replace_validates_and_rejects_unknown_fields():
    config = SACConfig()
    assert config.replace(batch_size=128).batch_size == 128
    with pytest.raises(ValueError, match="no field"):
        config.replace(batch=128)
    with pytest.raises(ValueError, match=r"SACConfig\.tau"):
        config.replace(tau=2.0)


def test_config_is_frozen_and_hashable():
    config = SACConfig(actor_hidden=[64, 64])  # a list from JSON or a CLI becomes a tuple
    assert config.actor_hidden == (64, 64)
    assert hash(config) == hash(SACConfig(actor_hidden=(64, 64)))
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.batch_size = 1


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_are_valid_and_derived_sizes_consistent(name):
    config = PRESETS[name]
    assert config.prefill_iterations * config.num_envs == config.learning_starts
    assert config.num_evals >= 1
    assert config.replace() == config


def test_stop_return_defaults_to_the_tasks_solved_return():
    import envs
    config = SACConfig(env="Pendulum-v1", stop_when_solved=True)
    assert config.stop_at == envs.spec("Pendulum-v1").solved_return
    assert config.replace(stop_return=-100.0).stop_at == -100.0
    with pytest.raises(ValueError,
                       match=r"SACConfig.stop_return=nan: must be a finite number or None"):
        config.replace(stop_return=float("nan"))


def test_run_steps_is_what_a_run_takes():
    """v1: 20000 total steps of which 1000 prefill and three whole periods of 5000 run."""
    assert PRESETS["v1"].run_steps == 16_000 and PRESETS["fast"].run_steps == 20_480
