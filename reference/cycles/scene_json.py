"""Shared by the scene-JSON drivers (reference/cycles/render.py, reference/luxcore/render.py):
reading and checking furnace's scene interchange JSON (docs/scene-json.md, version 1), the common
command line, small vector helpers, the camera frame, a tessellated sphere with its stated error,
a point-in-dielectric test and the sidecar. Pure Python (no numpy), so it runs inside Blender's
and LuxCore's interpreters alike.
"""

import argparse
import json
import math
import os
import platform
import sys

EXIT_INVALID = 2
EXIT_UNSUPPORTED = 3


class Invalid(Exception):
    """The input is malformed (exit 2)."""


class Unsupported(Exception):
    """The renderer cannot express this (exit 3, `unsupported: ...` on stderr)."""


def parser(description, default_subdiv):
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--scene", required=True, help="furnace scene interchange JSON (scene.json)")
    p.add_argument("--out", required=True, help="output EXR path (a sidecar <stem>.json is written beside it)")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    p.add_argument("--seed", type=int, default=0, help="sampler seed (default: 0)")
    p.add_argument("--width", type=int, help="pixels (default: the scene's)")
    p.add_argument("--height", type=int, help="pixels (default: the scene's)")
    p.add_argument("--max-depth", type=int, default=None,
                   help="maximum number of BOUNCES in furnace's convention (0 = emitters seen directly, "
                        "1 = direct light), -1 = unlimited (default: the scene's render.max_depth, null = unlimited)")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1, help="CPU threads (default: all)")
    p.add_argument("--sphere-subdiv", type=int, default=default_subdiv,
                   help="icosphere subdivision level where a sphere must be tessellated "
                        "(default: %(default)s; 20*4^level triangles)")
    return p


def vec(v, n, what):
    if (not isinstance(v, (list, tuple)) or len(v) != n
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
            or not all(math.isfinite(x) for x in v)):
        raise Invalid(f"{what}: expected {n} finite numbers, got {v!r}")
    return [float(x) for x in v]


def load_scene(path):
    try:
        with open(path) as f:
            s = json.load(f)
    except (OSError, ValueError) as e:
        raise Invalid(f"cannot read {path}: {e}")
    if not isinstance(s, dict) or s.get("format") != "furnace-scene-json":
        raise Invalid(f"{path}: format {s.get('format') if isinstance(s, dict) else None!r}, "
                      "expected \"furnace-scene-json\"")
    if s.get("version") != 1:
        raise Invalid(f"{path}: version {s.get('version')!r}; this driver reads version 1")
    for key in ("render", "camera", "materials", "shapes"):
        if key not in s:
            raise Invalid(f"{path}: missing key {key!r}")
    s.setdefault("lights", [])
    s.setdefault("media", [])
    nm, nmed = len(s["materials"]), len(s["media"])
    for i, sh in enumerate(s["shapes"]):
        if not (isinstance(sh.get("material"), int) and 0 <= sh["material"] < nm):
            raise Invalid(f"shape {i}: material {sh.get('material')!r} is not an index into materials (0..{nm - 1})")
        for side in ("interior", "exterior"):
            m = sh.get(side)
            if m is not None and not (isinstance(m, int) and 0 <= m < nmed):
                raise Invalid(f"shape {i}: {side} {m!r} is not an index into media (0..{nmed - 1})")
        if sh.get("type") == "mesh":
            pos = sh.get("positions", [])
            for t in sh.get("triangles", []):
                if len(t) != 3 or not all(isinstance(j, int) and 0 <= j < len(pos) for j in t):
                    raise Invalid(f"shape {i}: triangle {t!r} does not index positions (0..{len(pos) - 1})")
        elif sh.get("type") == "sphere":
            if not (isinstance(sh.get("radius"), (int, float)) and sh["radius"] > 0):
                raise Invalid(f"shape {i}: radius {sh.get('radius')!r} must be > 0")
    cm = s["camera"].get("medium")
    if cm is not None and not (isinstance(cm, int) and 0 <= cm < nmed):
        raise Invalid(f"camera.medium {cm!r} is not an index into media")
    return s


def resolve_render(args, s):
    """(width, height, spp, furnace depth with -1 = unlimited) from the CLI over the scene's."""
    rs = s["render"]
    width = args.width or rs.get("width")
    height = args.height or rs.get("height")
    spp = args.spp or rs.get("spp")
    if args.max_depth is not None:
        depth = args.max_depth
    else:
        depth = -1 if rs.get("max_depth") is None else int(rs["max_depth"])
    if depth < -1:
        depth = -1
    if not all(isinstance(v, int) and v >= 1 for v in (width, height, spp)):
        raise Invalid(f"width {width!r}, height {height!r}, spp {spp!r}: need positive integers")
    return width, height, spp, depth


def unsupported(msg):
    print(f"unsupported: {msg}", file=sys.stderr)
    return EXIT_UNSUPPORTED


def invalid(msg):
    print(f"invalid scene: {msg}", file=sys.stderr)
    return EXIT_INVALID


# --- vectors ----------------------------------------------------------------------------------

def sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def add(a, b):
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def scale(a, k):
    return [a[0] * k, a[1] * k, a[2] * k]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def normalize(a):
    n = math.sqrt(dot(a, a))
    if n == 0:
        raise Invalid(f"zero-length vector {a}")
    return [a[0] / n, a[1] / n, a[2] / n]


def camera_frame(cam):
    """(position, forward, right, up') of the scene JSON's pinhole: right = forward x up, so image
    x runs to the camera's right in a right-handed frame; up' = right x forward."""
    pos = vec(cam["position"], 3, "camera.position")
    fwd = normalize(sub(vec(cam["look_at"], 3, "camera.look_at"), pos))
    right = cross(fwd, vec(cam["up"], 3, "camera.up"))
    if dot(right, right) < 1e-24:
        raise Invalid("camera: up is parallel to the viewing direction")
    right = normalize(right)
    return pos, fwd, right, cross(right, fwd)


def scene_extent(s):
    pts = [s["camera"]["position"]]
    for sh in s["shapes"]:
        if sh["type"] == "mesh":
            pts += sh["positions"]
        else:
            c, r = sh["center"], sh["radius"]
            pts += [[c[0] - r, c[1] - r, c[2] - r], [c[0] + r, c[1] + r, c[2] + r]]
    pts += [l["position"] for l in s["lights"] if l["type"] == "point"]
    lo = [min(p[k] for p in pts) for k in range(3)]
    hi = [max(p[k] for p in pts) for k in range(3)]
    return max(max(h - l for h, l in zip(hi, lo)), 1e-30)


# --- tessellated sphere -------------------------------------------------------------------------

def icosphere(level):
    """Unit icosphere: 20 * 4^level faces, vertices on the unit sphere, every face wound so that
    (b - a) x (c - a) points outwards. Returns (vertices, faces, sagitta) where sagitta = 1 - the
    smallest distance of a face plane from the centre: the largest radial gap between the mesh and
    the sphere, relative to the radius (the mesh lies inside the sphere)."""
    t = (1 + math.sqrt(5)) / 2
    verts = [normalize(v) for v in [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                                    [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]]
    faces = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
             [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
             [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(level):
        cache = {}

        def mid(i, j):
            k = (min(i, j), max(i, j))
            if k not in cache:
                a, b = verts[i], verts[j]
                verts.append(normalize([(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2]))
                cache[k] = len(verts) - 1
            return cache[k]

        nf = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = nf
    sag = 0.0
    for a, b, c in faces:
        n = normalize(cross(sub(verts[b], verts[a]), sub(verts[c], verts[a])))
        if dot(n, verts[a]) <= 0:
            raise AssertionError("icosphere face wound inwards")
        sag = max(sag, 1 - dot(n, verts[a]))
    return verts, faces, sag


def tessellate_sphere(sh, level):
    """(positions, triangles, note) of a sphere shape as an icosphere, wound per flip_normals."""
    c, r = vec(sh["center"], 3, "center"), float(sh["radius"])
    verts, faces, sag = icosphere(level)
    pos = [[c[0] + r * v[0], c[1] + r * v[1], c[2] + r * v[2]] for v in verts]
    if sh.get("flip_normals"):
        faces = [[a, cc, b] for a, b, cc in faces]
    note = {"geometry": f"icosphere level {level}: {len(faces)} flat triangles with vertices on the sphere",
            "max_radial_deviation_relative": sag, "max_radial_deviation": sag * r}
    return pos, faces, note


# --- which side of a dielectric is a point on ---------------------------------------------------

_DIRS = (normalize([0.5377, 0.8147, -0.2163]), normalize([-0.4336, 0.3426, 0.8339]))


def _ray_triangle(o, d, a, b, c):
    e1, e2 = sub(b, a), sub(c, a)
    p = cross(d, e2)
    det = dot(e1, p)
    if abs(det) < 1e-300:
        return None
    inv = 1.0 / det
    tv = sub(o, a)
    u = dot(tv, p) * inv
    if u < 0 or u > 1:
        return None
    q = cross(tv, e1)
    v = dot(d, q) * inv
    if v < 0 or u + v > 1:
        return None
    t = dot(e2, q) * inv
    return t if t > 0 else None


def inside_dielectric(s, p):
    """Index of a dielectric shape whose inside (the side opposite its normal) holds point p, or
    None. Along two fixed directions the nearest dielectric surface is found; p is inside when
    that surface is met from its back (the ray leaves through it)."""
    for d in _DIRS:
        best = (math.inf, None, False)
        for i, sh in enumerate(s["shapes"]):
            if s["materials"][sh["material"]]["type"] != "dielectric":
                continue
            if sh["type"] == "sphere":
                c, r = sh["center"], sh["radius"]
                oc = sub(p, c)
                b = dot(oc, d)
                disc = b * b - (dot(oc, oc) - r * r)
                if disc < 0:
                    continue
                for t in (-b - math.sqrt(disc), -b + math.sqrt(disc)):
                    if t > 0:
                        n = sub(add(p, scale(d, t)), c)
                        back = (dot(n, d) > 0) != bool(sh.get("flip_normals"))
                        if t < best[0]:
                            best = (t, i, back)
                        break
            else:
                P = sh["positions"]
                for a, b, c in sh["triangles"]:
                    t = _ray_triangle(p, d, P[a], P[b], P[c])
                    if t is not None and t < best[0]:
                        n = cross(sub(P[b], P[a]), sub(P[c], P[a]))
                        best = (t, i, dot(n, d) > 0)
        if best[1] is not None and best[2]:
            return best[1]
    return None


def emitter_points(s):
    """A point just in front of each emitter (point lights, and one emitting face per shape)."""
    ext = scene_extent(s)
    eps = 1e-6 * ext
    out = []
    for i, l in enumerate(s["lights"]):
        if l["type"] == "point":
            out.append((f"point light {i}", l["position"]))
    for i, sh in enumerate(s["shapes"]):
        em = sh.get("emission")
        if em is None:
            continue
        if sh["type"] == "sphere":
            c, r = sh["center"], sh["radius"]
            k = (1 - 1e-6) if sh.get("flip_normals") else (1 + 1e-6)
            out.append((f"shape {i}", [c[0], c[1], c[2] + r * k]))
        elif sh["triangles"]:
            P = sh["positions"]
            a, b, c = (P[j] for j in sh["triangles"][0])
            n = normalize(cross(sub(b, a), sub(c, a)))
            g = [(a[k] + b[k] + c[k]) / 3 for k in range(3)]
            out.append((f"shape {i}", add(g, scale(n, eps))))
            if em.get("two_sided"):
                out.append((f"shape {i} (back)", add(g, scale(n, -eps))))
    return out


# --- sidecar ------------------------------------------------------------------------------------

def max_albedo(s):
    """Largest single-scattering albedo in the scene (1 where a mirror or glass is present): the
    radiance of paths longer than K bounces is at most a^(K+1)/(1-a) x the largest radiance a
    path can pick up after one bounce, for energy-conserving scattering."""
    a = 0.0
    for m in s["materials"]:
        if m["type"] == "diffuse":
            a = max(a, *m["rgb"])
        elif m["type"] in ("conductor", "dielectric"):
            a = 1.0
    for md in s["media"]:
        for sa, ss in zip(md["sigma_a_rgb"], md["sigma_s_rgb"]):
            if sa + ss > 0:
                a = max(a, ss / (sa + ss))
    return a


def truncation(s, bounces):
    """What ending every path after `bounces` bounces can lose: the scene's largest albedo a and
    the bound a^(K+1)/(1-a) on the missing tail relative to the radiance a path picks up after
    one bounce (None when a = 1: a mirror, glass or white surface has no such bound)."""
    a = max_albedo(s)
    return {"bounces": bounces, "max_albedo": a,
            "tail_bound_relative": (a ** (bounces + 1) / (1 - a)) if a < 1 else None}


def write_sidecar(stem, data):
    data = dict(data)
    data.setdefault("python", platform.python_version())
    data.setdefault("platform", platform.platform())
    with open(stem + ".json", "w") as f:
        json.dump(data, f, indent=2)
        f.write("\n")


def out_paths(out):
    out = os.path.abspath(out)
    stem = out[:-4] if out.lower().endswith(".exr") else out
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    return out, stem
