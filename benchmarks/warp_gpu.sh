#!/usr/bin/env bash
# The warp backend on a CUDA GPU in one call: where its cycle goes, its CUDA tests, its agreement with the default
# backend, and its speed in the TorchRL env and in training, with the OpenGL backend beside it on the same machine.
# The env is timed for 30 s a size: random play ends nearly every room's episode at once, at cycle 90, and a shorter
# window at 16,384 rooms would leave those resets out.
# The log goes to warp_gpu.log, the tables to CSVs, in benchmarks/results/<gpu>/ (or $OUT when set).
#
#     bash benchmarks/warp_gpu.sh               # first makes .venv-gpu and installs the project's train, dev, warp extras
#     bash benchmarks/warp_gpu.sh --no-install  # the python on PATH, as it is
set -uo pipefail
cd "$(dirname "$0")/.."
if [[ "${1:-}" != --no-install ]]; then
  python3 -m venv .venv-gpu && . .venv-gpu/bin/activate || exit 1
  pip install --quiet --upgrade pip && pip install --quiet torch==2.13.0 -e ".[train,dev,warp]" || exit 1
fi
gpu=$(python -c "import torch; print(torch.cuda.get_device_name(0).split()[-1].lower())") || exit 1
out=${OUT:-benchmarks/results/$gpu}
log=$out/warp_gpu.log
mkdir -p "$out"
: > "$log"
export MUJOCO_GL=egl PYTHONUNBUFFERED=1

# one step: its command, its output and how it ended, in the log; a step past its limit (seconds) is stopped
step() {
  local limit=$1 start=$SECONDS
  shift
  echo "== $(date -u +%FT%TZ) \$ $*" | tee -a "$log"
  timeout "$limit" "$@" 2>&1 | tee -a "$log"
  echo "== exit ${PIPESTATUS[0]} after $((SECONDS - start)) s" | tee -a "$log"
}

step 20 nvidia-smi
step 60 python -c "import sys, torch, mujoco, warp, mujoco_warp; print(sys.version.split()[0], 'torch', torch.__version__,
  'mujoco', mujoco.__version__, 'warp', warp.__version__, 'mujoco_warp', mujoco_warp.__version__)"
step 300 python benchmarks/warp_profile.py --device cuda --num-envs 4096 16384 --seconds 30 --warmup 2 \
  --csv "$out/warp_profile.csv"
step 120 python -m pytest -q -p no:cacheprovider tests/test_warp.py tests/test_layers.py -k cuda
step 60 python experiments/warp_agreement.py --device cuda
step 150 python benchmarks/env_scaling.py --backend warp --device cuda --num-envs 4096 16384 --seconds 30 \
  --warmup 2 --rounds 1 --no-peer --csv "$out/warp_env_scaling.csv"
step 120 python benchmarks/train_speed.py --methods meta --backend warp --device cuda --num-envs 4096 --seconds 15 \
  --rounds 1 --no-peer --parts
step 60 python benchmarks/env_scaling.py --num-envs 1024 --seconds 3 --warmup 2 --rounds 1 --no-peer --device cuda \
  --csv "$out/opengl_env_scaling.csv"
