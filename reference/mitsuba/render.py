#!/usr/bin/env python3
"""Render a furnace scene with Mitsuba 3 through furnace's own exporter.

The scene is exported by `furnace export --format mitsuba3` (src/export/mitsuba.rs: spectra stay
spectra, two-sided diffuse, flat-shaded PLY meshes, one-sided area emitters, box filter, path
integrator; see the README next to this script) and loaded with `mitsuba.load_file`, so the
translation lives in one place, tested in Rust, and this script only drives Mitsuba.

Writes <out> (linear sRGB / Rec.709 EXR, the film's native output in spectral variants; with
--batches K >= 2 also variance.R/G/B = the variance of the mean over K independent batches),
<stem>_xyz.exr (CIE XYZ via Mitsuba's Bitmap.convert), <stem>.json (sidecar), and keeps the
exact export in <stem>.export/ (scene.xml + meshes/) unless --xml names an existing export.

Example (tiny smoke test):
    python3 reference/mitsuba/render.py --scene scenes/cornell-box.toml --width 32 --height 32 \
        --spp 4 --out /tmp/cbox.exr
"""

import argparse
import hashlib
import json
import re
import os
import platform
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--scene", help="furnace TOML scene, exported with `furnace export`")
    src.add_argument("--xml", help="an existing Mitsuba export (scene.xml written by `furnace export`)")
    p.add_argument("--furnace", default=None,
                   help="furnace binary for --scene (default: target/release/furnace if built, else `cargo run --release --`)")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    p.add_argument("--width", type=int, help="pixels (default: the scene's)")
    p.add_argument("--height", type=int, help="pixels (default: the scene's)")
    p.add_argument("--seed", type=int, default=0, help="sampler seed of the first batch (default: 0)")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                   help="CPU threads incl. the main thread (default: all cores, %(default)s)")
    p.add_argument("--max-depth", type=int, default=None,
                   help="maximum number of BOUNCES in furnace's convention; Mitsuba gets this + 1; "
                        "-1 = unlimited (default: the scene's)")
    p.add_argument("--variant", default="scalar_spectral", help="Mitsuba variant (default: %(default)s)")
    p.add_argument("--out", required=True, help="output EXR path")
    p.add_argument("--batches", type=int, default=1,
                   help="render K independent batches of spp/K (seeds seed..seed+K-1) and write their mean "
                        "with variance.R/G/B = variance of that mean; K >= 2 needs numpy (default: 1)")
    return p.parse_args(argv)


def export(scene, folder, furnace):
    if furnace:
        cmd = [furnace]
    elif os.path.exists(os.path.join(REPO, "target", "release", "furnace")):
        cmd = [os.path.join(REPO, "target", "release", "furnace")]
    else:
        cmd = ["cargo", "run", "--quiet", "--release", "--manifest-path", os.path.join(REPO, "Cargo.toml"), "--"]
    subprocess.run(cmd + ["export", scene, "--format", "mitsuba3", "--out", folder], check=True,
                   stdout=subprocess.DEVNULL)
    return os.path.join(folder, "scene.xml")


def rel(path):
    path = os.path.abspath(path)
    return os.path.relpath(path, REPO) if path.startswith(REPO + os.sep) else path


def main(argv=None):
    args = parse_args(argv)
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    mi.set_log_level(mi.LogLevel.Warn)
    # The CPU pool is Dr.Jit's: N threads including the main thread (like Mitsuba's `-t N`).
    default_threads = dr.thread_count()
    dr.set_thread_count(args.threads)
    render_threads = dr.thread_count()

    out = os.path.abspath(args.out)
    stem = out[:-4] if out.lower().endswith(".exr") else out
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    xml = os.path.abspath(args.xml) if args.xml else export(os.path.abspath(args.scene), stem + ".export", args.furnace)

    params = {}
    for key in ("spp", "width", "height"):
        if getattr(args, key) is not None:
            params[key] = getattr(args, key)
    if args.max_depth is not None:
        params["max_depth"] = -1 if args.max_depth < 0 else args.max_depth + 1
    t0 = time.perf_counter()
    scene = mi.load_file(xml, **params)
    t_load = time.perf_counter() - t0
    sensor = scene.sensors()[0]
    width, height = (int(v) for v in sensor.film().size())
    spp = sensor.sampler().sample_count()
    max_depth_mitsuba = params.get("max_depth")
    if max_depth_mitsuba is None:  # the export's default, read back from the XML text
        m = re.search(r'<default name="max_depth" value="(-?\d+)"', open(xml).read())
        max_depth_mitsuba = int(m.group(1))
    k = max(args.batches, 1)
    if spp % k:
        raise SystemExit(f"spp {spp} must be a multiple of --batches {k}")
    nonfinite = []
    t0 = time.perf_counter()
    imgs = []
    for b in range(k):
        img = mi.render(scene, spp=spp // k, seed=args.seed + b)
        dr.eval(img)
        imgs.append(img)
    t_render = time.perf_counter() - t0
    # mitsuba 3.9.1 / drjit 1.5.0: Bitmap.write() of an EXR hangs forever when the pool has one
    # thread (no workers); restore a pool of at least 2 before writing.
    dr.set_thread_count(max(default_threads, 2))

    if k == 1:
        bmp = mi.Bitmap(imgs[0], mi.Bitmap.PixelFormat.RGB)
        bmp.write(out)
    else:
        import numpy as np
        stack = np.stack([np.array(i, dtype=np.float64) for i in imgs])  # (K, H, W, 3)
        # A batch whose pixel is NaN/Inf (a Mitsuba sample went non-finite) is left out of that
        # pixel's mean and variance, and every such (x, y, batch) is recorded in the sidecar.
        finite = np.isfinite(stack).all(axis=3, keepdims=True)  # (K, H, W, 1)
        for b, y, x in np.argwhere(~finite[..., 0]):
            nonfinite.append([int(x), int(y), int(b)])
        n = finite.sum(axis=0)
        if (n < 2).any():
            raise SystemExit("a pixel has fewer than 2 finite batches; cannot estimate its variance")
        clean = np.where(finite, stack, 0.0)
        mean = clean.sum(axis=0) / n
        var_of_mean = (np.where(finite, (stack - mean) ** 2, 0.0).sum(axis=0) / (n - 1)) / n
        if nonfinite:
            print(f"warning: {len(nonfinite)} (pixel, batch) pairs were NaN/Inf in Mitsuba's output and were left out: "
                  f"{nonfinite[:8]}{' ...' if len(nonfinite) > 8 else ''}")
        both = np.concatenate([mean, var_of_mean], axis=2).astype(np.float32)
        names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"]
        mi.Bitmap(both, channel_names=names).write(out)
        bmp = mi.Bitmap(mean.astype(np.float32), mi.Bitmap.PixelFormat.RGB)
    xyz_out = stem + "_xyz.exr"
    bmp.convert(mi.Bitmap.PixelFormat.XYZ, mi.Struct.Type.Float32, srgb_gamma=False).write(xyz_out)

    samples = width * height * spp
    sidecar = {
        "renderer": "mitsuba",
        "version": mi.__version__,
        "drjit_version": dr.__version__,
        "variant": args.variant,
        "spp": spp,
        "batches": k,
        "seed": args.seed,
        "width": width,
        "height": height,
        "max_depth_mitsuba": max_depth_mitsuba,
        "max_depth_furnace": -1 if max_depth_mitsuba < 0 else max_depth_mitsuba - 1,
        "threads": render_threads,
        "time_s": t_render,
        "load_time_s": t_load,
        "samples_per_second": samples / t_render,
        "scene_file": rel(args.scene) if args.scene else None,
        "export": rel(xml),
        "export_sha256": hashlib.sha256(open(xml, "rb").read()).hexdigest(),
        "filter": "box",
        "integrator": re.search(r'<integrator type="(\w+)"', open(xml).read()).group(1),
        "nonfinite_pixel_batches": nonfinite,
        "sampler": "independent",
        "rgb_file": os.path.basename(out),
        "xyz_file": os.path.basename(xyz_out),
        "rgb_space": "linear sRGB / Rec.709 primaries, D65 white, no white balance (Mitsuba hdrfilm 'rgb'); "
                     "compare with furnace --observer mitsuba3",
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
    with open(stem + ".json", "w") as f:
        json.dump(sidecar, f, indent=2)
        f.write("\n")
    print(f"mitsuba {mi.__version__} {args.variant}: {width}x{height} @ {spp} spp in {k} batch(es), "
          f"max_depth(mitsuba)={max_depth_mitsuba}, threads={render_threads}, seed={args.seed}")
    print(f"load {t_load:.3f} s, render {t_render:.3f} s, {samples / t_render:.0f} samples/second")
    print(f"wrote {out}, {xyz_out}, {stem}.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
