#!/usr/bin/env bash
# GPU figures for BENCHMARKS.md, run on a lent H100/H200 through the device tool, where jax (CUDA)
# and torch are installed but mujoco, mujoco-mjx, flax, optax and distrax travel as wheels in
# .whl/ (see BENCHMARKS.md), brax and its imported needs too (brax, jaxopt, ml_collections,
# orbax-checkpoint, tensorstore; pillow and scipy come with the image's torchvision and jax),
# and gymnasium for the PyTorch seed-002 loop (gymnasium, farama-notifications, imageio).
# `bash benchmarks/gpu_wheels.sh` (brax modes: `... brax`) downloads them at CI's versions.
# mujoco's viewer wheels (mujoco-studio, pyopengl, glfw) stay out: MJX does not import them,
# and without their 16 MB our wheels and brax's fit the device tool's 64 MiB carry together (49 MB).
# Every results file a mode writes (benchmarks/provenance.py's write_result, NAME-KIND.json, e.g.
# seed_scaling-h100.json) goes to a fresh folder, is printed, and is copied into $OUT, where the
# device tool sets it, to come back: put it in benchmarks/results/ and run
# python -m benchmarks.tables.
# Usage: bash benchmarks/gpu.sh env [env_throughput.py flags, e.g. --sizes 8 1280
#          --lean-stages on off]
#        bash benchmarks/gpu.sh evaluation [evaluation_cost.py flags, e.g. --seeds 1 256
#          --lean-stages on off]
#        bash benchmarks/gpu.sh updates [seed_scaling.py flags, e.g. --hidden-dtype float32
#          bfloat16]
#        bash benchmarks/gpu.sh profile [profile_chunk.py flags, e.g. --hidden-dtype float32]
#        bash benchmarks/gpu.sh parallel [data_parallel.py flags] (several GPUs: one GPU against
#          data parallel over all; without flags, four sizes, one process each)
#        bash benchmarks/gpu.sh brax|brax-cpu [brax_peer.py options, e.g. --seeds 2]
#        bash benchmarks/gpu.sh torch [torch_time_to_solve.py options] (CPU)
#        bash benchmarks/gpu.sh rejax [rejax_peer.py flags] (rejax's tuned Pendulum-v1 SAC and
#          ours, 1 and 256 seeds; `gpu_wheels.sh rejax`)
#        bash benchmarks/gpu.sh sweep [benchmarks/sweep.py flags] (64 settings x 4 seeds of fast
#          in one program against one seed's run; the delivered mode's wheels)
#        bash benchmarks/gpu.sh presets [presets_delivered.py flags] (4 seeds of each preset,
#          every delivered policy scored in Gymnasium; the same wheels as delivered)
#        bash benchmarks/gpu.sh delivered [benchmarks/delivered.py flags, e.g. --cold] (the
#          README's command, seeds 0, 1, 2 one at a time and 256 seeds in one run, judged on
#          the device; delivered-KIND.json comes back in $OUT). Its wheels (no brax): mujoco,
#          mujoco-core, mujoco-mjx, trimesh, flax, optax, distrax, tfp-nightly, dm-tree,
#          decorator, gast, tyro, docstring-parser, typeguard, gymnasium,
#          farama-notifications, glfw, which Gymnasium's MuJoCo environments import, and for
#          checkpoints and TensorBoard orbax-checkpoint, tensorstore, humanize, aiofiles,
#          simplejson, uvloop, prometheus-client and tensorboard (59 MB).
#        bash benchmarks/gpu.sh progress [progress_overhead.py flags, e.g. --seeds 256] (the
#          delivered mode's wheels)
#        bash benchmarks/gpu.sh playground [playground_peer.py flags, e.g. --task CartpoleBalance]
#          (Brax's SAC with Playground's config against ours; `gpu_wheels.sh playground`)
#        bash benchmarks/gpu.sh playground_adapter [playground_adapter.py flags] (the same wheels)
#        bash benchmarks/gpu.sh search [preset_search.py flags] (the same wheels)
#        bash benchmarks/gpu.sh compile [compile_options.py flags: --variant XLA_FLAGS ...] (a
#          cold and a warm first run per variant; the delivered mode's wheels)
#        bash benchmarks/gpu.sh memory [benchmarks/memory.py flags, e.g. --largest 1000000] (the
#          delivered mode's wheels; memory-KIND.json)
set -uo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
  --target /tmp/site .whl/*.whl >/dev/null 2>&1 || { echo "wheel install failed"; exit 1; }
if [ -f .warp/rest.whl ]; then  # warp-lang in parts (benchmarks/gpu_wheels.sh warp)
  python3 -m zipfile -e .warp/rest.whl /tmp/site && cat .warp/so.a .warp/so.b | xz -dc \
    > /tmp/site/warp/bin/warp.so || { echo "warp did not go together"; exit 1; }
fi
# Bytecode now, as an installed package has it: the image sets PYTHONDONTWRITEBYTECODE, and without
# this every process would compile these packages' sources again (1.7 s of each startup).
python3 -m compileall -q -j 0 /tmp/site sac_jax envs scripts benchmarks >/dev/null 2>&1
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
via=$(printf ' %q' "$@")  # quoted as a shell takes it back
export SAC_JAX_BENCHMARK_VIA="bash benchmarks/gpu.sh${via}"  # recorded beside each file's command
SAC_JAX_RESULTS_DIR=$(mktemp -d /tmp/results.XXXXXX); export SAC_JAX_RESULTS_DIR
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
python3 -c "import jax, flax, optax, distrax; print('jax', jax.__version__, jax.devices())"
rc=0
run() { "$@" || rc=$?; }  # runs one benchmark; the mode's status is its last failure's
mode=${1:-}; shift
case "$mode" in
  env)
    run python3 -m benchmarks.env_throughput --sizes 1024 16384 131072 --steps 200 --repeats 3 \
      --skip-baselines "$@" ;;
  updates)
    run python3 -m benchmarks.seed_scaling --seeds 1 16 256 1024 --updates 200 "$@" ;;
  evaluation)
    rm -rf /tmp/policy-run
    python3 scripts/train.py --seed 0 --cache-dir /tmp/jaxcache --out /tmp/policy-run 2>&1 | tail -1
    run python3 -m benchmarks.evaluation_cost /tmp/policy-run "$@" ;;
  profile)
    run python3 -m benchmarks.profile_chunk "$@" ;;
  parallel)
    if [ $# -gt 0 ]; then
      run python3 -m benchmarks.data_parallel "$@"
    else
      run python3 -m benchmarks.data_parallel --num-envs 65536 --batch-size 16384
      run python3 -m benchmarks.data_parallel  # 262,144 environments, batch 65,536
      run python3 -m benchmarks.data_parallel --num-envs 524288 --batch-size 131072
      run python3 -m benchmarks.data_parallel --num-envs 1048576 --batch-size 262144 --repeats 3
    fi ;;
  brax|brax-cpu)
    if ! out=$(python3 -c "import PIL, scipy, brax.training.agents.sac.train" 2>&1); then
      echo "$out" | tail -5; echo "brax does not import"; exit 1
    fi
    if [ "$mode" = brax-cpu ]; then export JAX_PLATFORMS=cpu; fi
    run python3 -m benchmarks.brax_peer "$@" ;;
  playground)
    python3 -c "import tyro, orbax.checkpoint, brax.training.agents.sac.train
from mujoco_playground import registry" || exit 1
    run python3 -m benchmarks.playground_peer "$@" ;;
  playground_adapter)
    python3 -c "from mujoco_playground import registry" || exit 1
    run python3 -m benchmarks.playground_adapter "$@" ;;
  search)
    run python3 -m benchmarks.preset_search "$@" ;;
  torch)
    run python3 -m benchmarks.torch_time_to_solve "$@" ;;
  rejax)
    python3 -c "import tyro, orbax.checkpoint, rejax, gymnax" || exit 1
    # the benchmark holds JAX on the GPU while scripts/train.py runs in a subprocess
    export XLA_PYTHON_CLIENT_PREALLOCATE=false
    run python3 -m benchmarks.rejax_peer --rejax-python python3 --seeds 1 256 "$@" ;;
  delivered)
    python3 -c "import tyro, tensorboard, orbax.checkpoint, gymnasium; from mujoco import mjx
gymnasium.make('InvertedPendulum-v5').close()" || exit 1
    # delivered.py holds JAX on the GPU (its judging) while it starts each training process:
    # with JAX's default preallocation of 75 % of the memory the next one cannot allocate.
    export XLA_PYTHON_CLIENT_PREALLOCATE=false
    run python3 -m benchmarks.delivered --seeds 0 1 2 --many 256 --judge ours "$@" ;;
  presets)
    # presets_delivered.py holds JAX on the GPU (its scoring) while it starts the next preset's
    # training process: on an H100 that process ran out of memory (2026-12-07) at the default.
    export XLA_PYTHON_CLIENT_PREALLOCATE=false
    run python3 -m benchmarks.presets_delivered "$@" ;;
  progress)
    python3 -c "import tyro, tensorboard, orbax.checkpoint; from mujoco import mjx" || exit 1
    run python3 -m benchmarks.progress_overhead "$@" ;;
  compile)
    python3 -c "import tyro, tensorboard, orbax.checkpoint; from mujoco import mjx" || exit 1
    run python3 -m benchmarks.compile_options "$@" ;;
  memory)
    python3 -c "import tyro, tensorboard, orbax.checkpoint; from mujoco import mjx" || exit 1
    run env XLA_PYTHON_CLIENT_PREALLOCATE=false python3 -m benchmarks.memory "$@" ;;
  sweep)
    python3 -c "import tyro, tensorboard, orbax.checkpoint; from mujoco import mjx" || exit 1
    run python3 -m benchmarks.sweep --grid 64 --seeds 4 --separate 1 "$@" ;;
  *)
    echo "unknown mode $mode"; exit 2 ;;
esac
for file in "$SAC_JAX_RESULTS_DIR"/*.json; do
  [ -e "$file" ] || { echo "no results file written"; break; }
  echo "== $(basename "$file")"; cat "$file"
  if [ -n "${OUT:-}" ]; then cp "$file" "$OUT/"; fi
done
exit $rc
