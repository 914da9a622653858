"""Cost of following a run from the host: progress lines, TensorBoard, checkpoints, finiteness
checks.

In one process, the same configuration and seeds run (a) as the pure `make_train` program, one
`lax.scan` with nothing reported until it ends, and (b) through `sac_jax.run.run_training`
driven chunk by chunk, printing nothing but writing TensorBoard scalars at every evaluation
point and a checkpoint (the whole state, replay buffers included) after it, as
`scripts/train.py` does. Compile time is excluded from both; the figure is the median of
`--repeats` runs of each, interleaved.

    python benchmarks/progress_overhead.py                  # the default preset, 1 seed
    python benchmarks/progress_overhead.py --preset pendulum --seeds 4 --repeats 5
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import jax  # noqa: E402

import sac_jax  # noqa: E402
from sac_jax import run_dir  # noqa: E402
from sac_jax.run import run_training  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default=sac_jax.DEFAULT_PRESET, choices=sorted(sac_jax.PRESETS))
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    sac_jax.enable_compilation_cache()
    config = sac_jax.PRESETS[args.preset]
    keys = jax.random.split(jax.random.key(0), args.seeds)
    whole = jax.jit(jax.vmap(sac_jax.make_train(config))).lower(keys).compile()
    jax.block_until_ready(whole(keys))  # warm-up
    plain, followed = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            start = time.perf_counter()
            jax.block_until_ready(whole(keys))
            plain.append(time.perf_counter() - start)
            out = os.path.join(tmp, f"run{r}")
            run_dir.create(out, config, args.preset, args.seeds, 0)
            tensorboard = run_dir.TensorBoard(out)
            result = run_training(
                config, seeds=args.seeds,
                on_point=lambda step, means, returns, _: tensorboard.add_point(step, means, returns),
                on_checkpoint=lambda state, position: run_dir.save_checkpoint(out, state, position))
            tensorboard.close()
            followed.append(result.summary["run_s"])
    p, f = statistics.median(plain), statistics.median(followed)
    print(json.dumps({"preset": args.preset, "seeds": args.seeds, "repeats": args.repeats,
                      "single_scan_s": round(p, 3), "host_driven_s": round(f, 3),
                      "overhead_pct": round(100 * (f / p - 1), 2),
                      "single_scan_all_s": [round(x, 3) for x in plain],
                      "host_driven_all_s": [round(x, 3) for x in followed],
                      "device": str(jax.devices()[0])}))


if __name__ == "__main__":
    main()
