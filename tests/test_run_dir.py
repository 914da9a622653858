"""sac_jax.run_dir and the writers beside it: the TensorBoard writer imports no torch."""

import pytest

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
