"""Run directories for the tests of load_policy, checkpoints and the evaluate and render scripts,
ways to damage their checkpoints, and the one-line-error check."""

from __future__ import annotations

import os

import jax

from sac_jax import PRESETS, run_checkpoint, run_dir
from sac_jax.train import SEED_AXES, make_train_parts
from scripts import train as train_script

TINY_PENDULUM = ["--preset", "pendulum", "--total-steps", "3000", "--eval-every", "1000",
                 "--learning-starts", "1000", "--buffer-size", "3000", "--eval-episodes", "2"]


def trained_pendulum(out: str) -> str:
    """A 3000-step Pendulum-v1 run of scripts/train.py (a policy that has learned a little)."""
    assert train_script.main(TINY_PENDULUM + ["--out", out]) == 0
    return out


def untrained(out: str, env: str, seeds: int = 1, **overrides) -> str:
    """A run directory whose checkpoint is the freshly initialised state of `seeds` seeds on
    `env` (preset `fast` with `overrides`): only the initialisation is compiled."""
    config = PRESETS["fast"].replace(env=env, **overrides)
    run_dir.create(out, config, preset="fast", seeds=seeds, seed=0)
    init = jax.jit(jax.vmap(make_train_parts(config).init, out_axes=SEED_AXES))
    runner = init(jax.random.split(jax.random.key(0), seeds))
    run_checkpoint.save_checkpoint(out, runner, {"env_steps": 0, "chunks_done": 0,
                                                 "compile_s": 0.0, "run_s": 0.0, "walls": {}})
    return out


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
