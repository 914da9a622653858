"""sac_jax.background.LoopImportGate: while installed, an import of a module not loaded yet on
another thread waits until the host loop waits for the device, or at most MAX_IMPORT_HOLD_S
after the loop's work began; the loop's own imports never wait, even while another thread's is
held; and the gate puts Python's import back as it was, releasing what it held, however its
block ends."""

import builtins
import sys
import threading
import uuid

import pytest

from sac_jax import background


@pytest.fixture
def new_module(tmp_path, monkeypatch):
    """A function returning the name of a module not imported yet, on sys.path."""
    monkeypatch.syspath_prepend(str(tmp_path))

    def make() -> str:
        name = f"gated_{uuid.uuid4().hex}"
        (tmp_path / f"{name}.py").write_text("VALUE = 1\n")
        return name
    return make


def import_on_thread(name: str) -> threading.Thread:
    thread = threading.Thread(target=__import__, args=(name,), daemon=True)
    thread.start()
    return thread


def test_another_threads_import_waits_until_the_loop_waits(new_module, monkeypatch):
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 60.0)
    held, own = new_module(), new_module()
    with background.LoopImportGate() as gate:
        thread = import_on_thread(held)
        thread.join(0.3)
        assert thread.is_alive() and held not in sys.modules
        __import__(own)  # the loop's own import goes through at once
        loaded = import_on_thread("json")  # as does another thread's of a module loaded
        loaded.join(10)
        assert not loaded.is_alive()
        with gate.waiting():
            thread.join(10)
            assert not thread.is_alive() and held in sys.modules
        later = new_module()
        thread = import_on_thread(later)  # held again once the loop works
        thread.join(0.3)
        assert thread.is_alive()
    thread.join(10)  # released as the gate goes
    assert later in sys.modules


def test_imports_are_held_at_most_max_import_hold_s_per_spell_of_work(new_module, monkeypatch):
    """A loop that works longer than MAX_IMPORT_HOLD_S (a follower waiting for a write) lets
    the imports go on: of three new modules loaded in a row, the first waits out what is left
    of the spell's hold, and the others do not wait."""
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 1.0)
    names = [new_module() for _ in range(3)]
    with background.LoopImportGate() as gate:
        waits, wait = [], gate._waiting.wait
        gate._waiting.wait = lambda timeout: waits.append(timeout) or wait(timeout)
        thread = threading.Thread(target=lambda: [__import__(n) for n in names], daemon=True)
        thread.start()
        thread.join(10)
    assert all(n in sys.modules for n in names)
    assert len(waits) == 1 and 0 < waits[0] <= 1.0, waits


def test_the_gate_goes_with_its_block_even_on_an_error(new_module, monkeypatch):
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 60.0)
    before, name = builtins.__import__, new_module()
    with pytest.raises(RuntimeError, match="the loop failed"):
        with background.LoopImportGate():
            thread = import_on_thread(name)
            thread.join(0.3)
            assert thread.is_alive()
            raise RuntimeError("the loop failed")
    thread.join(10)
    assert name in sys.modules and builtins.__import__ is before
