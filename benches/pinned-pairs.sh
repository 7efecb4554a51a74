#!/usr/bin/env bash
# Two furnace builds rendering the same scene at the same time, pinned to CPUs 0 and 1 and
# swapped each round: on a noisy 2-vCPU VM both runs of a round see the same host, so their
# ratio spreads far less than that of runs one after the other. Prints each round's whole-process
# times and B/A (after the CPU and both builds' `furnace --version`), then the geometric mean
# of B/A with its 95 % t interval; the two images are compared bit for bit. Needs taskset
# (util-linux) and at least 2 CPUs; runs of a few seconds each resolve a few per cent.
#
#   benches/pinned-pairs.sh A B SCENE ROUNDS [render options...]
#   benches/pinned-pairs.sh /tmp/furnace-before target/release/furnace scenes/cornell-box.toml 10 \
#       --width 256 --height 256 --spp 32 --max-depth 5
set -euo pipefail
[ $# -ge 4 ] || { sed -n 2,11p "$0"; exit 2; }
a=$1 b=$2 scene=$3 rounds=$4
shift 4
command -v taskset >/dev/null || { echo "pinned-pairs.sh: taskset is not installed" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
. "$(dirname "$0")/same-image.sh"
run() { # binary cpu tag
    local s e
    s=$(date +%s.%N)
    taskset -c "$2" "$1" render "$scene" --threads 1 --quiet --out "$tmp/$3.exr" "${@:4}"
    e=$(date +%s.%N)
    echo "$s $e" >"$tmp/$3.t"
}
# the machine and the builds, so that the figures below can be quoted with them
cpu=$(awk -F': ' '/^model name/ {m = $2} /^cpu family/ {f = $2} /^model\t/ {n = $2}
    /^$/ {exit} END {printf "%s (family %s model %s)", m, f, n}' /proc/cpuinfo 2>/dev/null || true)
echo "CPU: ${cpu:-unknown}, $(nproc) logical CPUs"
echo "A: $a: $("$a" --version 2>/dev/null || echo '?')"
echo "B: $b: $("$b" --version 2>/dev/null || echo '?')"
echo "round A_seconds B_seconds B/A"
for i in $(seq "$rounds"); do
    ca=$(((i + 1) % 2)) cb=$((i % 2))
    run "$a" "$ca" a "$@" &
    run "$b" "$cb" b "$@" &
    wait
    ta=$(awk '{print $2 - $1}' "$tmp/a.t")
    tb=$(awk '{print $2 - $1}' "$tmp/b.t")
    echo "$i $ta $tb $(awk -v a="$ta" -v b="$tb" 'BEGIN {printf "%.4f", b / a}')"
done | tee "$tmp/rounds"
echo "images: $(same_image "$a" "$tmp/a.exr" "$tmp/b.exr")"
# geometric mean of B/A and a 95 % t interval on the log ratios (t quantiles for 1-30 dof)
awk '{l = log($4); n++; s += l; q += l * l}
    END {
        split("12.706 4.303 3.182 2.776 2.571 2.447 2.365 2.306 2.262 2.228 2.201 2.179 2.160 2.145 2.131 2.120 2.110 2.101 2.093 2.086 2.080 2.074 2.069 2.064 2.060 2.056 2.052 2.048 2.045 2.042", t, " ")
        if (n < 2) { print "B/A: one round, no interval"; exit }
        m = s / n; sd = sqrt((q - n * m * m) / (n - 1)); h = t[n - 1 > 30 ? 30 : n - 1] * sd / sqrt(n)
        printf "B/A: geometric mean %.3f, 95 %% %.3f-%.3f over %d rounds\n", exp(m), exp(m - h), exp(m + h), n
    }' "$tmp/rounds"
