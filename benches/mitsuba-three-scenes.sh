#!/usr/bin/env bash
# furnace against Mitsuba 3's llvm_ad_spectral on three scenes, paired in one run each
# (reference/mitsuba/bench.py alternates the renderers within every repetition): the measured
# Cornell Box and the glossy box at 128², unlimited depth, against their committed 4096-spp
# references (time to equal error), and at 256², 5 bounces, the Cornell Box and the Cornell Box
# with a sphere of 101 888 triangles (speed only: no reference at that size and depth). Each
# JSON records the CPU it ran on.
#
#   VENV=/path/to/mitsuba-venv REPS=9 benches/mitsuba-three-scenes.sh reports/bench-mitsuba-three
#
# With PGO=1, benches/pgo.sh's profile-guided build (built first when missing) goes first and
# the default build runs beside it as furnace:default, so both compare with Mitsuba in one run.
# With LLVM_AVX2=1, Mitsuba's LLVM variant also runs with its JIT limited to AVX2 (bench.py
# --llvm-avx2): on a CPU with AVX-512, the same core with only Mitsuba's vector width changed.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?output prefix, e.g. reports/bench-mitsuba-three}
reps=${REPS:-9}
export PATH=${VENV:+$VENV/bin:}$PATH
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1}
[ -x target/release/furnace ] || cargo build --release
builds=()
if [ "${PGO:-0}" = 1 ]; then
    [ -x target/pgo/release/furnace ] || benches/pgo.sh
    builds=(--furnace target/pgo/release/furnace --furnace-label furnace:pgo
        --furnace-also furnace:default=target/release/furnace)
fi
python3 benches/cornell-mesh/make.py
if [ "${LLVM_AVX2:-0}" = 1 ]; then builds+=(--llvm-avx2); fi
bench() { python3 reference/mitsuba/bench.py --reps "$reps" --variants llvm_ad_spectral "${builds[@]}" "$@"; }
bench --spp 256 --json "$out-cornell.json"
bench --spp 256 --scene scenes/cornell-glossy.toml --reference reference/mitsuba/cornell-glossy.exr \
    --json "$out-glossy.json"
bench --spp 64 --reference none --size 256x256 --max-depth 5 --json "$out-cornell-256.json"
bench --spp 64 --reference none --size 256x256 --max-depth 5 --scene benches/cornell-mesh/scene.toml \
    --json "$out-mesh-256.json"
