#!/usr/bin/env bash
# Time to a looker that pays on one CUDA GPU, in one call: installs the project, runs the warp backend's CUDA tests,
# then trains the default recipe with the warp backend at each setting of SETTINGS over SEEDS, each run timed as a
# user would time it (wall clock from the command's start: start-up, compile and the held-out evaluation included).
# Each run's row goes to gpu_learning.csv (setting, seed, wall seconds, held-out success of the learned policy, with
# the camera held forward, of random play), the log to gpu_learning.log, in benchmarks/results/<gpu>/ (or $OUT).
#
#     bash benchmarks/gpu_learning.sh                     # makes .venv-gpu and installs the train, dev, warp extras
#     bash benchmarks/gpu_learning.sh --no-install        # the python on PATH, as it is
#     SEEDS="0 1 2 3 4" SETTINGS="--num-envs 256 --frames 1500000" bash benchmarks/gpu_learning.sh --no-install
#
# SETTINGS holds one setting per line (activeperc-train's flags). The defaults, seed 0 only, fit one call of 10
# minutes with the install; the setting that pays then gets SEEDS="0 1 2 3 4" in a second call, --no-install. They
# follow the CPU runs of docs/performance.md's many-rooms table: at 256 rooms x 8 cycles a decaying 1.4e-3 nears the
# 32-room curve by 800,000-1,000,000 frames and 2.8e-3 learns slower, so more frames, not a larger rate, for more rooms.
set -uo pipefail
cd "$(dirname "$0")/.."
if [[ "${1:-}" != --no-install ]]; then
  python3 -m venv .venv-gpu && . .venv-gpu/bin/activate || exit 1
  pip install --quiet --upgrade pip && pip install --quiet torch==2.13.0 -e ".[train,dev,warp]" || exit 1
fi
SEEDS=${SEEDS:-0}
SETTINGS=${SETTINGS:-"--num-envs 256 --rollout-length 8 --frames 2000000 --lr 0.0014 --lr-schedule linear
--num-envs 1024 --rollout-length 8 --frames 4000000 --lr 0.0014 --lr-schedule linear"}
LIMIT=${LIMIT:-150}  # seconds a run may take
gpu=$(python -c "import torch; print(torch.cuda.get_device_name(0).split()[-1].lower())") || exit 1
out=${OUT:-benchmarks/results/$gpu}
log=$out/gpu_learning.log
csv=$out/gpu_learning.csv
mkdir -p "$out" runs/gpu_learning
: > "$log"
export MUJOCO_GL=egl PYTHONUNBUFFERED=1
machine="$(python -c "import torch; print(torch.cuda.get_device_name(0))"), $(nproc) cores"
echo "setting,seed,wall_s,success_rate,camera_held_success_rate,random_success_rate,command,machine,date" > "$csv"

echo "== $(date -u +%FT%TZ) CUDA tests of the warp backend" | tee -a "$log"
timeout 180 python -m pytest -q -p no:cacheprovider tests/test_warp.py tests/test_layers.py -k cuda 2>&1 | tee -a "$log"

index=0
while IFS= read -r setting; do
  [[ -z "$setting" ]] && continue
  index=$((index + 1))
  for seed in $SEEDS; do
    run=runs/gpu_learning/setting$index/seed$seed
    rm -rf "$run"
    command="activeperc-train --backend warp --device cuda $setting --seed $seed --no-progress --out $run"
    echo "== $(date -u +%FT%TZ) \$ $command" | tee -a "$log"
    start=$(date +%s.%N)
    timeout "$LIMIT" $command 2>&1 | tee -a "$log"
    status=${PIPESTATUS[0]}
    wall=$(python -c "print(f'{$(date +%s.%N) - $start:.1f}')")
    echo "== exit $status after $wall s" | tee -a "$log"
    python - "$run/eval.json" "$setting" "$seed" "$wall" "$command" "$machine" >> "$csv" <<'EOF'
import csv, datetime, json, pathlib, sys

path, setting, seed, wall, command, machine = sys.argv[1:]
scores = json.loads(pathlib.Path(path).read_text()) if pathlib.Path(path).is_file() else {}
rate = lambda name: scores[name]["success_rate"] if name in scores else "nan"  # nan: the run did not finish
row = [setting, seed, wall, rate("learned"), rate("camera_held"), rate("random"), command, machine]
csv.writer(sys.stdout).writerow(row + [datetime.date.today().isoformat()])
EOF
  done
done <<< "$SETTINGS"
cat "$csv"
