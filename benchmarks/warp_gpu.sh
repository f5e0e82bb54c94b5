#!/usr/bin/env bash
# The warp backend on a CUDA GPU in one call: install, its tests, its agreement with the default backend, and its
# speed; every output goes to benchmarks/results/<gpu>/ (or $OUT when set, as on the device machine).
#
#     bash benchmarks/warp_gpu.sh            # about 10 minutes on an H100/H200
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv-gpu
. .venv-gpu/bin/activate
pip install --quiet --upgrade pip
pip install --quiet torch==2.13.0 -e ".[train,dev,warp]"
gpu=$(python -c "import torch; print(torch.cuda.get_device_name(0).split()[-1].lower())")
out=${OUT:-benchmarks/results/$gpu}
mkdir -p "$out"
export MUJOCO_GL=egl
nvidia-smi > "$out/warp_machine.txt" 2>&1 || true
pytest -q tests/test_warp.py 2>&1 | tee "$out/warp_tests.txt"
python experiments/warp_agreement.py --device cuda 2>&1 | tee "$out/warp_agreement.txt"
python benchmarks/env_scaling.py --backend warp --device cuda --num-envs 1024 4096 16384 --rounds 1 --no-peer \
  --csv "$out/warp_env_scaling.csv" 2>&1 | tee "$out/warp_env_scaling.txt"
python benchmarks/env_scaling.py --num-envs 1024 4096 --rounds 1 --no-peer --device cuda \
  --csv "$out/opengl_env_scaling.csv" 2>&1 | tee "$out/opengl_env_scaling.txt"
python benchmarks/train_speed.py --methods meta --backend warp --device cuda --num-envs 256 --rounds 1 --no-peer \
  2>&1 | tee "$out/warp_train_speed.txt"
