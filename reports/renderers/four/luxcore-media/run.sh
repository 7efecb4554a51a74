#!/bin/sh
# LuxCore 2.11.2 in a lossless isotropic fog (FINDINGS.md, LuxCore): each scene here is furnace's
# JSON export of tests/manifests/scenes/medium-furnace-glass-1.toml (`furnace export --format json`)
# with the boundary or sigma_s changed. Prints the 8x8 centre pixels' mean over the environment's
# radiance (expected 1: a lossless furnace) and its standard error, at path caps K.
#   LUXCORE_PYTHON=~/venvs/luxcore/bin/python reports/renderers/four/luxcore-media/run.sh
set -eu
here=$(cd "$(dirname "$0")" && pwd)
py=${LUXCORE_PYTHON:-$HOME/venvs/luxcore/bin/python}
out=$(mktemp -d)
for scene in "$here"/*.json; do
  for k in 64 256 2048; do
    name=$(basename "$scene" .json)
    "$py" "$here/../../../../reference/luxcore/render.py" --scene "$scene" --out "$out/$name-$k.exr" \
      --spp 256 --seed 1 --width 16 --height 16 --max-depth -1 --threads 2 \
      --unlimited-depth "$k" --render-lossless-media > /dev/null 2> "$out/stderr" \
      || { cat "$out/stderr" >&2; exit 1; }
    "$py" - "$out/$name-$k.exr" "$scene" "$name" "$k" <<'PY'
import json, sys, numpy as np, OpenEXR
c = OpenEXR.File(sys.argv[1]).channels()
p = np.asarray(c["RGB"].pixels if "RGB" in c else np.stack([c[k].pixels for k in "RGB"], -1), float)
env = json.load(open(sys.argv[2]))["lights"][0]["radiance_rgb"]
r = (p[4:12, 4:12] / env)[..., 1]
print(f"{sys.argv[3]:32} K {sys.argv[4]:>4}: {r.mean():.4f} +- {r.std(ddof=1) / 8:.4f}")
PY
  done
done
rm -rf "$out"
