"""`SACConfig`: the static description of one SAC run, validated when built.

Every field is a plain Python value, so a config is hashable and can be closed over by
`jax.jit`. Building a config with a bad value raises `ValueError` naming the field and the
rule it breaks; nothing is half-built.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import numbers
import typing
from typing import Annotated, Literal, Optional, Tuple

import tyro

Variant = Literal["v2", "v1"]
Init = Literal["flax", "torch", "xavier"]
LogStdMode = Literal["clip", "tanh"]
LogProbCorrection = Literal["exact", "epsilon"]
AlphaLoss = Literal["alpha", "log_alpha"]
AlphaLogProb = Literal["resample", "reuse"]
HiddenDtype = Literal["float32", "bfloat16"]
EnvImpl = Literal["jax", "warp"]
(VARIANTS, INITS, LOG_STD_MODES, LOG_PROB_CORRECTIONS, ALPHA_LOSSES, ALPHA_LOG_PROBS,
 HIDDEN_DTYPES, ENV_IMPLS) = (typing.get_args(t) for t in (
    Variant, Init, LogStdMode, LogProbCorrection, AlphaLoss, AlphaLogProb, HiddenDtype, EnvImpl))
UPDATE_ORDERS = {  # any order of the variant's updates
    "v2": set(itertools.permutations(("critic", "actor"))),
    "v1": set(itertools.permutations(("value", "actor", "critic"))),
}


@dataclasses.dataclass(frozen=True)
class SACConfig:
    """Hyperparameters of SAC v2 (learned or fixed temperature) and SAC v1 (value network).

    Environment steps count single transitions: one iteration of the training loop steps all
    `num_envs` environments once and adds `num_envs` transitions to the replay buffer.
    """

    # --- task and loop ---
    env: str = "InvertedPendulum-v5"
    """Environment name, one of `envs.registered()`."""
    env_impl: Optional[EnvImpl] = None
    """Physics backend of a MuJoCo Playground task: "jax" (MJX) or "warp" (MuJoCo Warp); None:
    MJX, which steps the pendulum family 30-50x faster than Warp on a CPU (envs/playground.py).
    Only for `playground/<Task>` environments."""
    variant: Variant = "v2"
    """"v2": critic targets and temperature (Haarnoja et al. 2018b). "v1": value network V and
    its Polyak target V-bar, no critic targets (Haarnoja et al. 2018a)."""
    num_envs: int = 1
    """Environments stepped in parallel per iteration."""
    total_steps: int = 30_000
    """Environment steps, prefill included. Training stops at the last whole evaluation period."""
    learning_starts: int = 5_000
    """Environment steps of uniform random actions that fill the buffer before any update."""
    buffer_size: int = 1_000_000
    """Replay capacity in transitions."""
    batch_size: int = 256
    """Transitions per minibatch of each gradient update."""
    updates_per_step: int = 1
    """Gradient updates (calls of `sac_update`) per iteration of `num_envs` environment steps."""
    eval_every: int = 5_000
    """Environment steps between deterministic evaluations (a multiple of `num_envs`)."""
    eval_episodes: int = 10
    """Evaluation episodes, run in parallel on their own environment instances."""
    confirm_episodes: int = 20
    """Episodes, from fresh initial states, of the confirmation evaluation of an actor that
    scores above the kept one: it replaces the kept (delivered) actor only if its confirmed
    return is higher too (`sac_jax.selection`)."""
    eval_alongside: bool = False
    """Step each evaluation point's episodes (evaluation and confirmation) alongside training,
    one step per training iteration, batched with those of the points still under way, instead
    of running them to their end at the point. Their returns enter the selection at the first
    point after they have all ended, ceil(max episode steps / iterations per evaluation)
    points later, or at the run's last point, where every evaluation under way is run to its
    end (a run that every seed's `stop_when_solved` ends sooner leaves them unscored); the
    outputs' evaluation fields at a point are those of the evaluation that ended there (the
    last point's: its own actor's). For a GPU, where a step of the environment costs about
    as much for a few episodes as for a thousand and an evaluation's steps run one after
    another (`sac_jax.train`)."""
    stop_when_solved: bool = False
    """End a seed's learning once its delivered actor's kept score reaches `stop_return` and
    averages at least `stop_measurements` measurements; the run ends when every seed has
    stopped."""
    stop_return: Optional[float] = None
    """Kept score at which `stop_when_solved` stops a seed; None: the task's solved return
    (`envs.spec(env).solved_return`)."""
    stop_measurements: int = 2
    """Measurements (its confirmation, then its re-measurements on later points' confirmation
    episodes: `sac_jax.selection`) that the kept score must average before `stop_when_solved`
    stops a seed. With 1 a seed can stop on one lucky confirmation."""

    # --- objective ---
    gamma: float = 0.99
    """Discount factor of the soft Q target."""
    tau: float = 0.005
    """Polyak coefficient: target <- tau * online + (1 - tau) * target."""
    target_update_period: int = 1
    """Polyak update every this many `sac_update` calls."""
    policy_frequency: int = 1
    """CleanRL's policy delay K: every K-th update runs K actor (and temperature) steps."""
    reward_scale: float = 1.0
    """Multiplies rewards in the Q target (SAC v1's reward scale)."""
    loss_coef: float = 1.0
    """Factor of each squared-error loss (J_Q per critic, J_V): 1 for MSE, 0.5 for the paper's."""
    update_order: Tuple[str, ...] = ("critic", "actor")
    """Order of the updates inside `sac_update`; the temperature step follows each actor step and
    the Polyak step comes last. v2: a permutation of ("critic", "actor"); v1: of
    ("value", "actor", "critic")."""

    # --- temperature ---
    learn_alpha: bool = True
    """Learn the temperature alpha by J_alpha; if false, alpha stays at alpha_init."""
    alpha_init: float = 1.0
    """alpha used by the losses until the first temperature step."""
    log_alpha_init: Optional[float] = None
    """Initial log alpha for the temperature optimiser; None means log(alpha_init)."""
    target_entropy: Optional[float] = None
    """Target entropy H-bar of J_alpha; None means -|A|."""
    alpha_loss: AlphaLoss = "alpha"
    """J_alpha form: "alpha" = mean(-exp(log a)(log pi + H)); "log_alpha" =
    mean(-log a (log pi + H))."""
    alpha_log_prob: AlphaLogProb = "resample"
    """log pi fed to J_alpha: "resample" draws a fresh action from the updated actor (CleanRL);
    "reuse" takes the actor step's log pi (before its update)."""

    # --- optimisers (Adam with PyTorch's defaults) ---
    actor_lr: float = 3e-4
    """Adam learning rate of the actor (J_pi)."""
    critic_lr: float = 1e-3
    """Adam learning rate of the critics (J_Q)."""
    alpha_lr: float = 1e-3
    """Adam learning rate of log alpha (J_alpha)."""
    value_lr: float = 3e-4
    """Adam learning rate of the value network (J_V, SAC v1)."""

    # --- networks ---
    actor_hidden: Tuple[int, ...] = (256, 256)
    """Hidden widths of the actor (its trunk, or each of its two MLPs)."""
    critic_hidden: Tuple[int, ...] = (256, 256)
    """Hidden widths of each critic and of the value network."""
    num_critics: int = 2
    """Critics N in the ensemble; targets and J_pi take the minimum over them."""
    critic_layer_norm: bool = False
    """Follow each hidden ReLU of the critics by a LayerNorm (Brax's `q_network_layer_norm`,
    which MuJoCo Playground's SAC uses)."""
    normalize_observations: bool = False
    """Feed every network (s - mean) / std, with the running statistics of all observations
    so far, kept in the actor's variables (`sac_jax.observation_norm`; Brax's
    `normalize_observations`, which MuJoCo Playground's SAC uses)."""
    init: Init = "flax"
    """"flax": lecun-normal kernels, zero bias; "torch": PyTorch's nn.Linear default
    U(+-1/sqrt(fan_in)) for kernel and bias; "xavier": Xavier-uniform kernels, zero bias."""
    last_layer_init: Optional[float] = None
    """If set, output layers (Q, V, mean, log std) are drawn U(+-last_layer_init)."""
    separate_log_std_network: bool = False
    """Actor with separate mean and log-std MLPs (seed 001) instead of two heads on one trunk."""
    log_std_mode: LogStdMode = "tanh"
    """"clip": clip to [log_std_min, log_std_max]; "tanh": min + (max - min)(tanh(x) + 1) / 2."""
    log_std_min: float = -5.0
    """Lower bound of the actor's log standard deviation."""
    log_std_max: float = 2.0
    """Upper bound of the actor's log standard deviation."""
    log_prob_correction: LogProbCorrection = "epsilon"
    """"exact": log|d a/d u| = log scale + 2(log 2 - u - softplus(-2u)); "epsilon":
    log(scale (1 - tanh(u)^2) + 1e-6) as the PyTorch seeds."""
    hidden_dtype: HiddenDtype = "float32"
    """"float32": the networks compute in their parameters' dtype (float32, or float64 with
    jax_enable_x64). "bfloat16": the hidden layers' products and activations are bfloat16;
    parameters, output layers, losses and optimisers stay float32. For many seeds on a GPU,
    whose networks are bound by memory traffic (BENCHMARKS.md); not for equivalence checks."""

    # --- execution ---
    data_parallel_axis: Annotated[Optional[str], tyro.conf.Suppress] = None
    """Mapped device axis over which every update averages its gradients and losses
    (`jax.lax.pmean`), so parameters stay equal on all devices. Set by `sac_jax.parallel` on each
    device's share of a data-parallel run; None for a run on one device."""

    def __post_init__(self):
        # Lists from a JSON file or a CLI become tuples, so the config stays hashable.
        for name in ("update_order", "actor_hidden", "critic_hidden"):
            value = getattr(self, name)
            if not isinstance(value, (list, tuple)):
                raise ValueError(f"SACConfig.{name}={value!r}: must be a tuple, e.g. "
                                 f"{SACConfig.__dataclass_fields__[name].default!r}")
            object.__setattr__(self, name, tuple(value))
        self._validate()

    # ------------------------------------------------------------------ validation
    def _validate(self):
        def fail(field, rule):
            raise ValueError(f"SACConfig.{field}={getattr(self, field)!r}: {rule}")

        def choice(field, options):
            if getattr(self, field) not in options:
                fail(field, f"must be one of {list(options)}")

        import envs  # local import: building a config must not pull MJX at module import

        if not isinstance(self.env, str):
            fail("env", "must be an environment's name, e.g. 'InvertedPendulum-v5'")
        try:
            envs.spec(self.env)  # close names where it is unknown
        except ValueError as error:
            fail("env", str(error))
        if self.env_impl is not None:
            choice("env_impl", ENV_IMPLS)
            if not self.env.startswith(envs.playground.PREFIX):
                fail("env_impl", f"only MuJoCo Playground tasks (playground/<Task>) have a "
                     f"backend choice, not {self.env}")
        choice("variant", VARIANTS)
        choice("init", INITS)
        choice("log_std_mode", LOG_STD_MODES)
        choice("log_prob_correction", LOG_PROB_CORRECTIONS)
        choice("alpha_loss", ALPHA_LOSSES)
        choice("alpha_log_prob", ALPHA_LOG_PROBS)
        choice("hidden_dtype", HIDDEN_DTYPES)
        for field in ("num_envs", "total_steps", "buffer_size", "batch_size", "updates_per_step",
                      "eval_every", "eval_episodes", "confirm_episodes", "target_update_period",
                      "policy_frequency", "num_critics", "stop_measurements"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                fail(field, "must be a positive integer")
        for field in ("eval_alongside", "stop_when_solved", "learn_alpha", "critic_layer_norm",
                      "normalize_observations", "separate_log_std_network"):
            if not isinstance(getattr(self, field), bool):
                fail(field, "must be True or False")
        if isinstance(self.learning_starts, bool) or not isinstance(self.learning_starts, int):
            fail("learning_starts", "must be an integer")
        for field in ("actor_hidden", "critic_hidden"):
            sizes = getattr(self, field)
            if not sizes or any(isinstance(h, bool) or not isinstance(h, int) or h <= 0
                                for h in sizes):
                fail(field, "must be a non-empty tuple of positive integers")
        def real(value) -> bool:
            return isinstance(value, numbers.Real) and not isinstance(value, bool)

        for field in ("gamma", "tau", "reward_scale", "loss_coef", "actor_lr", "critic_lr",
                      "alpha_lr", "value_lr", "alpha_init", "log_std_min", "log_std_max"):
            if not real(getattr(self, field)) or not math.isfinite(getattr(self, field)):
                fail(field, "must be a finite number")
        for field in ("actor_lr", "critic_lr", "alpha_lr", "value_lr", "alpha_init",
                      "reward_scale", "loss_coef"):
            if getattr(self, field) <= 0:
                fail(field, "must be > 0")
        if not 0.0 <= self.gamma <= 1.0:
            fail("gamma", "must lie in [0, 1]")
        if not 0.0 < self.tau <= 1.0:
            fail("tau", "must lie in (0, 1]")
        if self.log_std_min >= self.log_std_max:
            fail("log_std_min", f"must be below log_std_max={self.log_std_max}")
        for field in ("log_alpha_init", "target_entropy", "last_layer_init", "stop_return"):
            value = getattr(self, field)
            if value is not None and (not real(value) or not math.isfinite(value)):
                fail(field, "must be a finite number or None")
        if self.data_parallel_axis is not None and (
                not isinstance(self.data_parallel_axis, str) or not self.data_parallel_axis):
            fail("data_parallel_axis", "must be a non-empty axis name or None")
        if self.eval_alongside and self.data_parallel_axis is not None:
            fail("eval_alongside", "is not supported in a data-parallel run; set False")
        if self.last_layer_init is not None and self.last_layer_init <= 0:
            fail("last_layer_init", "must be > 0 or None")
        if self.batch_size > self.buffer_size:
            fail("batch_size", f"must not exceed buffer_size={self.buffer_size}")
        if self.learning_starts < self.batch_size:
            fail("learning_starts", f"must be at least batch_size={self.batch_size}, so the "
                 "first update samples a full batch of real transitions")
        if self.learning_starts % self.num_envs:
            fail("learning_starts", f"must be a multiple of num_envs={self.num_envs}")
        if self.eval_every % self.num_envs:
            fail("eval_every", f"must be a multiple of num_envs={self.num_envs}")
        if self.total_steps >= 2 ** 31:
            fail("total_steps", "must be below 2**31 (environment steps are counted in int32)")
        if self.total_steps < self.learning_starts + self.eval_every:
            fail("total_steps", f"must be at least learning_starts + eval_every = "
                 f"{self.learning_starts + self.eval_every}")
        if self.buffer_size % self.num_envs:
            fail("buffer_size", f"must be a multiple of num_envs={self.num_envs} (each "
                 "iteration writes num_envs transitions in one piece)")
        if self.update_order not in UPDATE_ORDERS[self.variant]:
            fail("update_order", f"for variant {self.variant!r} must be one of "
                 f"{sorted(UPDATE_ORDERS[self.variant])}")
        if self.stop_when_solved and self.stop_at is None:
            fail("stop_when_solved", f"{self.env} has no solved return to stop at; set stop_return")
        if self.variant == "v1" and self.learn_alpha:
            fail("learn_alpha", "SAC v1 uses a fixed temperature (and reward_scale); set False")

    def make_env(self):
        """The `envs.Env` this config trains on (`env`, with `env_impl` where set)."""
        import envs

        return envs.make(self.env, **({} if self.env_impl is None else {"impl": self.env_impl}))

    # ------------------------------------------------------------------ derived sizes
    @property
    def iterations_per_eval(self) -> int:
        """Training iterations between two evaluations."""
        return self.eval_every // self.num_envs

    @property
    def num_evals(self) -> int:
        """Evaluations in a run; each follows `eval_every` environment steps of training."""
        return (self.total_steps - self.learning_starts) // self.eval_every

    @property
    def stop_at(self) -> Optional[float]:
        """The confirmed return at which `stop_when_solved` stops a seed (see `stop_return`)."""
        import envs

        return (self.stop_return if self.stop_return is not None
                else envs.spec(self.env).solved_return)

    @property
    def run_steps(self) -> int:
        """Environment steps a whole run takes: the prefill and `num_evals` whole evaluation
        periods (at most `total_steps`)."""
        return self.learning_starts + self.num_evals * self.eval_every

    @property
    def prefill_iterations(self) -> int:
        return self.learning_starts // self.num_envs

    @property
    def run_iterations(self) -> int:
        """Iterations a whole run takes: the prefill's and `num_evals` periods'."""
        return self.prefill_iterations + self.num_evals * self.iterations_per_eval

    def replace(self, **changes) -> "SACConfig":
        """A copy with `changes` applied, validated anew."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise ValueError(f"SACConfig has no field(s) {sorted(unknown)}")
        return dataclasses.replace(self, **changes)

