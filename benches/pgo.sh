#!/usr/bin/env bash
# A profile-guided (PGO) build of furnace, for this machine's CPU: an instrumented build runs a
# training workload, LLVM merges the counts, and a second build optimises with them (code
# layout and branch order from measured frequencies). Images are bit-identical to the default
# build's (PGO changes no arithmetic); measured gains are in docs/performance.md, "A
# profile-guided build". Opt-in: `cargo build --release` stays the default build.
#
#   benches/pgo.sh                 # writes target/pgo/release/furnace
#   TRAIN=renders benches/pgo.sh   # train on the benchmark renders only (no default suite)
#
# Training: the measured Cornell Box, the glossy box and (when Python can write it) the
# 10^5-triangle mesh box at 128x128, unlimited depth and 5 bounces, then the default suite
# (`furnace check`, every integrator). Needs llvm-profdata of the toolchain's own LLVM:
# `rustup component add llvm-tools`. About 6 minutes on a 2-core machine.
set -euo pipefail
cd "$(dirname "$0")/.."
train=${TRAIN:-all}
case $train in all | renders) ;; *) echo "pgo.sh: TRAIN must be 'all' or 'renders'" >&2; exit 2 ;; esac
host=$(rustc -vV | sed -n 's/^host: //p')
profdata=$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata
[ -x "$profdata" ] || {
    echo "pgo.sh: $profdata not found; install it with: rustup component add llvm-tools" >&2
    exit 2
}
# RUSTFLAGS replaces .cargo/config.toml's flags, so the CPU target is repeated here.
base=${RUSTFLAGS:--C target-cpu=native -C target-feature=-avx512f}
# the sources the two builds compile: a profile trained on one tree and used on another
# loses every changed function's counts (rustc's hash-mismatch warnings), so an edit while
# this runs stops it instead of writing a build that is not the tree's profile-guided one
sources() { find src Cargo.toml Cargo.lock .cargo -type f -print0 | sort -z | xargs -0 cksum | cksum; }
before=$(sources)
raw=$PWD/target/pgo-data
rm -rf "$raw"
mkdir -p "$raw"
RUSTFLAGS="$base -Cprofile-generate=$raw" cargo build --release --target-dir target/pgo-generate
bin=target/pgo-generate/release/furnace
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenes=(scenes/cornell-box.toml scenes/cornell-glossy.toml)
python3 benches/cornell-mesh/make.py >/dev/null 2>&1 && scenes+=(benches/cornell-mesh/scene.toml) ||
    echo "pgo.sh: no mesh scene (benches/cornell-mesh/make.py needs python3); training without it" >&2
for s in "${scenes[@]}"; do
    "$bin" render "$s" --width 128 --height 128 --spp 32 --quiet --out "$tmp/a.exr"
    "$bin" render "$s" --width 128 --height 128 --spp 16 --max-depth 5 --quiet --out "$tmp/b.exr"
done
[ "$train" = all ] && "$bin" check -q
"$profdata" merge -o "$raw/merged.profdata" "$raw"
# named by its content: cargo rebuilds when its flags change, not when a file they name does,
# so a new profile under the old name would leave the dependencies built with the old one
sum=$(cksum <"$raw/merged.profdata" | cut -d' ' -f1)
mv "$raw/merged.profdata" "$raw/merged-$sum.profdata"
if [ "$(sources)" != "$before" ]; then
    echo "pgo.sh: the sources changed during training (src/, Cargo.toml, Cargo.lock or .cargo/); run it again on a tree that stays put" >&2
    exit 1
fi
RUSTFLAGS="$base -Cprofile-use=$raw/merged-$sum.profdata" cargo build --release --target-dir target/pgo
if [ "$(sources)" != "$before" ]; then
    rm -f target/pgo/release/furnace
    echo "pgo.sh: the sources changed during the profile-guided build; removed it, run again on a tree that stays put" >&2
    exit 1
fi
echo "pgo.sh: wrote target/pgo/release/furnace (trained on: $train)"
