#!/bin/sh
# mitsuba3:llvm_ad_spectral as furnace ran it: 4 independent runs of 128 spp, 8x8 px; each writes batch-B.exr here.
here=$(cd "$(dirname "$0")" && pwd)
cd /work/main || exit 1
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-0.exr --spp 128 --seed 1634845390 --width 8 --height 8 --max-depth 1 --variant llvm_ad_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-1.exr --spp 128 --seed 1243145237 --width 8 --height 8 --max-depth 1 --variant llvm_ad_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-2.exr --spp 128 --seed 883881742 --width 8 --height 8 --max-depth 1 --variant llvm_ad_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-3.exr --spp 128 --seed 430817361 --width 8 --height 8 --max-depth 1 --variant llvm_ad_spectral --threads 2
