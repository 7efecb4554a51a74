#!/usr/bin/env bash
# Instructions and simulated branch mispredictions of the path tracer's loop, for one furnace
# build or two side by side: repeatable counts for changes too small for wall-time pairs on a
# noisy machine (a 2-vCPU VM's repeated runs of one build spread by ±25 % on some days).
# Callgrind's branch predictor is a simple model, not the CPU's: its mispredictions show
# whether a change removes hard-to-predict branches, not what they cost.
#
#   benches/instructions.sh target/release/furnace                 # one build
#   benches/instructions.sh /tmp/furnace-before target/release/furnace   # A, B and B/A
#
# Scenes: the measured Cornell Box, the glossy box, the albedo-0.99 furnace sphere, the fog
# box and (when benches/cornell-mesh/make.py has written it) the 10^5-triangle mesh; 32x32 px,
# 16 spp, 5 bounces, one thread. Needs valgrind. Images are compared bit for bit too.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { sed -n 2,14p "$0"; exit 2; }
command -v valgrind >/dev/null || { echo "instructions.sh: valgrind is not installed" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
sed 's/^reflectance = 0.5 /reflectance = 0.99/' scenes/furnace-sphere.toml >"$tmp/furnace-sphere-0.99.toml"
scenes=(scenes/cornell-box.toml scenes/cornell-glossy.toml "$tmp/furnace-sphere-0.99.toml" scenes/hg-fog.toml)
[ -f benches/cornell-mesh/scene.toml ] && scenes+=(benches/cornell-mesh/scene.toml)

. "$(dirname "$0")/same-image.sh"
count() { # binary scene tag -> "instructions mispredictions"
    valgrind --tool=callgrind --branch-sim=yes --callgrind-out-file="$tmp/cg.out" \
        --toggle-collect='furnace::integrators::path::PathTracer::trace' \
        "$1" render "$2" --width 32 --height 32 --spp 16 --max-depth 5 --threads 1 --quiet \
        --out "$tmp/$3.exr" 2>&1 |
        awk '/Collected/ {ir=$4} /Mispredicts:/ {gsub(",", "", $3); mp=$3} END {print ir, mp}'
}

printf '%-28s %16s %12s' scene instructions mispredicts
[ $# -ge 2 ] && printf ' %16s %12s %8s %8s %s' "B instructions" "B mispred." "B/A ir" "B/A mp" image
echo
for s in "${scenes[@]}"; do
    read -r ir mp < <(count "$1" "$s" a)
    name=$(basename "$s" .toml)
    [ "$name" = scene ] && name=$(basename "$(dirname "$s")")
    printf '%-28s %16s %12s' "$name" "$ir" "$mp"
    if [ $# -ge 2 ]; then
        read -r ir2 mp2 < <(count "$2" "$s" b)
        same=$(same_image "$1" "$tmp/a.exr" "$tmp/b.exr")
        printf ' %16s %12s %8.4f %8.4f %s' "$ir2" "$mp2" "$(echo "$ir2 / $ir" | bc -l)" \
            "$(echo "$mp2 / $mp" | bc -l)" "$same"
    fi
    echo
done
