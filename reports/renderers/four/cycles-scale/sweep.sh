#!/bin/sh
# Cycles' direct light from an emissive icosphere against the sphere's radius R (furnace
# sphere of albedo 0.5 with the camera inside, max depth 1, 16x16 px, 512 spp, seed 1): the
# G channel's image mean and its standard error over pixels. The exact reading is
# 1.5 x 0.94824 = 1.42236 (G of the exported emission, E(1 + a)). Run from the repository's
# root with Blender's bpy in ~/venvs/cycles (or CYCLES_PYTHON) and numpy + OpenEXR in PYTHON
# (any venv with both, e.g. the LuxCore one). Output: sweep.txt's format.
set -e
py=${CYCLES_PYTHON:-$HOME/venvs/cycles/bin/python}
num=${PYTHON:-python3}
furnace=${FURNACE:-target/release/furnace}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
run() { # level radius extra-driver-flags...
    level=$1 r=$2; shift 2
    sed "s/radius = 1.0/radius = $r/" tests/manifests/scenes/furnace-sphere-0.5.toml > "$tmp/s.toml"
    "$furnace" export "$tmp/s.toml" --format json --out "$tmp/e" -q
    "$py" reference/cycles/render.py --scene "$tmp/e/scene.json" --out "$tmp/o.exr" --spp 512 \
        --seed 1 --width 16 --height 16 --max-depth 1 --threads 2 --sphere-subdiv "$level" "$@" >/dev/null 2>&1
    "$num" - "$tmp/o.exr" "$level" "$r" "$*" <<'PY'
import sys, numpy as np, OpenEXR
f = OpenEXR.InputFile(sys.argv[1])
g = np.frombuffer(f.channel("G"), dtype=np.float32).astype(np.float64)
print(f"level {sys.argv[2]}  R {float(sys.argv[3]):>8g}  G {g.mean():.5f} +- {g.std(ddof=1) / np.sqrt(g.size):.5f}  "
      f"direct term {(g.mean() / 0.94824 - 1) / 0.5 - 1:+.2%}  {sys.argv[4]}")
PY
}
for r in 1.0 100.0 300.0 1000.0 1300.0 1600.0 2000.0 3000.0 10000.0 100000.0; do run 7 $r; done
for r in 1.0 10.0 30.0 100.0 300.0 1000.0 100000.0; do run 5 $r; done
run 7 100000.0 --no-emitter-sampling
run 5 100000.0 --no-emitter-sampling
