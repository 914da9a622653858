"""Named configurations: the seeds' SACs, `fast` (the default) and presets tuned per task.

    cleanrl   seed 002: CleanRL-style SAC v2 on InvertedPendulum-v4
    v1        seeds 000/003: SAC v1 (value network, reward scale 2, fixed alpha = 1) on the
              Bullet-style InvertedPendulum, seed 000's update order V -> pi -> Q -> V-bar
    pendulum  seed 001: SAC v2 on Pendulum-v1 with 3x64 networks and its temperature handling
    fast      InvertedPendulum-v5, tuned for wall-clock time to a delivered policy on 2 CPU
              cores; a seed stops once its delivered actor scores 1000 over 2 measurements
    double-pendulum  `fast`'s settings on InvertedDoublePendulum-v5, stopping at 9350 (of
              about 9360, no fall; solved: 9000) over 5 measurements of 100 episodes
    CartpoleBalance  `fast`'s settings with critic layer norm on MuJoCo Playground's task,
              stopping at 950 of 1000 (the `playground` extra; CPU or GPU)
    CartpoleSwingup  `fast`'s settings with critic layer norm, 256-wide networks, 32
              environments, 819,200 steps, 20 episodes per evaluation, stopping at 850 (a GPU
              preset)
    PendulumSwingup  CartpoleSwingup's with learning rates 1e-3, a starting temperature of 0.1
              and 5 episodes per evaluation; no stop (a GPU preset)
    AcrobotSwingup  PendulumSwingup's with 512-wide networks, Playground SAC's updates (8 per
              step, batch 512, tau 0.005, 8,192 steps before learning), a starting
              temperature of 1, observation normalisation, 256 environments, 8,192,000 steps
              evaluated every 8,192, evaluations stepped alongside training (a GPU preset)

The measurements that chose each tuned preset's numbers, with their result files:
docs/presets.md.
"""

from sac_jax.config import SACConfig

PRESETS = {
    "cleanrl": SACConfig(
        env="InvertedPendulum-v4", total_steps=30_000, learning_starts=5_000,
        buffer_size=1_000_000, batch_size=256, gamma=0.99, tau=0.005, policy_frequency=2,
        target_update_period=1, actor_lr=3e-4, critic_lr=1e-3, alpha_lr=1e-3,
        actor_hidden=(256, 256), critic_hidden=(256, 256), init="torch",
        log_std_mode="tanh", log_std_min=-5.0, log_std_max=2.0,
        log_prob_correction="epsilon", alpha_loss="alpha", alpha_log_prob="resample"),
    "v1": SACConfig(
        env="InvertedPendulumBullet-v0", variant="v1", total_steps=20_000,
        learning_starts=1_000, batch_size=256, gamma=0.99, tau=0.005, reward_scale=2.0,
        loss_coef=0.5, update_order=("value", "actor", "critic"), learn_alpha=False,
        alpha_init=1.0, actor_lr=3e-4, critic_lr=3e-4, value_lr=3e-4,
        actor_hidden=(256, 256), critic_hidden=(256, 256), init="torch", last_layer_init=3e-3,
        log_std_mode="clip", log_std_min=-20.0, log_std_max=2.0,
        log_prob_correction="epsilon"),
    "pendulum": SACConfig(
        env="Pendulum-v1", total_steps=11_000, learning_starts=1_000, batch_size=256,
        eval_every=2_000, gamma=0.99, tau=0.005, actor_lr=3e-4, critic_lr=3e-4, alpha_lr=3e-4,
        actor_hidden=(64, 64, 64), critic_hidden=(64, 64, 64), init="xavier",
        separate_log_std_network=True, log_std_mode="clip", log_std_min=-20.0,
        log_std_max=2.0, log_prob_correction="epsilon", alpha_init=0.5, log_alpha_init=0.0,
        alpha_loss="log_alpha", alpha_log_prob="reuse"),
    "fast": SACConfig(
        env="InvertedPendulum-v5", num_envs=8, updates_per_step=4, total_steps=20_480,
        learning_starts=1_024, buffer_size=20_480, batch_size=256, eval_every=1_024,
        eval_episodes=5, tau=0.02, actor_lr=3e-3, critic_lr=3e-3, alpha_lr=1e-3,
        actor_hidden=(64, 64), critic_hidden=(64, 64), log_std_mode="tanh",
        log_prob_correction="exact", stop_when_solved=True, stop_return=1000.0),
    "double-pendulum": SACConfig(
        env="InvertedDoublePendulum-v5", num_envs=8, updates_per_step=4, total_steps=102_400,
        learning_starts=1_024, buffer_size=102_400, batch_size=256, eval_every=1_024,
        eval_episodes=5, confirm_episodes=100, tau=0.02, actor_lr=3e-3, critic_lr=3e-3,
        alpha_lr=1e-3, actor_hidden=(64, 64), critic_hidden=(64, 64), log_std_mode="tanh",
        log_prob_correction="exact", stop_when_solved=True, stop_return=9350.0,
        stop_measurements=5),
}
PRESETS["CartpoleBalance"] = PRESETS["fast"].replace(env="playground/CartpoleBalance",
                                                     critic_layer_norm=True, stop_return=950.0)
PRESETS["CartpoleSwingup"] = PRESETS["fast"].replace(
    env="playground/CartpoleSwingup", num_envs=32, total_steps=819_200, buffer_size=819_200,
    eval_every=16_384, eval_episodes=20, actor_hidden=(256, 256), critic_hidden=(256, 256),
    critic_layer_norm=True, stop_return=850.0)
PRESETS["PendulumSwingup"] = PRESETS["CartpoleSwingup"].replace(
    env="playground/PendulumSwingup", eval_episodes=5, actor_lr=1e-3, critic_lr=1e-3,
    alpha_init=0.1, stop_when_solved=False, stop_return=None)
PRESETS["AcrobotSwingup"] = PRESETS["PendulumSwingup"].replace(
    env="playground/AcrobotSwingup", actor_hidden=(512, 512), critic_hidden=(512, 512),
    num_envs=256, updates_per_step=8, batch_size=512,
    total_steps=8_192_000, buffer_size=8_192_000, eval_every=8_192, tau=0.005,
    learning_starts=8_192, alpha_init=1.0, normalize_observations=True, eval_alongside=True)
DEFAULT_PRESET = "fast"
