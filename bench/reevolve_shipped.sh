#!/usr/bin/env bash
# Re-evolve the shipped controllers with --stamp-timed and check each run on the twin.
# For each model, seeds 1..3 at the shipped controller's own GA budget (its "ga" field), then a
# build of each best.json runs 30 transitions on the twin with physics; the table printed at the
# end (and OUT/twin.tsv) gives the stamp-timed fitness, the twin's distance and the plain
# simulator's. The run with the longest twin distance is the candidate to ship
# (docs/results.md "The shipped controllers re-evolved with --stamp-timed"): copy OUT/M-sS/best.json and history.csv to
# bstool/data/controllers/M.json and M.history.csv, then regenerate the goldens.
# About 1 hour on 1 core. Usage: [MODELS="nnsin nnsig"] [SEEDS="1 2"]
# [EVOLVE_ARGS="--schedule-builds 3"] bash bench/reevolve_shipped.sh [OUT_DIR] [WORKERS]
set -euo pipefail
OUT=${1:-/tmp/reevolve}
WORKERS=${2:-1}
mkdir -p "$OUT"
budget() {  # the shipped run's pop gens coevol_gens pm
  python - "$1" <<'PY'
import sys
from bstool import fileio
from bstool.builtin import builtin_controller
ga = fileio.read_json(builtin_controller(sys.argv[1]), "controller file")["ga"]
print(ga["pop"], ga["gens"], ga["coevol_gens"], ga["pm"])
PY
}
for m in ${MODELS:-nnsin nnsig ca1d ca2dsing ca2ddiff}; do
  read -r pop gens coevol pm < <(budget "$m")
  for seed in ${SEEDS:-1 2 3}; do
    run="$OUT/$m-s$seed"
    [ -f "$run/best.json" ] || bstool evolve "$m" --pop "$pop" --gens "$gens" \
      --coevol-gens "$coevol" --pm "$pm" --seed "$seed" --workers "$WORKERS" --stamp-timed \
      ${EVOLVE_ARGS:-} --out "$run" --force -q
    [ -f "$run/twin.json" ] && continue
    bstool compile "$run/best.json" -o "$run/build" -q --force
    bstool twin "$run/build" -T 30 --json -q > "$run/twin.json.tmp"
    mv "$run/twin.json.tmp" "$run/twin.json"
  done
done
python - "$OUT" <<'PY'
import sys
from pathlib import Path
from bstool import fileio
rows = ["run\tstamp_fitness_cm\ttwin_cm\tstamp_timed_cm\tplain_cm\tstates_equal"]
for run in sorted(Path(sys.argv[1]).glob("*-s*")):
    best = fileio.read_json(run / "best.json", "controller file")
    twin = fileio.read_json(run / "twin.json", "twin report")
    rows.append("\t".join([run.name, f"{100 * best['fitness']:.1f}",
                           f"{100 * twin['twin_distance']:.1f}", f"{100 * twin['stamp_distance']:.1f}",
                           f"{100 * twin['sim_distance']:.1f}", str(twin.get("states_equal"))]))
text = "\n".join(rows) + "\n"
fileio.write_text(Path(sys.argv[1]) / "twin.tsv", text)
print(text, end="")
PY
