#!/bin/sh
# mitsuba3:scalar_spectral as furnace ran it: 4 independent runs of 64 spp, 16x16 px; each writes batch-B.exr here.
here=$(cd "$(dirname "$0")" && pwd)
cd /work/main || exit 1
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-0.exr --spp 64 --seed 639569637 --width 16 --height 16 --max-depth 3 --variant scalar_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-1.exr --spp 64 --seed 1723480988 --width 16 --height 16 --max-depth 3 --variant scalar_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-2.exr --spp 64 --seed 1843230457 --width 16 --height 16 --max-depth 3 --variant scalar_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-3.exr --spp 64 --seed 1123313818 --width 16 --height 16 --max-depth 3 --variant scalar_spectral --threads 2
