#!/bin/sh
# The README's sharded render workflow, run on one machine: N part jobs (one after another),
# then the merge job, which writes the EXR and PNG the whole render would. Exit code: the
# merge's (0 written, 1 written with non-finite pixels or cut paths, 2 the parts do not make
# one render).
#
#   cargo build --release && docs/ci/films-locally.sh N SCENE [render options...]
# FURNACE (the binary) and OUT (the folder, emptied first) override the defaults.
set -eu
cd "$(dirname "$0")/../.."
n=$1
scene=$2
shift 2
bin=${FURNACE:-target/release/furnace}
out=${OUT:-out/films}
rm -rf "$out" && mkdir -p "$out"
k=1
while [ "$k" -le "$n" ]; do
    "$bin" render "$scene" -q --shard "$k/$n" -o "$out/part-$k.film" "$@"
    k=$((k + 1))
done
"$bin" merge-films "$out"/part-*.film -o "$out/image.exr"
