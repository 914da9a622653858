"""Run directories for the tests of load_policy, checkpoints and the evaluate and render scripts,
ways to damage their checkpoints, and the one-line-error check."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil

import jax
import numpy as np

from sac_jax import PRESETS, run_checkpoint, run_dir
from sac_jax.position import Position
from sac_jax.train import SEED_AXES, make_train_parts
from scripts import train as train_script

TINY_PENDULUM = ["--preset", "pendulum", "--total-steps", "3000", "--eval-every", "1000",
                 "--learning-starts", "1000", "--buffer-size", "3000", "--eval-episodes", "2"]
SMALL_RUN = ["--preset", "pendulum", "--total-steps", "4000", "--eval-every", "1000",
             "--learning-starts", "1000", "--buffer-size", "4000", "--eval-episodes", "2",
             "--actor-hidden", "32", "32", "--critic-hidden", "32", "32", "--seed", "3"]
"""scripts/train.py flags of a 4000-step Pendulum-v1 run with 32-wide networks, evaluated
every 1000 steps: a run directory with points and checkpoints, quick to compile."""


def copied_run(run_dir: str, tmp_path, name: str = "copy") -> str:
    """A copy of the run directory `run_dir` at tmp_path/name, to damage or change."""
    copy = str(tmp_path / name)
    shutil.copytree(run_dir, copy)
    return copy


def checkpoint_header(step_dir: str) -> dict:
    """The JSON metadata orbax keeps beside a checkpoint step's arrays."""
    with open(os.path.join(step_dir, "meta", "metadata")) as f:
        return json.load(f)


def trained_pendulum(out: str) -> str:
    """A 3000-step Pendulum-v1 run of scripts/train.py (a policy that has learned a little)."""
    assert train_script.main(TINY_PENDULUM + ["--out", out]) == 0
    return out


def with_planted_delivered_actor(path: str) -> str:
    """The run directory `path`, its checkpoint's delivered actor replaced by half the last
    actor's parameters, so that the two policies differ (in a short run they may be one)."""
    _, _, runner, position = run_checkpoint.load_checkpoint(path)
    half = jax.tree_util.tree_map(lambda x: x / 2, runner.sac.actor_params)
    planted = runner.replace(delivered=runner.delivered.replace(actor_params=half))
    run_checkpoint.save_checkpoint(path, planted, position)
    return path


def untrained(out: str, env: str, seeds: int = 1, **overrides) -> str:
    """A run directory whose checkpoint is the freshly initialised state of `seeds` seeds on
    `env` (preset `fast` with `overrides`): only the initialisation is compiled."""
    config = PRESETS["fast"].replace(env=env, **overrides)
    run_dir.create(out, config, preset="fast", seeds=seeds, seed=0)
    init = jax.jit(jax.vmap(make_train_parts(config).init, out_axes=SEED_AXES))
    runner = init(jax.random.split(jax.random.key(0), seeds))
    run_checkpoint.save_checkpoint(out, runner, Position())
    return out


def two_checkpoints(out: str):
    """(out, state): a Pendulum-v1 run directory of 2 seeds whose state has 40 of 4000 replay
    slots filled (with normal draws), saved as step 0 (the untrained state) and step 800."""
    untrained(out, "Pendulum-v1", seeds=2, buffer_size=4000, total_steps=6000,
              learning_starts=2000, eval_every=2000, num_envs=8)
    _, _, runner, position = run_checkpoint.load_checkpoint(out)
    rng = np.random.default_rng(0)
    data = jax.tree_util.tree_map(lambda x: np.concatenate(
        [rng.normal(size=(x.shape[0], 40) + x.shape[2:]).astype(x.dtype), x[:, 40:]], axis=1),
        runner.buffer.data)
    runner = runner.replace(buffer=runner.buffer.replace(data=data, size=np.int32(40)))
    run_checkpoint.save_checkpoint(out, runner,
                                   dataclasses.replace(position, chunks_done=3, env_steps=800))
    return out, runner


def fails_in_one_line(capsys, main, argv, code, message):
    """`main(argv)` exits with `code` and exactly one line on stderr holding `message`."""
    result = main(argv)
    err = capsys.readouterr().err
    assert result == code, err
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err, err


def newest_checkpoint(run: str) -> str:
    """The directory of the newest checkpoint step of the run directory `run`."""
    return os.path.join(run_checkpoint.directory(run), str(run_checkpoint.saved_steps(run)[-1]))


def _largest_data_file(run: str) -> str:
    state = os.path.join(newest_checkpoint(run), "state")
    files = [os.path.join(root, name) for root, _, names in os.walk(state) for name in names]
    return max(files, key=os.path.getsize)


def damage_checkpoint(run: str, how: str = "flip") -> None:
    """Damages the newest checkpoint of `run` in place: "flip" inverts 4 bytes in the middle of
    its largest data file (the replay observations), "truncate" cuts that file in half,
    "garbage" replaces its metadata with random bytes."""
    if how == "garbage":
        with open(os.path.join(newest_checkpoint(run), "meta", "metadata"), "wb") as f:
            f.write(os.urandom(1000))
        return
    path = _largest_data_file(run)
    data = bytearray(open(path, "rb").read())
    if how == "truncate":
        data = data[:len(data) // 2]
    else:
        middle = len(data) // 2
        data[middle:middle + 4] = bytes(b ^ 0xFF for b in data[middle:middle + 4])
    with open(path, "wb") as f:
        f.write(bytes(data))
