"""Threefry, JAX's PRNG, lowered without its loop in the training program on a CPU.

JAX lowers a Threefry-2x32 draw (every `jax.random.split`, `normal`, `uniform`, `randint`) for a
CPU as a `fori_loop` of 5 trips of 4 rounds each, and for a GPU as the 20 rounds written out.
Both compute the same bits. On a CPU each trip of such a loop is a step of XLA's runtime, and a
training iteration of SAC makes a dozen small draws (the iteration's keys, the actions' noise,
the minibatch's slots, each update's noise), so the loops cost more than the hashing: a split
and a normal draw of 256 numbers took 5.1 us in a `lax.scan` against 1.3 us written out (2
cores of a Zen 4 AMD EPYC, 2026-12-06, ad hoc). Within `unrolled()` the lowering is the
written-out one, as on a GPU:

    rejax's Pendulum-v1 configuration (`benchmarks/rejax_peer.py`), `jax.jit(make_train)`, the
    same returns: 5.60-5.66 s against 6.29-6.61 s (2 alternated processes each, 3 calls
    each; that EPYC).

`sac_jax.run` lowers the training program (`advance`) so, and the evaluation program as JAX
does: for `fast` the evaluation's chunks took 0.53-0.56 s written out against 0.44-0.53 s (3
alternated processes each, medians of 7 calls, a trained actor), though the evaluation draws
only its episodes' starts, while its training chunks took as long either way (0.49-0.58 s
against 0.51-0.55 s).
Outside `unrolled()`, and on other platforms, a draw is lowered as JAX lowers it.
"""

from __future__ import annotations

import contextlib
import threading

from jax._src.interpreters import mlir  # no public way to choose a primitive's lowering
from jax._src.random import threefry2x32 as _threefry

_choice = threading.local()


def _lowering(ctx, *args):
    """JAX's GPU lowering (the rounds written out) within `unrolled()`, else its CPU one."""
    rule = (_threefry._threefry2x32_lowering_rule if getattr(_choice, "unrolled", False)
            else _threefry._threefry2x32_cpu_lowering_rule)
    return rule(ctx, *args)


mlir.register_lowering(_threefry.threefry2x32_p, _lowering, platform="cpu")


@contextlib.contextmanager
def unrolled():
    """Programs lowered in this block, on this thread, draw through Threefry's rounds written
    out rather than looped (on a CPU; the same bits). Lowering is `jax.jit(f).lower`, or the
    first call of a jitted function for its shapes; JAX keeps a function's lowering for its
    shapes, so one lowered before the block keeps its loop within it (and one lowered within,
    its rounds written out after it)."""
    before = getattr(_choice, "unrolled", False)
    _choice.unrolled = True
    try:
        yield
    finally:
        _choice.unrolled = before
