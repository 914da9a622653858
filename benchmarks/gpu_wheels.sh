#!/usr/bin/env bash
# Downloads into .whl/ the wheels benchmarks/gpu.sh installs on a lent GPU machine (Python 3.12,
# x86-64), each at the version installed in the active environment (pip install -e ".[test]"
# first), so that the device runs what CI tests. .whl/ is git-ignored: carry it (carry: [".whl"]).
# Usage: bash benchmarks/gpu_wheels.sh            # the delivered, progress and memory modes' set
#        bash benchmarks/gpu_wheels.sh brax       # and brax with its imported needs (brax modes)
#        bash benchmarks/gpu_wheels.sh playground # brax's and MuJoCo Playground (playground modes;
#          pip install -e ".[playground]" first). Warp stays out: warp-lang's wheel (136 MB) is
#          over the device tool's 64 MiB carry, and Playground's MJX tasks run without it.
#        bash benchmarks/gpu_wheels.sh rejax      # rejax's peer (rejax mode): ours without MuJoCo
#          (Pendulum-v1 needs none), and rejax 0.1.3 with gymnax 0.0.9 (the image has the rest)
#        bash benchmarks/gpu_wheels.sh all        # the playground set with rejax's and gymnasium:
#          the modes of one device session in one carry (41 MB)
#        bash benchmarks/gpu_wheels.sh warp       # warp-lang (149 MB) into .warp/ in three parts
#          under the carry's 64 MiB: its warp.so xz-compressed and split (.warp/so.a, .warp/so.b),
#          and the rest of the wheel (.warp/rest.whl). A carried path is gone at the next call,
#          so each call to one warm machine carries one part and copies it out of the tree:
#            carry .warp/so.a:  mkdir -p /tmp/parts && cp .warp/so.a /tmp/parts/
#            carry .warp/so.b:  cp .warp/so.b /tmp/parts/
#            carry .whl:        cp -r .whl /tmp/parts/whl
#            carry .warp/rest.whl:  cp -r /tmp/parts/whl .whl && cp /tmp/parts/so.* .warp/ &&
#              bash benchmarks/gpu.sh playground_adapter --impl jax warp --envs 4096
#          (benchmarks/gpu.sh puts warp together where it finds .warp/rest.whl)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = warp ]; then
  version=$(python -c "import importlib.metadata as m; print(m.version('warp-lang'))")
  rm -rf .warp && mkdir -p .warp/dl
  python -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 -d .warp/dl "warp-lang==$version"
  wheel=$(ls .warp/dl/*.whl)
  (cd .warp && unzip -q "dl/$(basename "$wheel")" warp/bin/warp.so)
  xz -T0 -6 -c .warp/warp/bin/warp.so > .warp/so.xz
  split -n 2 .warp/so.xz .warp/so. && mv .warp/so.aa .warp/so.a && mv .warp/so.ab .warp/so.b
  rm .warp/so.xz
  cp "$wheel" .warp/rest.whl && zip -q -d .warp/rest.whl warp/bin/warp.so
  rm -rf .warp/dl .warp/warp
  du -sh .warp/*
  exit 0
fi
names="mujoco mujoco-core mujoco-mjx trimesh flax optax distrax tfp-nightly dm-tree decorator
gast tyro docstring-parser typeguard gymnasium farama-notifications glfw orbax-checkpoint
tensorstore humanize aiofiles simplejson uvloop prometheus-client tensorboard"
case "${1:-}" in
  brax) names="$names brax jaxopt ml_collections" ;;
  playground)  # without the packages the image has (tensorstore, tensorboard, ...), to fit
    names="mujoco mujoco-core mujoco-mjx trimesh flax optax distrax tfp-nightly dm-tree decorator
gast tyro docstring-parser typeguard orbax-checkpoint brax jaxopt ml_collections playground" ;;
  all)
    names="mujoco mujoco-core mujoco-mjx trimesh flax optax distrax tfp-nightly dm-tree decorator
gast tyro docstring-parser typeguard orbax-checkpoint brax jaxopt ml_collections playground
gymnasium farama-notifications glfw tensorboard rejax==0.1.3 gymnax==0.0.9" ;;
  rejax)
    names="flax optax distrax tfp-nightly dm-tree decorator gast tyro docstring-parser typeguard
orbax-checkpoint gymnasium farama-notifications rejax==0.1.3 gymnax==0.0.9" ;;
esac
# ml_dtypes at our pin in every set (pyproject.toml: 0.7.0 takes 0.8 s to import), for the
# image's own and rejax's side alike, since both import it through jax
names="$names ml_dtypes"
mkdir -p .whl
for name in $names; do
  case "$name" in  # a name with its version pinned here, or at the active environment's
    *==*) version=${name#*==}; name=${name%%==*} ;;
    *) version=$(python -c "import importlib.metadata as m, sys; print(m.version(sys.argv[1]))" \
         "$name") ;;
  esac
  python -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
    --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
    --platform manylinux1_x86_64 -d .whl "$name==$version"
done
du -sh .whl
