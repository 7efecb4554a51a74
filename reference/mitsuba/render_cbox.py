#!/usr/bin/env python3
"""Render a furnace TOML scene (default: scenes/cornell-box.toml) with Mitsuba 3.

Reference images and timings for furnace. The Mitsuba scene is built as a Python dict directly
from the furnace scene file (no Mitsuba XML involved), so both renderers see the same geometry,
spectra and camera:

* spectra stay spectra: constants -> 'uniform'; inline tables and CSV columns -> 'irregular'
  (piecewise linear, zero outside the table = furnace's outside = "zero"; outside = "clamp" is
  emulated by extending the table with its end values to 360 and 830 nm, Mitsuba's wavelength
  sampling range); blackbody -> 'blackbody' (or, with a scale, a 1 nm table of Planck's law);
* diffuse materials -> 'diffuse' wrapped in 'twosided' (furnace's diffuse is two-sided,
  Mitsuba's is one-sided);
* shapes with `emission` -> an 'area' emitter (one-sided, on the side of the normal, like furnace);
* triangles / quads -> a binary PLY written to a temporary directory (face_normals = true:
  flat shading, as furnace; Mitsuba would otherwise smooth normals across the two triangles of a
  quad, which matters for the non-planar red wall); spheres -> 'sphere'; mesh files -> 'obj' /
  'ply' with face_normals = true;
* point lights -> 'point'; environment -> 'constant';
* pinhole camera -> 'perspective' with the vertical field of view (fov_axis = "y") computed from
  focal_length / film_size or taken from `fov`; reconstruction filter from [render].filter
  ('box', or Mitsuba's default 'gaussian', stddev 0.5 px); 'independent' sampler;
* integrator 'path' with max_depth = furnace bounces + 1 (-1 = unlimited).

Writes <out> (linear sRGB/Rec.709 EXR: the film's native output in spectral variants), <out
without .exr>_xyz.exr (CIE XYZ, converted from the same film by Mitsuba's Bitmap.convert) and
<out without .exr>.json (run metadata), and prints samples/second.

Example (tiny smoke test):
    python3 reference/mitsuba/render_cbox.py --width 32 --height 32 --spp 4 --out /tmp/cbox.exr
"""

import argparse
import csv
import json
import math
import os
import platform
import struct
import sys
import tempfile
import time
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
DEFAULT_SCENE = os.path.join(REPO, "scenes", "cornell-box.toml")

# Mitsuba samples wavelengths in [360, 830] nm in its spectral variants.
MI_WAVELENGTH_MIN = 360.0
MI_WAVELENGTH_MAX = 830.0


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scene", default=DEFAULT_SCENE, help="furnace TOML scene (default: %(default)s)")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's [render].spp)")
    p.add_argument("--width", type=int, help="pixels (default: [render].width)")
    p.add_argument("--height", type=int, help="pixels (default: [render].height)")
    p.add_argument("--seed", type=int, default=0, help="sampler seed (default: 0)")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                   help="CPU threads incl. the main thread (default: all cores, %(default)s)")
    p.add_argument("--max-depth", type=int, default=None,
                   help="maximum number of BOUNCES in furnace's convention; Mitsuba gets this + 1; "
                        "-1 = unlimited (default: [render].max_depth, absent = unlimited)")
    p.add_argument("--variant", default="scalar_spectral", help="Mitsuba variant (default: %(default)s)")
    p.add_argument("--out", default="cbox_mitsuba.exr", help="output EXR path (default: %(default)s)")
    p.add_argument("--batches", type=int, default=1,
                   help="render K independent batches of spp/K (seeds seed..seed+K-1) and write their "
                        "mean with variance.R/G/B = the variance of that mean (sample variance / K), so "
                        "furnace compare can weigh the reference's own noise; K >= 2 needs numpy "
                        "(default: %(default)s)")
    return p.parse_args(argv)


# ------------------------------------------------------------------------------------------------
# Spectra


def read_csv_column(path, column):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = [h.strip() for h in rows[0]]
    if header[0] != "wavelength_nm":
        raise ValueError(f"{path}: first column must be wavelength_nm, found {header[0]!r}")
    if column not in header[1:]:
        raise ValueError(f"{path}: no column {column!r}; columns are {header[1:]}")
    j = header.index(column)
    wl, val = [], []
    for r in rows[1:]:
        if not r or not r[0].strip():
            continue
        wl.append(float(r[0]))
        val.append(float(r[j]))
    return wl, val


def planck_nm(wavelength_nm, temperature):
    """Planck spectral radiance, W sr^-1 m^-2 nm^-1 (CODATA 2018 constants)."""
    h, c, k = 6.62607015e-34, 299792458.0, 1.380649e-23
    lam = wavelength_nm * 1e-9
    return 2.0 * h * c * c / lam**5 / math.expm1(h * c / (lam * k * temperature)) * 1e-9


def irregular(wl, val):
    return {
        "type": "irregular",
        "wavelengths": ", ".join(repr(float(w)) for w in wl),
        "values": ", ".join(repr(float(v)) for v in val),
    }


def to_mitsuba_spectrum(value, named, base_dir, where):
    """furnace spectrum value -> Mitsuba spectrum dict (never RGB)."""
    if isinstance(value, bool):
        raise ValueError(f"{where}: a spectrum cannot be a boolean")
    if isinstance(value, (int, float)):
        return {"type": "uniform", "value": float(value)}
    if isinstance(value, str):
        if value not in named:
            raise ValueError(f"{where}: unknown spectrum name {value!r}")
        return to_mitsuba_spectrum(named[value], named, base_dir, f"spectra.{value}")
    if not isinstance(value, dict):
        raise ValueError(f"{where}: unsupported spectrum {value!r}")
    scale = float(value.get("scale", 1.0))
    outside = value.get("outside", "zero")
    if outside not in ("zero", "clamp"):
        raise ValueError(f"{where}: outside must be 'zero' or 'clamp', got {outside!r}")
    if "blackbody" in value:
        t = float(value["blackbody"])
        if scale == 1.0:
            return {"type": "blackbody", "temperature": t}
        wl = [MI_WAVELENGTH_MIN + i for i in range(int(MI_WAVELENGTH_MAX - MI_WAVELENGTH_MIN) + 1)]
        return irregular(wl, [scale * planck_nm(w, t) for w in wl])
    if "csv" in value:
        wl, val = read_csv_column(os.path.join(base_dir, value["csv"]), value["column"])
    elif "wavelengths" in value:
        wl, val = list(map(float, value["wavelengths"])), list(map(float, value["values"]))
    else:
        raise ValueError(f"{where}: unsupported spectrum table {value!r}")
    if len(wl) != len(val) or len(wl) < 2 or any(b <= a for a, b in zip(wl, wl[1:])):
        raise ValueError(f"{where}: need >= 2 strictly increasing wavelengths with one value each")
    val = [scale * v for v in val]
    if outside == "clamp":  # Mitsuba's 'irregular' is zero outside; hold the end values instead
        if wl[0] > MI_WAVELENGTH_MIN:
            wl, val = [MI_WAVELENGTH_MIN] + wl, [val[0]] + val
        if wl[-1] < MI_WAVELENGTH_MAX:
            wl, val = wl + [MI_WAVELENGTH_MAX], val + [val[-1]]
    return irregular(wl, val)


# ------------------------------------------------------------------------------------------------
# Geometry


def write_ply(path, vertices, triangles):
    """Binary little-endian PLY with float32 positions and int32 triangle indices."""
    with open(path, "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\n"
                 f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
                 f"element face {len(triangles)}\nproperty list uchar int vertex_indices\n"
                 "end_header\n").encode("ascii"))
        for v in vertices:
            f.write(struct.pack("<3f", *map(float, v)))
        for t in triangles:
            if any(not 0 <= i < len(vertices) for i in t):
                raise ValueError(f"{path}: triangle index out of range in {t}")
            f.write(struct.pack("<B3i", 3, *map(int, t)))


def add3(a, b):
    return [x + y for x, y in zip(a, b)]


def build_scene_dict(scene_path, args, tmpdir, mi):
    with open(scene_path, "rb") as f:
        s = tomllib.load(f)
    base = os.path.dirname(os.path.abspath(scene_path))
    render = s.get("render", {})
    width = args.width or render.get("width", 256)
    height = args.height or render.get("height", 256)
    spp = args.spp or render.get("spp", 64)
    if args.max_depth is not None:
        bounces = args.max_depth
    else:
        bounces = render.get("max_depth", -1)
    max_depth_mitsuba = -1 if bounces < 0 else bounces + 1
    rfilter = render.get("filter", "box")
    if rfilter not in ("box", "gaussian"):
        raise ValueError(f"[render].filter must be 'box' or 'gaussian', got {rfilter!r}")

    named = s.get("spectra", {})
    bsdfs = {}
    for name, m in s.get("materials", {}).items():
        if m.get("type") != "diffuse":
            raise ValueError(f"materials.{name}: only type = 'diffuse' is supported here")
        bsdfs[name] = {
            "type": "twosided",
            "bsdf": {"type": "diffuse",
                     "reflectance": to_mitsuba_spectrum(m["reflectance"], named, base, f"materials.{name}.reflectance")},
        }

    d = {"type": "scene"}
    points = []  # for the clip range
    for i, sh in enumerate(s.get("shape", [])):
        kind = sh["type"]
        where = f"shape[{i}] ({kind})"
        flip = bool(sh.get("flip_normals", False))
        if kind in ("triangles", "quad"):
            if kind == "triangles":
                verts, tris = sh["vertices"], sh["indices"]
            else:
                c, u, v = sh["corner"], sh["edge_u"], sh["edge_v"]
                verts = [c, add3(c, u), add3(add3(c, u), v), add3(c, v)]
                tris = [[0, 1, 2], [0, 2, 3]]  # normal = edge_u x edge_v
            ply = os.path.join(tmpdir, f"shape{i}.ply")
            write_ply(ply, verts, tris)
            md = {"type": "ply", "filename": ply, "face_normals": True, "flip_normals": flip}
            points += verts
        elif kind == "sphere":
            md = {"type": "sphere", "center": list(map(float, sh["center"])),
                  "radius": float(sh["radius"]), "flip_normals": flip}
            r = float(sh["radius"])
            points += [add3(sh["center"], [r, r, r]), add3(sh["center"], [-r, -r, -r])]
        elif kind == "mesh":
            fn = os.path.join(base, sh["file"])
            ext = os.path.splitext(fn)[1].lower()
            if ext not in (".obj", ".ply"):
                raise ValueError(f"{where}: mesh file must be .obj or .ply, got {fn}")
            md = {"type": ext[1:], "filename": fn, "face_normals": True, "flip_normals": flip}
        else:
            raise ValueError(f"{where}: unknown shape type")
        if sh["material"] not in bsdfs:
            raise ValueError(f"{where}: unknown material {sh['material']!r}")
        md["bsdf"] = bsdfs[sh["material"]]
        if "emission" in sh:
            if sh.get("two_sided", False):
                raise ValueError(f"{where}: two_sided emission has no one-shape equivalent in Mitsuba")
            md["emitter"] = {"type": "area",
                             "radiance": to_mitsuba_spectrum(sh["emission"], named, base, f"{where}.emission")}
        d[f"shape_{i:03d}"] = md

    for i, li in enumerate(s.get("light", [])):
        if li["type"] == "point":
            d[f"light_{i:03d}"] = {"type": "point", "position": list(map(float, li["position"])),
                                   "intensity": to_mitsuba_spectrum(li["intensity"], named, base, f"light[{i}].intensity")}
            points.append(li["position"])
        elif li["type"] == "environment":
            d[f"light_{i:03d}"] = {"type": "constant",
                                   "radiance": to_mitsuba_spectrum(li["radiance"], named, base, f"light[{i}].radiance")}
        else:
            raise ValueError(f"light[{i}]: unknown light type {li['type']!r}")

    cam = s["camera"]
    if "fov" in cam:
        fov = float(cam["fov"])
    else:  # vertical field of view of a pinhole with this focal length and film height
        fov = math.degrees(2.0 * math.atan(0.5 * cam["film_size"][1] / cam["focal_length"]))
    points.append(cam["position"])
    ext = max((max(p[k] for p in points) - min(p[k] for p in points)) for k in range(3)) or 1.0
    d["sensor"] = {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "y",
        "near_clip": 1e-4 * ext,
        "far_clip": 1e3 * ext,
        "to_world": mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["look_at"], up=cam["up"]),
        "sampler": {"type": "independent", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "rgb",
                 "component_format": "float32", "rfilter": {"type": rfilter}},
    }
    d["integrator"] = {"type": "path", "max_depth": max_depth_mitsuba}
    info = {"spp": spp, "width": width, "height": height, "max_depth_furnace": bounces,
            "max_depth_mitsuba": max_depth_mitsuba, "fov_deg": fov, "filter": rfilter}
    return d, info


def main(argv=None):
    args = parse_args(argv)
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    mi.set_log_level(mi.LogLevel.Warn)
    # Mitsuba 3's Python API has no Thread.set_thread_count; the CPU thread pool is Dr.Jit's
    # (nanothread) pool, sized with dr.set_thread_count(N): N threads including the main thread
    # (Mitsuba's own `-t N` does the same: pool size N - 1 plus the calling thread).
    default_threads = dr.thread_count()
    dr.set_thread_count(args.threads)
    render_threads = dr.thread_count()

    scene_file = os.path.abspath(args.scene)
    out = os.path.abspath(args.out)
    stem = out[:-4] if out.lower().endswith(".exr") else out
    with tempfile.TemporaryDirectory(prefix="furnace_mitsuba_") as tmp:
        d, info = build_scene_dict(scene_file, args, tmp, mi)
        t0 = time.perf_counter()
        scene = mi.load_dict(d)
        t_load = time.perf_counter() - t0
    k = max(args.batches, 1)
    if info["spp"] % k:
        raise SystemExit(f"--spp {info['spp']} must be a multiple of --batches {k}")
    t0 = time.perf_counter()
    imgs = []
    for b in range(k):
        img = mi.render(scene, spp=info["spp"] // k, seed=args.seed + b)
        dr.eval(img)
        imgs.append(img)
    t_render = time.perf_counter() - t0
    # Restore the default pool before writing: with mitsuba 3.9.1 / drjit 1.5.0, Bitmap.write()
    # of an EXR hangs forever (no CPU use) when the pool was set to 1 thread (no workers).
    dr.set_thread_count(max(default_threads, 2))

    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    if k == 1:
        bmp = mi.Bitmap(imgs[0], mi.Bitmap.PixelFormat.RGB)
        bmp.write(out)
    else:
        import numpy as np
        stack = np.stack([np.array(i, dtype=np.float64) for i in imgs])  # (K, H, W, 3)
        mean = stack.mean(axis=0)
        var_of_mean = stack.var(axis=0, ddof=1) / k
        both = np.concatenate([mean, var_of_mean], axis=2).astype(np.float32)
        names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"]
        mi.Bitmap(both, channel_names=names).write(out)
        bmp = mi.Bitmap(mean.astype(np.float32), mi.Bitmap.PixelFormat.RGB)
    xyz_out = stem + "_xyz.exr"
    bmp.convert(mi.Bitmap.PixelFormat.XYZ, mi.Struct.Type.Float32, srgb_gamma=False).write(xyz_out)

    samples = info["width"] * info["height"] * info["spp"]
    sidecar = {
        "renderer": "mitsuba",
        "version": mi.__version__,
        "drjit_version": dr.__version__,
        "variant": args.variant,
        "spp": info["spp"],
        "batches": k,
        "seed": args.seed,
        "width": info["width"],
        "height": info["height"],
        "max_depth_mitsuba": info["max_depth_mitsuba"],
        "max_depth_furnace": info["max_depth_furnace"],
        "threads": render_threads,
        "time_s": t_render,
        "load_time_s": t_load,
        "samples_per_second": samples / t_render,
        "scene_file": os.path.relpath(scene_file, REPO) if scene_file.startswith(REPO + os.sep) else scene_file,
        "fov_deg": info["fov_deg"],
        "filter": info["filter"],
        "integrator": "path",
        "sampler": "independent",
        "rgb_file": os.path.basename(out),
        "xyz_file": os.path.basename(xyz_out),
        "rgb_space": "linear sRGB / Rec.709 primaries, D65 white, no white balance (Mitsuba hdrfilm 'rgb')",
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
    with open(stem + ".json", "w") as f:
        json.dump(sidecar, f, indent=2)
        f.write("\n")
    print(f"mitsuba {mi.__version__} {args.variant}: {info['width']}x{info['height']} @ {info['spp']} spp, "
          f"max_depth(mitsuba)={info['max_depth_mitsuba']}, threads={render_threads}, seed={args.seed}")
    print(f"load {t_load:.3f} s, render {t_render:.3f} s, {samples / t_render:.0f} samples/second")
    print(f"wrote {out}, {xyz_out}, {stem}.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
