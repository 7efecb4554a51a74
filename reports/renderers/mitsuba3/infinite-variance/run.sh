#!/bin/sh
# Verdicts of Mitsuba 3's capped Russian roulette (furnace/sphere at albedo 0.99 and 0.999)
# over run seeds FIRST..LAST, for one variant: one JSON line per check and seed in
# verdicts-VARIANT.jsonl. Needs Mitsuba 3 on PATH (README: "Other renderers"), and for llvm_*
# variants DRJIT_LIBLLVM_PATH. Run from the repository's root (FURNACE: the furnace binary).
# The two checks alone make a family of 2: per-test α 0.005.
# Usage: run.sh VARIANT [FIRST [LAST]]
set -eu
variant=$1
first=${2:-1}
last=${3:-100}
furnace=${FURNACE:-furnace}
out=$(dirname "$0")/verdicts-$variant.jsonl
seed=$first
while [ "$seed" -le "$last" ]; do
    "$furnace" check tests/manifests/furnace.toml --filter 'furnace/sphere*0.99*' \
        --renderer "mitsuba3:$variant" --seed "$seed" --no-isolation --format json 2>/dev/null |
        grep '"verdict"' | sed "s/^{/{\"seed\":$seed,/" >>"$out" || true
    seed=$((seed + 1))
done
