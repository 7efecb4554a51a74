#!/usr/bin/env bash
# The path tracer's time against accuracy as Russian roulette starts earlier or later
# (`--rr-depth`, the bounces before roulette starts; default 5). For each scene and depth,
# medians over SEEDS runs of:
#   * the render's own wall time;
#   * relMSE against the committed Mitsuba reference, (x - r)^2/(r^2 + 0.01) averaged over
#     pixels and R, G, B (`furnace compare`, as reference/mitsuba/bench.py measures it, here
#     without subtracting the reference's own noise), and the efficiency 1/(relMSE x time);
#   * the render's noise figure, the mean variance of the Y pixel means over the squared image
#     mean (a plain MSE, which bright pixels dominate), and its efficiency;
# each efficiency also as a ratio to depth 5. The two efficiencies can disagree: starting
# roulette early costs most in dim pixels lit only after several bounces, which relMSE weights
# up. Renders use Mitsuba's colour pipeline (`--observer mitsuba3`), as the references do.
# Prints Markdown rows after the CPU it ran on.
#
#   benches/roulette-depth.sh                      # the scenes and depths below, seeds 1 2
#   DEPTHS="1 5" SEEDS="1 2 3" benches/roulette-depth.sh
set -euo pipefail
cd "$(dirname "$0")/.."
furnace=${FURNACE:-target/release/furnace}
[ -x "$furnace" ] || cargo build --release
depths=${DEPTHS:-1 2 3 5}
seeds=${SEEDS:-1 2}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# scene | width height spp | reference (the references' sizes: reference/mitsuba/*.json)
runs=(
  "scenes/cornell-box.toml|128 128 256|reference/mitsuba/cornell-box.exr"
  "scenes/cornell-glossy.toml|128 128 256|reference/mitsuba/cornell-glossy.exr"
  "scenes/hg-fog.toml|96 64 256|reference/mitsuba/hg-fog.exr"
  "scenes/rayleigh-sky.toml|128 96 64|reference/mitsuba/rayleigh-sky.exr"
  "scenes/furnace-sphere.toml|64 64 64|reference/mitsuba/furnace-sphere.exr"
)
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | xargs), $(nproc) threads; seeds: $seeds"
echo "| scene | px, spp | roulette from bounce | wall time (s) | relMSE | 1/(relMSE x time) | vs bounce 5 | MSE / mean² | 1/(MSE/mean² x time) | vs bounce 5 |"
echo "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for run in "${runs[@]}"; do
  IFS='|' read -r scene size ref <<<"$run"
  read -r w h spp <<<"$size"
  for d in $depths; do
    for s in $seeds; do
      "$furnace" render "$scene" --width "$w" --height "$h" --spp "$spp" --rr-depth "$d" --seed "$s" \
        --observer mitsuba3 -o "$tmp/out.exr"
      "$furnace" compare "$tmp/out.exr" "$ref" --color never || true
    done | python3 -c "
import re, statistics as st, sys
text = sys.stdin.read()
wall = [float(x) for x in re.findall(r'([0-9.]+) s wall', text)]
mse = [float(x) for x in re.findall(r'squared mean of Y ([0-9.e+-]+)', text)]
# the compare table's R, G, B rows: channel, mean test, mean ref, RMSE, relMSE, SMAPE
rows = re.findall(r'^[RGB] +\S+ +\S+ +\S+ +(\S+) +\S+$', text, re.M)
rel = [sum(float(x) for x in rows[i:i + 3]) / 3 for i in range(0, len(rows), 3)]
print(sys.argv[1], sys.argv[2], sys.argv[3], st.median(wall), st.median(rel), st.median(mse))
" "$(basename "$scene" .toml)" "${w}x$h, $spp" "$d"
  done
done | python3 -c "
import sys
rows = [l.rstrip('\n').split(' ') for l in sys.stdin if l.strip()]
rows = [(r[0], ' '.join(r[1:3]), r[3], *map(float, r[4:])) for r in rows]
eff = lambda wall, err: 1.0 / (err * wall)
base = {r[0]: r for r in rows if r[2] == '5'}
for name, px, d, wall, rel, mse in rows:
    b = base.get(name)
    r1 = f'{eff(wall, rel) / eff(b[3], b[4]):.2f}' if b else ''
    r2 = f'{eff(wall, mse) / eff(b[3], b[5]):.2f}' if b else ''
    print(f'| {name} | {px} | {d} | {wall:.2f} | {rel:.3e} | {eff(wall, rel):.3e} | {r1} | {mse:.3e} | {eff(wall, mse):.3e} | {r2} |')
"
