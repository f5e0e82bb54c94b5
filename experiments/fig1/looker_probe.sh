#!/usr/bin/env bash
# Probe what meta's looker learns under 16 settings of its options (fov 60, seed 0 unless named): 16 trainings
# of FRAMES frames at once, each pinned to one CPU (CPU i % the machine's count, so 16 cores run them side by
# side), then looker_stats.py prints what each looker did. Stop it with Ctrl-C: every run saves its checkpoint.
#
#   bash experiments/fig1/looker_probe.sh OUT_DIR FRAMES [extra activeperc-train flags, e.g. --device cuda]
#
# docs/reproduction.md says which command produced experiments/fig1/results/looker_probe.csv.
set -euo pipefail
if [ $# -lt 2 ]; then
    echo "usage: $0 OUT_DIR FRAMES [activeperc-train flags]" >&2
    exit 2
fi
out=$1 frames=$2
shift 2
if [ -e "$out" ]; then
    echo "$0: $out exists; give a new folder" >&2
    exit 2
fi
variants=(
    "default|"
    "lr3e-4|--looker-lr 3e-4"
    "lr1e-3|--looker-lr 1e-3"
    "hold0.6|--looker-hold-prob 0.6"
    "hold0.6_lr3e-4|--looker-hold-prob 0.6 --looker-lr 3e-4"
    "hold0.4|--looker-hold-prob 0.4"
    "hold0.4_lr3e-4|--looker-hold-prob 0.4 --looker-lr 3e-4"
    "sample|--e1-looks sample"
    "sample_hold0.6_lr3e-4|--e1-looks sample --looker-hold-prob 0.6 --looker-lr 3e-4"
    "eps0.5_lr3e-4|--epsilon 0.5 --looker-lr 3e-4"
    "ent1e-3_lr3e-4|--looker-entropy-coeff 0.001 --looker-lr 3e-4"
    "alpha0.2_lr3e-4|--alpha 0.2 --looker-lr 3e-4"
    "paper_mover|--mover-rollouts d1"
    "fixed_forward|--method fixed_forward"
    "hold0.6_lr3e-4_seed1|--looker-hold-prob 0.6 --looker-lr 3e-4 --seed 1"
    "hold0.6_lr3e-4_fov100|--looker-hold-prob 0.6 --looker-lr 3e-4 --fov 100"
)
mkdir -p "$out"
cpus=$(nproc)
pids=()
for i in "${!variants[@]}"; do
    name=${variants[$i]%%|*}
    read -r -a flags <<< "${variants[$i]#*|}"
    taskset -c $((i % cpus)) python -m activeperc_rl.cli --out "$out/$name" --frames "$frames" --eval-episodes 0 \
        --no-progress "${flags[@]}" "$@" > "$out/$name.log" 2>&1 &
    pids+=($!)
done
trap 'kill -INT "${pids[@]}" 2> /dev/null || true' TERM  # a terminal's Ctrl-C reaches the runs themselves
wait "${pids[@]}" || wait "${pids[@]}" || true
python "$(dirname "$0")/looker_stats.py" "$out"/*/
