#!/bin/sh
# mitsuba3:scalar_spectral as furnace ran it: 4 independent runs of 128 spp, 8x8 px; each writes batch-B.exr here.
here=$(cd "$(dirname "$0")" && pwd)
cd /work/main || exit 1
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-0.exr --spp 128 --seed 487779392 --width 8 --height 8 --max-depth 1 --variant scalar_spectral --threads 2
