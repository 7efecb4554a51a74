#!/bin/sh
# The model protocol's overhead: the chi2 check of tests/manifests/bsdf.toml (the kind that asks
# the most queries) in process, through the stand-in server (`furnace serve-models`, the same
# models over the protocol), and through each Mitsuba 3 variant given as an argument.
# The difference between the first two is the protocol's cost; the server lines give queries/s.
#
#   cargo build --release && benches/model-protocol.sh [mitsuba3:llvm_ad_spectral ...]
#
# Mitsuba needs its venv on PATH (README, "Other renderers"). Runs are interleaved, ROUNDS rounds (default 3).
set -eu
cd "$(dirname "$0")/.."
bin=target/release/furnace
[ -x "$bin" ] || { echo "build first: cargo build --release" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc) threads"
printf '%-28s %5s %10s %12s %s\n' renderer round check_s samples server
for round in $(seq "${ROUNDS:-3}"); do
    for r in furnace furnace-models "$@"; do
        "$bin" check tests/manifests/bsdf.toml --filter 'chi2*' --renderer "$r" \
            --json "$tmp/out.json" >"$tmp/out.txt" 2>&1 || true
        secs=$(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print([o['seconds'] for o in d['outcomes'] if o['name'].startswith('chi2')][0])" "$tmp/out.json" 2>/dev/null || echo '?')
        n=$(python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print([o['samples'] for o in d['outcomes'] if o['name'].startswith('chi2')][0])" "$tmp/out.json" 2>/dev/null || echo '?')
        server=$(grep '^model server:' "$tmp/out.txt" | sed 's/^model server: //' || true)
        printf '%-28s %5s %10s %12s %s\n' "$r" "$round" "$secs" "$n" "${server:--}"
    done
done
