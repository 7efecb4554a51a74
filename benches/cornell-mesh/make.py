#!/usr/bin/env python3
"""Writes the benchmark scene with more geometry: the measured Cornell Box plus a UV sphere of
about 10^5 triangles (radius 80 mm, centre (278, 400, 150) mm: above the short block, in front
of the tall one), white like the blocks. Deterministic; the files are generated, not committed:

    python3 benches/cornell-mesh/make.py            # writes benches/cornell-mesh/{scene.toml,sphere.obj}
    python3 reference/mitsuba/bench.py --scene benches/cornell-mesh/scene.toml --reference none ...
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
SEGMENTS, RINGS = 256, 200          # 2 * 256 * 199 = 101 888 triangles
RADIUS, CENTRE = 80.0, (278.0, 400.0, 150.0)


def sphere_obj():
    lines = [f"# UV sphere, {SEGMENTS} segments x {RINGS} rings, radius {RADIUS} mm (benches/cornell-mesh/make.py)"]
    lines.append(f"v {CENTRE[0]} {CENTRE[1] + RADIUS} {CENTRE[2]}")
    for r in range(1, RINGS):
        theta = math.pi * r / RINGS
        for s in range(SEGMENTS):
            phi = 2 * math.pi * s / SEGMENTS
            x = CENTRE[0] + RADIUS * math.sin(theta) * math.cos(phi)
            y = CENTRE[1] + RADIUS * math.cos(theta)
            z = CENTRE[2] + RADIUS * math.sin(theta) * math.sin(phi)
            lines.append(f"v {x:.6f} {y:.6f} {z:.6f}")
    lines.append(f"v {CENTRE[0]} {CENTRE[1] - RADIUS} {CENTRE[2]}")
    bottom = 2 + (RINGS - 1) * SEGMENTS  # 1-based index of the last vertex
    ring = lambda r, s: 2 + (r - 1) * SEGMENTS + (s % SEGMENTS)  # 1-based
    faces = 0
    for s in range(SEGMENTS):  # outward windings (counter-clockwise seen from outside)
        lines.append(f"f 1 {ring(1, s + 1)} {ring(1, s)}")
        faces += 1
    for r in range(1, RINGS - 1):
        for s in range(SEGMENTS):
            a, b, c, d = ring(r, s), ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s)
            lines.append(f"f {a} {b} {c}")
            lines.append(f"f {a} {c} {d}")
            faces += 2
    for s in range(SEGMENTS):
        lines.append(f"f {bottom} {ring(RINGS - 1, s)} {ring(RINGS - 1, s + 1)}")
        faces += 1
    return "\n".join(lines) + "\n", faces


def main():
    obj, faces = sphere_obj()
    with open(os.path.join(HERE, "sphere.obj"), "w") as f:
        f.write(obj)
    with open(os.path.join(REPO, "scenes", "cornell-box.toml")) as f:
        box = f.read()
    # the box's spectra are CSV files relative to scenes/; this scene sits two levels down
    box = box.replace('csv = "../', 'csv = "../../')
    scene = box + f"""
[[shape]]                 # benches/cornell-mesh/make.py: a UV sphere of {faces} triangles
type = "mesh"
file = "sphere.obj"
material = "white"
"""
    with open(os.path.join(HERE, "scene.toml"), "w") as f:
        f.write(scene)
    print(f"wrote {HERE}/scene.toml and sphere.obj ({faces} triangles)")


if __name__ == "__main__":
    main()
