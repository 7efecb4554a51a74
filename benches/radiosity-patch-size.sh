#!/usr/bin/env bash
# Radiosity's time and error against patch size on the measured Cornell box (64x64): each
# patch size is solved (and solved again at twice the size for the discretisation estimate)
# and compared region by region with a path-traced reference (8192 spp, seed 7). Prints one
# Markdown row per size with the CPU it ran on. Whole-process wall times, one run each.
#
#   benches/radiosity-patch-size.sh [SIZE...]      # default 200 140 97 70 47 (mm)
set -euo pipefail
cd "$(dirname "$0")/.."
furnace=${FURNACE:-target/release/furnace}
[ -x "$furnace" ] || cargo build --release
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(200 140 97 70 47)
scene=scenes/cornell-box.toml
regions=scenes/cornell-box.regions.toml
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | xargs), $(nproc) threads"
"$furnace" render "$scene" --width 64 --height 64 --spp 8192 --seed 7 -q -o "$tmp/ref.exr"
echo "| patch size (mm) | patches | whole image Y vs reference | named regions (R, G, B) | discretisation estimate (whole image) | wall time |"
echo "|---|---|---|---|---|---|"
for s in "${sizes[@]}"; do
  start=$(date +%s.%N)
  log=$("$furnace" render "$scene" --integrator radiosity --patch-size "$s" --width 64 --height 64 --spp 64 -o "$tmp/rad.exr")
  end=$(date +%s.%N)
  cmp=$("$furnace" compare "$tmp/rad.exr" "$tmp/ref.exr" --color never --regions "$regions" || true)
  python3 - "$s" "$start" "$end" <<PY
import re, sys
log = """$log"""
cmp = """$cmp"""
s, t0, t1 = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
patches = re.search(r"radiosity: (\d+) patches", log).group(1)
est = re.search(r"([0-9.e+-]+) on the whole image", log).group(1)
rows = [l for l in cmp.splitlines() if re.match(r"^\S.* (R|G|B) ", l) and not l.startswith(("R ", "G ", "B "))]
diffs = {}
for l in rows:
    m = re.search(r"^(.*?)\s+(R|G|B)\s.*?([-+][0-9.]+)%", l)
    diffs[(m.group(1).strip(), m.group(2))] = float(m.group(3))
whole = diffs[("whole image", "G")]
named = [v for (r, c), v in diffs.items() if r != "whole image"]
print(f"| {s} | {patches} | {whole:+.2f} % | {min(named):+.1f} … {max(named):+.1f} % | {100*float(est):.2f} % | {t1-t0:.1f} s |")
PY
done
