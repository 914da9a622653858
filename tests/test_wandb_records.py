"""sac_jax.wandb_records' framing: a log cut short within its file header (a process killed
as W&B created it) holds no records; a file that is not a W&B log is refused. (Logs of real
runs: tests/test_train_script.py.)"""

import pytest

from sac_jax import wandb_records


@pytest.mark.parametrize("content", [b"", b":W", b":W&B\x00"])
def test_a_log_cut_short_within_its_header_holds_no_records(tmp_path, content):
    path = tmp_path / "run-abc.wandb"
    path.write_bytes(content)
    assert list(wandb_records.records(str(path))) == []


@pytest.mark.parametrize("content", [b"PK", b"not a W&B log at all"])
def test_a_file_that_is_not_a_log_is_refused(tmp_path, content):
    path = tmp_path / "run-abc.wandb"
    path.write_bytes(content)
    with pytest.raises(wandb_records.UnreadableLog, match="not a W&B transaction log"):
        list(wandb_records.records(str(path)))
