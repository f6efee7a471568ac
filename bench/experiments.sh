#!/usr/bin/env bash
# The long runs behind docs/results.md: evolve all five models over several seeds at two
# budgets, report on them, multiple failures, and plain GA vs co-evolution with parasites.
# About 1.5 hours on 2 cores. Usage: bash bench/experiments.sh [OUT_DIR]  (default /tmp/exp)
# Then: python bench/results_table.py OUT/report-s1 OUT/report-s2 ... (tables of docs/results.md)
# `bash bench/experiments.sh OUT --stamp-timed`: budget A only, evolved and reported with
# --stamp-timed (docs/results.md "Budget A, stamp-timed").
set -euo pipefail
OUT=${1:-/tmp/exp}
MODE=${2:-}
TIMED=()
[ "$MODE" = "--stamp-timed" ] && TIMED=(--stamp-timed)
HERE="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$OUT/big"
cd "$OUT"

evolve_all() {  # $1: folder prefix, $2: pop, $3: gens, $4: ca2ddiff outer loops, $5: seed
  local dir=$1 pop=$2 gens=$3 loops=$4 seed=$5
  for m in nnsin nnsig ca1d ca2dsing; do
    [ -f "$dir$m-s$seed/best.json" ] || bstool evolve "$m" --pop "$pop" --gens "$gens" \
      --seed "$seed" --workers 2 --out "$dir$m-s$seed" -q "${TIMED[@]}"
  done
  [ -f "${dir}ca2ddiff-s$seed/best.json" ] || bstool evolve ca2ddiff --pop "$pop" \
    --gens "$loops" --coevol-gens 8 --seed "$seed" --workers 2 --out "${dir}ca2ddiff-s$seed" -q \
    "${TIMED[@]}"
}

report_seed() {  # $1: folder prefix, $2: seed, then extra report options
  local dir=$1 seed=$2
  shift 2
  bstool report "${dir}nnsin-s$seed" "${dir}nnsig-s$seed" "${dir}ca1d-s$seed" \
    "${dir}ca2dsing-s$seed" "${dir}ca2ddiff-s$seed" -o "${dir}report-s$seed" -q "${TIMED[@]}" "$@"
}

# small budget: pop 20, 15 generations (ca2ddiff: 1 outer loop of 8 co-evolution generations)
for seed in 1 2 3; do evolve_all "" 20 15 1 "$seed"; done
for seed in 1 2 3; do report_seed "" "$seed"; done
# multiple failures: 20 random sets per K = 1..5 on the seed-1 controllers
bstool report nnsin-s1 nnsig-s1 ca1d-s1 ca2dsing-s1 ca2ddiff-s1 --multi-failures 20 \
  -o report-multi-s1 -q "${TIMED[@]}"
[ "$MODE" = "--stamp-timed" ] && exit 0
# plain GA vs the same budget in generations vs co-evolved failures (ca1d, 4 seeds)
python "$HERE/bench/compare_evolution.py" --model ca1d --seeds 1 2 3 4 --pop 20 --gens 4 \
  --transitions 30 --variants plain plain-equal coevolve --workers 2 --out cmp-ca1d \
  > cmp-ca1d.txt
# larger budget: pop 30, 30 generations (ca2ddiff: 2 outer loops)
for seed in 1 2 3 4 5; do evolve_all big/ 30 30 2 "$seed"; done
for seed in 1 2 3 4 5; do report_seed big/ "$seed"; done
bstool report big/nnsin-s1 big/nnsig-s1 big/ca1d-s1 big/ca2dsing-s1 big/ca2ddiff-s1 \
  --multi-failures 20 -o big/report-multi-s1 -q
# figures of docs/results/ (budget B, seed 1)
python "$HERE/bench/results_table.py" big/report-multi-s1 --figures "$HERE/docs/results" > /dev/null
