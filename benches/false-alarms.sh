#!/usr/bin/env bash
# False alarms of the default suite, measured: runs `furnace check` (every manifest under
# tests/manifests/, the furnace renderer) once per seed and appends each check's verdict and
# p-value to reports/false-alarms/pvalues.tsv. Seeds already in the file are skipped, so the
# sweep can be stopped and resumed, or split across machines by seed range and the files
# concatenated. The test `false_alarms_stay_within_the_stated_rate` (tests/suite/false_alarms.rs)
# reads the file.
#
#   benches/false-alarms.sh 1001 1100          # seeds 1001..1100
#   FURNACE=target/release/furnace benches/false-alarms.sh 1001 1010
#
# Each seed takes what one default-suite run takes (about 150 s on 2 cores). The file records,
# per line: seed, build (git describe), check name, verdict, p-value. The suite's manifests and
# scenes are read from this checkout at every seed, so run the sweep from a checkout nobody
# edits meanwhile, e.g. a worktree of the commit whose binary runs it:
#
#   git worktree add ../furnace-sweep HEAD && cargo build --release
#   FURNACE=$PWD/target/release/furnace ../furnace-sweep/benches/false-alarms.sh 1001 1100
#   cat ../furnace-sweep/reports/false-alarms/pvalues.tsv   # then commit it here
#
# FILTER (a --filter glob), ALPHA (--alpha) and OUT (the results file) sweep one new check
# alone; a check's seed derives from the run seed and its name only, so its p-value at a seed is
# the one a whole-suite run at that seed would give, and ALPHA set to the suite's per-test level
# gives the suite's verdict:
#
#   FILTER=sppm/cornell-convergence ALPHA=1.005e-4 \
#     OUT=reports/false-alarms/sppm-cornell-convergence.tsv benches/false-alarms.sh 1001 1100
#
# ARGS adds options to every run, e.g. a power target, or `--fixed` for the fixed-sample test
# (the sequential looks are `furnace check`'s default since 2026-12-05, 13:00 UTC; files
# recorded before then, mode-sequential-furnace.tsv aside, are fixed-sample runs):
#
#   FILTER='furnace/*=0.?]' ALPHA=0.05 \
#     OUT=reports/false-alarms/mode-sequential-furnace.tsv benches/false-alarms.sh 2001 2100
set -euo pipefail
first=${1:?first seed}
last=${2:?last seed}
cd "$(dirname "$0")/.."
furnace=${FURNACE:-target/release/furnace}
[ -x "$furnace" ] || cargo build --release
out=${OUT:-reports/false-alarms/pvalues.tsv}
mkdir -p "$(dirname "$out")"
[ -f "$out" ] || printf 'seed\tbuild\tcheck\tverdict\tp\n' > "$out"
# the build: the commit, "-dirty" when anything but the results files differs from it (so that
# sweeps of seed ranges side by side, each into its own file, label each other clean)
build=$(git describe --always)
git diff --quiet HEAD -- . ":(exclude)$out" ":(exclude)reports/false-alarms" || build="$build-dirty"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for seed in $(seq "$first" "$last"); do
  if cut -f1 "$out" | grep -qx "$seed"; then continue; fi
  # Exit code 1 (a check failed) is data here, not an error.
  "$furnace" check --seed "$seed" --quiet --json "$tmp/run.json" ${FILTER:+--filter "$FILTER"} ${ALPHA:+--alpha "$ALPHA"} ${ARGS:-} || [ $? -eq 1 ]
  # One line per outcome: name, verdict, p-value ("-" when the check has none).
  # With FILTER, only the selected checks (the others are reported as skipped).
  python3 - "$tmp/run.json" "$seed" "$build" "${FILTER:+selected}" >> "$out" <<'EOF'
import json, sys
run = json.load(open(sys.argv[1]))
for o in run["outcomes"]:
    if sys.argv[4] and o["verdict"] == "SKIPPED":
        continue
    p = o.get("p_value")
    print(f'{sys.argv[2]}\t{sys.argv[3]}\t{o["name"]}\t{o["verdict"]}\t{"-" if p is None else repr(p)}')
EOF
  echo "seed $seed: $(awk -F'\t' -v s="$seed" '$1 == s && $4 != "PASS" && $4 != "SKIPPED"' "$out" | wc -l) checks not passed"
done
