#!/bin/sh
# mitsuba3:llvm_ad_spectral as furnace ran it: 4 independent runs of 4194304 spp, 1x1 px; each writes batch-B.exr here.
here=$(cd "$(dirname "$0")" && pwd)
cd /work/main || exit 1
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-0.exr --spp 4194304 --seed 1780008781 --width 1 --height 1 --max-depth 0 --variant llvm_ad_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-1.exr --spp 4194304 --seed 901134865 --width 1 --height 1 --max-depth 0 --variant llvm_ad_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-2.exr --spp 4194304 --seed 263068521 --width 1 --height 1 --max-depth 0 --variant llvm_ad_spectral --threads 2
env -i PATH="$PATH" HOME="$HOME" LANG="$LANG" TMPDIR="$TMPDIR" DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 reference/mitsuba/render.py --xml "$here"/scene.xml --out "$here"/batch-3.exr --spp 4194304 --seed 1284965743 --width 1 --height 1 --max-depth 0 --variant llvm_ad_spectral --threads 2
