#!/usr/bin/env bash
# Peak resident memory and wall time of `furnace` on each class of hostile input
# (docs/hostile-input.md). Usage: benches/hostile-rss.sh [path/to/furnace]
# Needs GNU time at /usr/bin/time. Prints one tab-separated line per class:
# class, exit code, peak RSS (MiB), wall seconds.
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$root/target/release/furnace}
[ -x "$bin" ] || { echo "build first: cargo build --release ($bin not found)" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

scene() { # scene SPP SHAPE-LINES
  cat <<EOF
[render]
width = 8
height = 8
spp = $1
[camera]
position = [0.0, 0.0, -3.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 40.0
[materials.m]
type = "diffuse"
reflectance = 0.5
[[shape]]
$2
material = "m"
[[light]]
type = "environment"
radiance = 1.0
EOF
}
sphere='type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0'

measure() { # measure CLASS ARGS...
  local class=$1; shift
  /usr/bin/time -f "%x %M %e" -o time.txt "$bin" "$@" >/dev/null 2>&1
  read -r code kib secs < <(tail -1 time.txt)
  printf '%s\t%s\t%.1f\t%s\n' "$class" "$code" "$(echo "$kib / 1024" | bc -l)" "$secs"
}

printf 'class\texit\tpeak_MiB\twall_s\n'

scene 4 "$sphere" > ok.toml
measure "baseline: 8x8 sphere, 4 spp" render ok.toml -o ok.exr -q

scene 1099511627776 "$sphere" > spp.toml
measure "spp = 2^40" render spp.toml -o o.exr -q
measure "--width 1e9" render ok.toml -o o.exr -q --width 1000000000
measure "65536 x 65536 image" render ok.toml -o o.exr -q --width 65536 --height 65536

head -c 17000000 /dev/zero | tr '\0' '#' > big.toml
measure "17 MB scene file" render big.toml -o o.exr -q

scene 4 'type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1e308' > huge.toml
measure "sphere radius 1e308" render huge.toml -o o.exr -q

mkfifo fifo.obj
scene 4 'type = "mesh"
file = "fifo.obj"' > fifo.toml
measure "mesh file is a FIFO" render fifo.toml -o o.exr -q
scene 4 'type = "mesh"
file = "/dev/zero"' > zero.toml
measure "mesh file is /dev/zero" render zero.toml -o o.exr -q

printf 'v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n' > flat.obj
scene 4 'type = "mesh"
file = "flat.obj"' > flat.toml
measure "only degenerate triangles" render flat.toml -o o.exr -q

for n in 20000 200000; do
  awk -v n=$n 'BEGIN { for (i = 0; i < n; i++) print "v 0 0 0\nv 1 0 0\nv 0 1 0";
                       for (i = 0; i < n; i++) printf "f %d %d %d\n", 3*i+1, 3*i+2, 3*i+3 }' > same$n.obj
  scene 2 "type = \"mesh\"
file = \"same$n.obj\"" > same$n.toml
  measure "$n coincident triangles (renders)" render same$n.toml -o o.exr -q
done

# a grid of 1000 x 1000 quads: 2 million triangles that pair (a quad's halves share an edge)
awk 'BEGIN { n = 1000; for (j = 0; j <= n; j++) for (i = 0; i <= n; i++) printf "v %g %g 0\n", i / n, j / n;
             for (j = 0; j < n; j++) for (i = 0; i < n; i++) { a = j * (n + 1) + i + 1;
               printf "f %d %d %d\nf %d %d %d\n", a, a + 1, a + n + 2, a, a + n + 2, a + n + 1 } }' > grid.obj
scene 1 'type = "mesh"
file = "grid.obj"' > grid.toml
measure "2 million triangles, a grid of quads (renders)" render grid.toml -o o.exr -q

measure "EXR declaring 100000^2 pixels" compare "$root/tests/fuzz/corpus/exr/huge-window.exr" "$root/tests/fuzz/corpus/exr/tiny.exr"
