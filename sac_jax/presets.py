"""Named configurations: the seeds' SACs and `fast`, the default.

    cleanrl   seed 002: CleanRL-style SAC v2 on InvertedPendulum-v4
    v1        seeds 000/003: SAC v1 (value network, reward scale 2, fixed alpha = 1) on the
              Bullet-style InvertedPendulum, seed 000's update order V -> pi -> Q -> V-bar
    pendulum  seed 001: SAC v2 on Pendulum-v1 with 3x64 networks and its temperature handling
    fast      InvertedPendulum-v5, tuned by measurement for wall-clock time to a delivered
              policy that solves the task on 2 CPU cores (BENCHMARKS.md); each seed stops
              once its delivered actor scores 1000 of 1000 on all 20 episodes of its
              confirmation and of a re-measurement (`stop_measurements`; a confirmed 955
              delivered 911 in Gymnasium), within a budget of 20,480 steps
    double-pendulum  `fast`'s settings on InvertedDoublePendulum-v5, stopping a seed once its
              delivered actor scores the solved return 9000 over 2 measurements of 100 episodes
              (stopping on one of 20, and on one of 100, one of 4 seeds delivered a policy
              that fell in one of 10 Gymnasium episodes; with 2 of 100 none of 4 did, an H200,
              BENCHMARKS.md)
    CartpoleBalance  `fast`'s settings on MuJoCo Playground's task (the `playground` extra) with
              critic layer norm, stopping a seed once its delivered actor scores 950 of 1000
              over 2 measurements of 20 episodes (the task counts as solved at 900). Layer
              norm makes seeds alike near the top: on an H100 all of 32 seeds vmapped were confirmed at 993.8
              (Playground SAC's final return) within 38,912 steps with it, and not within 61,440
              without it (`benchmarks/preset_search.py --target 993.8`)
    CartpoleSwingup  `fast`'s settings on Playground's swing-up with critic layer norm, 256-wide
              networks, 32 environments, a budget of 819,200 steps evaluated every 16,384 over
              20 episodes, stopping a seed once confirmed at 850 (solved: 800; SAC in TD-MPC2's
              baselines scores 839 after 1M steps), for a GPU. Chosen by
              `benchmarks/preset_search.py` on an H100 against Playground SAC's final return
              (858.1): of 16 seeds vmapped, all were confirmed at it within 787,456 steps (90.1 s)
              with these settings; 12 with 5 episodes per evaluation, 13 or 15 with a target
              entropy of -3 (64- or 256-wide), 11 with `fast`'s 64-wide networks whether over 8
              environments and 204,800 steps or these 32 and 819,200 (`-envs32c-h100.json`,
              `-envs32-h100.json`); evaluating every 8,192 steps instead, 14 and 15 of 16
              reached the peer's 858.4 (`-eval8k-h100.json`), and 50 episodes per evaluation
              picked the same actors as 20 (`-eval50-h100.json`); learning rates 1e-3,
              observation normalisation, or both, got 14, 14 and 15 of 16 to 858.4 within
              803,840 steps (`-lrnorm-h100.json`), and bfloat16 hidden layers 12 of 16, no
              faster per step (`-bf16-h100.json`). On 8 seeds (an H200) layer norm
              had delivered 863.7 on average (min 841.8) against 850.0 (825.1) without
    PendulumSwingup  CartpoleSwingup's settings with learning rates 1e-3, a starting temperature
              of 0.1 and 5 episodes per evaluation (256-wide networks, 32 environments and
              819,200 steps evaluated every 16,384, for a GPU); no stop at the task's solved
              return (300). On an H100 (`benchmarks/preset_search.py`), with 8 environments
              and 409,600 steps, learning rates 1e-3 and a temperature of 0.1 against 3e-3 and
              1: 8 seeds delivered 588.3 on average (6 of 8 at 630 or more) against 516.5, and
              16 other seeds 582.0 (13 of 16 at 265.5 or more) against 465.3 (12 of 16)
              (`preset_search-PendulumSwingup-alpha-h100.json`, `-alpha16-h100.json`);
              256-wide networks had delivered 290 against 156 with 64-wide ones (8 seeds,
              H200). 32 environments instead of 8 step 4x as far per iteration at about the
              same cost (its 4 updates dominate): 8 seeds delivered 505.3 on average (6 of 8
              over 300, lowest 205.7) after 819,200 steps in 64.6 s, against 532.0 (5 of 8,
              lowest 50.2) after 409,600 in 114.2 s (`-envs32-h100.json`), and 16 seeds vmapped
              were all confirmed at Playground SAC's final 38.9 within 443,392 steps, in 1.35x
              one seed's time (an H100, 2026-11-27; an H200 stopping at 2 measurements: within
              361,472 steps, 1.92x, `playground_peer-PendulumSwingup-h200.json`), where with 8
              environments 1 of 16 was not within 409,600 steps (`-envs32-target16-h100.json`).
              SAC in TD-MPC2's baselines: 354 after 1M steps. 16 seeds vmapped take 1.9x one
              seed's time per chunk on an H100 (8 environments: 2.75 s against 1.45 s): the
              same kernels, each about twice as long, the update's 256-wide matrix products
              most (`profile_chunk-PendulumSwingup-h100.json`)
    AcrobotSwingup  PendulumSwingup's with Playground SAC's updates: 8 per step, batch 512,
              tau 0.005, 8,192 steps before learning, a starting temperature of 1, and
              observation normalisation, over 256 environments for 8,192,000 steps evaluated
              every 8,192 (a GPU preset; no solved return set). Chosen on an H100
              (`benchmarks/preset_search.py`, 16 seeds; Playground SAC's final return was 12.3,
              118.8 and 65.9 in three runs of it, `playground_peer-AcrobotSwingup-h100.json`):
              with 128 environments and 409,600 steps 1 or 2 seeds were not confirmed at 12.3,
              whatever the environments (64), starting temperature (0.1) or updates per step
              (16) (`preset_search-AcrobotSwingup-h100.json`), nor 1 with 819,200 steps
              (`-budget-h100.json`); 256 environments confirmed all 16 at 12.3 within 688,128
              steps in 52.1 s (`-envs256-h100.json`). Over 4,096,000 steps, normalised
              observations delivered 64.4 on average (lowest 28.7; 2 seeds over 118.8) in
              180.4 s, against 38.1 (15.6; 1 seed) in 166.2 s without (`-norm-h100.json`,
              `-4m-h100.json`; both with 256 environments, the preset's then). For one seed
              512 environments or 4 updates per step were no faster to 65.9 (neither reached
              it in 4,096,000 steps, `-speed1-h100.json`); evaluating every 32,768 steps,
              16 seeds ran 4,096,000 steps in 134.9 s against 174.5 s, but 4 reached 65.9
              against 6, and 6 within 6,144,000 steps (`-eval32k-h100.json`); 20 episodes
              per evaluation, 6 of 16 (`-eval20-h100.json`). Its evaluations are stepped
              alongside training (`eval_alongside`): they had taken 60 % of one seed's time
              on an H100; the same actors scored, 16 seeds ran 4,096,000 steps in 139.5 s
              instead of 174.5 s (`playground_peer-AcrobotSwingup-h100.json`, BENCHMARKS.md).
              Without stopping, 16 seeds delivered 62.1 on average at 4,096,000 steps and
              96.4 at 8,192,000 (10 over Playground SAC's 65.9, 6 over its 118.8), all in
              244.3 s (`-8m-h100.json`): hence 8,192,000. Those were best-of confirmations,
              which overstated this task's policies (one delivered actor confirmed at 100.2
              scored 32.9 +- 99.4 over 20 fresh episodes). With the paired selection
              (`sac_jax.selection`) 16 seeds' kept scores averaged 39.2 and their delivered
              actors 40.1 over 100 fresh episodes each (`-paired-h100.json`, 231.2 s)
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
        log_prob_correction="exact", stop_when_solved=True),
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
    env="playground/AcrobotSwingup", num_envs=256, updates_per_step=8, batch_size=512,
    total_steps=8_192_000, buffer_size=8_192_000, eval_every=8_192, tau=0.005,
    learning_starts=8_192, alpha_init=1.0, normalize_observations=True, eval_alongside=True)
DEFAULT_PRESET = "fast"
