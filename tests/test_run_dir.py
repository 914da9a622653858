"""sac_jax.run_dir and the writers beside it: write_file leaves a file whole or absent, and no
temporary file; the TensorBoard writer imports no torch."""

import os

import pytest

from sac_jax import run_dir
from tests.subprocess_json import run_json


def test_tensorboard_writer_leaves_torch_unimported(tmp_path):
    """tensorboardX's writer imports torch when it can (2.2 s on the CPU); scalars need no torch,
    and an `import torch` afterwards still works where torch is installed."""
    pytest.importorskip("torch")
    script = ("import json, sys; from sac_jax import metric_writers; "
              f"metric_writers.TensorBoard({str(tmp_path)!r}).close(); "
              "before = 'torch' in sys.modules; import torch; "
              "print(json.dumps({'before': before, 'after': 'torch' in sys.modules}))")
    assert run_json(["-c", script]) == {"before": False, "after": True}


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
