# Sourced by benches/pinned-pairs.sh and benches/instructions.sh: compares two builds' images.
# "identical" when the two EXRs are the same bytes; "same R, G, B" when only the files differ
# (builds either side of 9e36fd0 write ZIP and RLE compression), by `furnace compare`'s RMSE
same_image() { # binary a.exr b.exr
    if cmp -s "$2" "$3"; then
        echo identical
    elif "$1" compare "$2" "$3" 2>/dev/null |
        awk '$1 ~ /^[RGB]$/ && NF == 6 {n++; if ($4 != "0.0000e0") d = 1} END {exit !(n == 3 && !d)}'; then
        echo "same R, G, B"
    else
        echo differ
    fi
}
