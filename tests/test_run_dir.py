"""sac_jax.run_dir and the writers beside it: write_file leaves a file whole or absent, and no
temporary file; a stored config from before `stop_measurements` stops on one measurement; the
TensorBoard writer imports no torch."""

import dataclasses
import os

import pytest

import sac_jax
from sac_jax import run_dir
from tests.subprocess_json import run_json


def test_a_stored_config_from_before_stop_measurements_stops_on_one():
    fields = dataclasses.asdict(sac_jax.PRESETS["fast"])
    assert run_dir.stored_config(fields) == sac_jax.PRESETS["fast"]  # 2, as stored
    del fields["stop_measurements"]  # a run or sweep directory written before the field
    assert run_dir.stored_config(fields).stop_measurements == 1


def test_tensorboard_writer_leaves_torch_unimported(tmp_path):
    """The TensorBoard writer (with a point written) imports no torch, which tensorboardX's
    writer did where torch is installed (2.2 s on the CPU), nor TensorFlow; an `import torch`
    afterwards still works."""
    pytest.importorskip("torch")
    script = ("import json, sys; from sac_jax import metric_writers; "
              f"board = metric_writers.TensorBoard({str(tmp_path)!r}); "
              "board.add_point(1000, {'eval_return': 1.0}, [1.0]); board.close(); "
              "before = sorted({'torch', 'tensorflow'} & set(sys.modules)); import torch; "
              "print(json.dumps({'before': before, 'after': 'torch' in sys.modules}))")
    assert run_json(["-c", script]) == {"before": [], "after": True}
    from tests.killed_run import tensorboard_steps
    # it did write the point (step 0: the event that starts every event file)
    assert tensorboard_steps(str(tmp_path / "tensorboard")) == {0, 1000}


@pytest.mark.parametrize("replace, final_step", [(True, "replace"), (False, "link")])
def test_write_file_is_whole_or_absent(tmp_path, monkeypatch, replace, final_step):
    """`write_file` puts the bytes at `path` whole; a write that fails at the last step (the
    temporary file complete) leaves no temporary file; without `replace` an existing file is
    kept."""
    path = str(tmp_path / "file.bin")
    run_dir.write_file(path, b"first", replace=replace)
    assert open(path, "rb").read() == b"first" and os.listdir(tmp_path) == ["file.bin"]
    if not replace:
        with pytest.raises(FileExistsError):
            run_dir.write_file(path, b"second", replace=False)
        assert open(path, "rb").read() == b"first" and os.listdir(tmp_path) == ["file.bin"]
    os.remove(path)

    def full_disk(*args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, final_step, full_disk)
    with pytest.raises(OSError, match="No space left"):
        run_dir.write_file(path, b"third", replace=replace)
    assert os.listdir(tmp_path) == []


def test_the_state_template_is_traced_once_per_configuration(monkeypatch):
    """`state_template` (before a run compiles and after) traces the state's constructor once
    per (config, seeds, settings): the same shapes come back without a second trace, and
    another seed count or setting traces anew."""
    from sac_jax import PRESETS

    traced = []
    real = run_dir.make_train_parts
    monkeypatch.setattr(run_dir, "make_train_parts", lambda c: traced.append(1) or real(c))
    # this process's memo alone: shapes kept on disk by an earlier run would not be traced
    monkeypatch.setattr(run_dir.compilation_cache, "program_directory", lambda: None)
    run_dir._state_template.cache_clear()
    config = PRESETS["fast"].replace(buffer_size=4096, num_envs=2)
    first = run_dir.state_template(config, 2)
    assert run_dir.state_template(config, 2) is first and len(traced) == 1
    assert run_dir.state_template(config, 3).buffer.data.obs.shape[0] == 3
    swept = run_dir.state_template(config, 2, {"actor_lr": [1e-3, 3e-3]})
    assert swept.buffer.data.obs.shape[0] == 4 and len(traced) == 3
