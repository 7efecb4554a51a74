#!/usr/bin/env python3
"""Writes icosphere-5120.ply: a closed, watertight triangle mesh approximating the unit sphere,
for the tessellated furnace enclosure (tests/manifests/scenes/furnace-tessellated.toml).

Authored by the furnace project (no data from elsewhere): the regular icosahedron (vertices at
the cyclic permutations of (0, +-1, +-phi)) subdivided 4 times, each edge split at its midpoint
once (shared by index, so neighbouring triangles meet exactly) and every vertex pushed onto the
unit sphere: 2562 vertices, 5120 triangles. Faces are wound so that the geometric normal
(v1 - v0) x (v2 - v0) points into the sphere, towards the camera inside. Binary little-endian
PLY, float32 positions. Run `python3 make_icosphere.py` here to regenerate it bit for bit.
"""
import math
import struct

phi = (1 + 5 ** 0.5) / 2
verts = [(-1, phi, 0), (1, phi, 0), (-1, -phi, 0), (1, -phi, 0),
         (0, -1, phi), (0, 1, phi), (0, -1, -phi), (0, 1, -phi),
         (phi, 0, -1), (phi, 0, 1), (-phi, 0, -1), (-phi, 0, 1)]
# outward-wound faces of the icosahedron
faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
         (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
         (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
         (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


verts = [unit(v) for v in verts]
for _ in range(4):
    cache = {}

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in cache:
            va, vb = verts[a], verts[b]
            verts.append(unit(tuple((x + y) / 2 for x, y in zip(va, vb))))
            cache[key] = len(verts) - 1
        return cache[key]

    new = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    faces = new


def outward(f):
    a, b, c = (verts[i] for i in f)
    e1 = [b[k] - a[k] for k in range(3)]
    e2 = [c[k] - a[k] for k in range(3)]
    n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    return sum(n[k] * a[k] for k in range(3)) > 0


assert all(outward(f) for f in faces)
faces = [(a, c, b) for a, b, c in faces]  # inward
assert len(verts) == 2562 and len(faces) == 5120

header = ("ply\nformat binary_little_endian 1.0\n"
          "comment icosphere-5120: the unit sphere, icosahedron subdivided 4 times, faces wound inward (furnace)\n"
          f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
          f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
with open("icosphere-5120.ply", "wb") as out:
    out.write(header.encode())
    for v in verts:
        out.write(struct.pack("<3f", *v))
    for f in faces:
        out.write(struct.pack("<B3i", 3, *f))
