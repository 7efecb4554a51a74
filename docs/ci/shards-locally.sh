#!/bin/sh
# The README's sharded CI workflow, run on one machine: N shard jobs, one after another, then
# the merge job. Exit code: the merge's (0 pass, 1 a check failed, 2 the shards do not make
# one run).
#
#   cargo build --release && docs/ci/shards-locally.sh [N] [check options...]
# FURNACE (the binary) and OUT (the folder, emptied first) override the defaults.
set -eu
cd "$(dirname "$0")/../.."
n=${1:-4}
[ $# -gt 0 ] && shift
bin=${FURNACE:-target/release/furnace}
out=${OUT:-out/shards}
rm -rf "$out" && mkdir -p "$out"
k=1
while [ "$k" -le "$n" ]; do
    # a shard exits 1 on its own failures: only 2 (invalid input) stops the workflow
    "$bin" check -q --shard "$k/$n" --json "$out/shard-$k.json" "$@" || [ $? -eq 1 ]
    k=$((k + 1))
done
"$bin" merge "$out"/shard-*.json --json "$out/merged.json" --junit "$out/junit.xml" \
    --markdown "$out/summary.md" --report "$out/report.html"
