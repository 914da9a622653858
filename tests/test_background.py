"""sac_jax.background.LoopImportGate: while installed, an import of a module not loaded yet on
another thread waits until the host loop waits for the device, or at most MAX_IMPORT_HOLD_S
after the loop's work began; the loop's own imports never wait, even while another thread's is
held; and the gate puts Python's import back as it was, releasing what it held, however its
block ends.

The imports are of names no module has (`absent`): the gate waits before Python looks for the
module, so a thread's import attempt ends (in ModuleNotFoundError) only once the gate lets it
go, and no module need be put on the import path."""

import builtins
import threading
import uuid

import pytest

from sac_jax import background


def absent() -> str:
    return f"gated_{uuid.uuid4().hex}"


def try_imports(*names: str) -> None:
    for name in names:
        with pytest.raises(ModuleNotFoundError):
            __import__(name)


def import_on_thread(*names: str) -> threading.Thread:
    thread = threading.Thread(target=try_imports, args=names, daemon=True)
    thread.start()
    return thread


def test_another_threads_import_waits_until_the_loop_waits(monkeypatch):
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 60.0)
    with background.LoopImportGate() as gate:
        thread = import_on_thread(absent())
        thread.join(0.3)
        assert thread.is_alive()
        try_imports(absent())  # the loop's own import goes through at once
        loaded = threading.Thread(target=__import__, args=("json",), daemon=True)
        loaded.start()  # as does another thread's of a module loaded
        loaded.join(10)
        assert not loaded.is_alive()
        with gate.waiting():
            thread.join(10)
            assert not thread.is_alive()
        thread = import_on_thread(absent())  # held again once the loop works
        thread.join(0.3)
        assert thread.is_alive()
    thread.join(10)  # released as the gate goes
    assert not thread.is_alive()


def test_imports_are_held_at_most_max_import_hold_s_per_spell_of_work(monkeypatch):
    """A loop that works longer than MAX_IMPORT_HOLD_S (a follower waiting for a write) lets
    the imports go on: of three new modules imported in a row, the first waits out what is
    left of the spell's hold, and the others do not wait."""
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 1.0)
    with background.LoopImportGate() as gate:
        waits, wait = [], gate._waiting.wait
        gate._waiting.wait = lambda timeout: waits.append(timeout) or wait(timeout)
        thread = import_on_thread(absent(), absent(), absent())
        thread.join(10)
        assert not thread.is_alive()
    assert len(waits) == 1 and 0 < waits[0] <= 1.0, waits


def test_the_gate_goes_with_its_block_even_on_an_error(monkeypatch):
    monkeypatch.setattr(background, "MAX_IMPORT_HOLD_S", 60.0)
    before = builtins.__import__
    with pytest.raises(RuntimeError, match="the loop failed"):
        with background.LoopImportGate():
            thread = import_on_thread(absent())
            thread.join(0.3)
            assert thread.is_alive()
            raise RuntimeError("the loop failed")
    thread.join(10)
    assert not thread.is_alive() and builtins.__import__ is before
