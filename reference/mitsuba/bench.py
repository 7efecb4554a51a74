#!/usr/bin/env python3
"""furnace against Mitsuba 3 on the same scene and machine: speed and time to equal error.

Renders the measured Cornell Box (or --scene) with furnace (`furnace render`) and with each
Mitsuba variant, alternating renderers within each repetition, and reports medians of:
  * samples per second (camera paths per second of render time; scene loading, and for the
    LLVM variants the JIT compilation of a warm-up render, are excluded);
  * the error against a high-spp reference (default: the committed Mitsuba reference, 128x128,
    4096 spp in 16 batches): relMSE of linear sRGB over all pixels, (x - r)^2/(r^2 + 0.01), minus
    the reference's own variance term (its variance channels), so it estimates the renderer's
    error alone;
  * efficiency 1/(relMSE x time) and the time each renderer needs to reach the same error,
    proportional to relMSE x time (independent sampling: relMSE ~ 1/spp), as a ratio to furnace.
  * for each renderer, its time and its relMSE x time as paired ratios to furnace's over the
    repetitions (each repetition runs every renderer in turn), geometric means with 95 %
    t intervals on the log ratios: the statement "ahead" needs the interval, not the median.
Equal settings: same exported scene, box filter, max depth (furnace bounces; Mitsuba gets + 1),
Russian roulette from depth 5 in both (or --rr-depth), 4 wavelengths per sample in both (Mitsuba's spectral
variants trace 4 wavelengths per path), furnace rendered with --observer mitsuba3 so both images
use Mitsuba's colour pipeline.

    cargo build --release        # for this machine's CPU (.cargo/config.toml)
    RUSTFLAGS="-C target-cpu=x86-64" cargo build --release --target-dir target/portable   # optional
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \\
        python3 reference/mitsuba/bench.py --reps 5 --spp 256 --variants scalar_spectral,llvm_ad_spectral \\
        --furnace-portable target/portable/release/furnace

A profile-guided build (benches/pgo.sh) goes first, with the default build beside it:
    --furnace target/pgo/release/furnace --furnace-label furnace:pgo \\
        --furnace-also furnace:default=target/release/furnace

With --furnace-sampler sobol and --mitsuba-sampler ldsampler (or multijitter, orthogonal) each
renderer runs at a low-discrepancy pattern; relMSE then falls faster than 1/spp, so the time to
equal error holds at the --spp measured only.

With `--reference none --size 256x256 --max-depth 5` it measures speed only (no error, so no
time to equal error), at any size and depth: the issue's setting is 256x256, Mitsuba max_depth 6.

With --llvm-avx2, each LLVM variant also runs with its JIT limited to AVX2 (8 lanes of f32
instead of AVX-512's 16; the same CPU model for tuning, every AVX-512 feature off), in a worker
process (Dr.Jit takes one target per process), in the same alternation, reported as
'mitsuba3:VARIANT:avx2': the same core with only the vector width changed. It sets the target
through Dr.Jit's C++ entry point jit_llvm_set_target (drjit-core as shipped with Mitsuba
3.9.1), since Python does not expose it.

Writes the results as JSON (--json) and prints a table.
"""

import argparse
import ctypes
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))


def furnace_build(binary):
    """What `furnace --version` says of a binary: its version and the vector code it was built
    for (a build may leave out extensions the CPU has, as the default build does AVX-512)."""
    try:
        out = subprocess.run([binary, "--version"], capture_output=True, text=True, timeout=30)
    except OSError as e:
        return f"unknown ({e})"
    return out.stdout.strip() or f"unknown (exit {out.returncode})"


def cpu_description():
    """The CPU as the kernel reports it: model name, family/model/stepping and the vector
    extensions that decide how wide Mitsuba's LLVM back end and furnace's native build go."""
    info = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if ":" in line:
                    k, v = line.split(":", 1)
                    info.setdefault(k.strip(), v.strip())
    except OSError:
        return platform.processor() or "unknown CPU"
    flags = set(info.get("flags", "").split())
    vector = [f for f in ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512bw",
                          "avx512vl", "avx512_fp16", "amx_tile") if f in flags]
    return (f"{info.get('model name', 'unknown')} (family {info.get('cpu family', '?')} "
            f"model {info.get('model', '?')} stepping {info.get('stepping', '?')}), "
            f"{os.cpu_count()} logical CPUs, vector: {' '.join(vector) or 'none'}")


class LlvmJit:
    """Dr.Jit's LLVM back end's target: which CPU and vector width its kernels are compiled
    for. drjit-core's C++ functions (Itanium-mangled names, as in the 3.9.1 wheel):
    jit_llvm_target_cpu(), jit_llvm_target_features(), jit_llvm_vector_width() and
    jit_llvm_set_target(cpu, features, width)."""

    def __init__(self, dr):
        path = os.path.join(os.path.dirname(dr.__file__), "libdrjit-core.so")
        try:
            lib = ctypes.CDLL(path)
            self._cpu = lib._Z19jit_llvm_target_cpuv
            self._features = lib._Z24jit_llvm_target_featuresv
            self._width = lib._Z21jit_llvm_vector_widthv
            self._set = lib._Z19jit_llvm_set_targetPKcS0_j
        except (OSError, AttributeError) as e:
            raise RuntimeError(f"this Dr.Jit ({path}) does not expose its LLVM target the way "
                               f"drjit-core 3.9.1 does ({e}); --llvm-avx2 needs Mitsuba 3.9.1") from e
        self._cpu.restype = ctypes.c_char_p
        self._features.restype = ctypes.c_char_p
        self._width.restype = ctypes.c_uint32
        self._set.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]

    def describe(self):
        """The target as 'cpu, N lanes' (after the back end has started: set_variant)."""
        return f"{self._cpu().decode()}, {self._width()} lanes"

    def limit_to_avx2(self):
        """The same CPU model (for scheduling), every AVX-512 feature off, 8 lanes. Before the
        first kernel: Dr.Jit does not take a second target in one process."""
        features = ",".join("-" + f[1:] if f.startswith("+avx512") or f == "+evex512" else f
                            for f in self._features().decode().split(","))
        self._set(self._cpu(), features.encode(), 8)


def llvm_worker(argv):
    """A worker rendering one LLVM variant with its JIT limited to AVX2 (see --llvm-avx2):
    argv = variant, scene XML, spp, width, height, Mitsuba max_depth, threads. Prints its
    target, then for each line 'seed path' on stdin renders, saves the image (numpy .npy) to
    path and prints the render's seconds."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np
    variant, xml, spp, width, height, max_depth, threads = argv
    spp, width, height, max_depth, threads = map(int, (spp, width, height, max_depth, threads))
    mi.set_variant(variant)
    jit = LlvmJit(dr)
    jit.limit_to_avx2()
    dr.set_thread_count(threads)
    scene = mi.load_file(xml, spp=spp, width=width, height=height, max_depth=max_depth)
    dr.eval(mi.render(scene, spp=spp, seed=999))  # warm-up (JIT)
    dr.sync_thread()
    print(jit.describe(), flush=True)
    for line in sys.stdin:
        seed, path = line.split(" ", 1)
        t0 = time.perf_counter()
        img = mi.render(scene, spp=spp, seed=int(seed))
        dr.eval(img)
        dr.sync_thread()
        secs = time.perf_counter() - t0
        np.save(path.strip(), np.array(img))
        print(secs, flush=True)
    return 0


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scene", default=os.path.join(REPO, "scenes", "cornell-box.toml"))
    p.add_argument("--reference", default=os.path.join(HERE, "cornell-box.exr"),
                   help="high-spp reference EXR with R, G, B and variance.R/G/B (sets the size); "
                        "'none' measures speed only, at --size")
    p.add_argument("--size", default=None,
                   help="WIDTHxHEIGHT, with --reference none (e.g. 256x256, the issue's setting)")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--max-depth", type=int, default=-1,
                   help="bounces (furnace's convention), -1 unlimited; must match the reference's (default: -1)")
    p.add_argument("--rr-depth", type=int, default=None,
                   help="bounces before Russian roulette starts, in both renderers (furnace's --rr-depth, "
                        "written into Mitsuba's integrator as rr_depth: src/integrators/path.cpp at v3.9.1 "
                        "counts it the same way, roulette first after the rr_depth-th surface's sampling); "
                        "default: each renderer's own, 5")
    p.add_argument("--reps", type=int, default=3)
    p.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--variants", default="scalar_spectral")
    p.add_argument("--furnace", default=os.path.join(REPO, "target", "release", "furnace"))
    p.add_argument("--furnace-label", default="furnace",
                   help="the name --furnace is reported under (e.g. 'furnace:pgo' for benches/pgo.sh's build)")
    p.add_argument("--furnace-also", action="append", default=[], metavar="LABEL=PATH",
                   help="another furnace binary (e.g. furnace:default=target/release/furnace), run in the "
                        "same alternation and compared, like every renderer, with --furnace; repeatable")
    p.add_argument("--furnace-portable", default=None,
                   help="a second furnace binary built for baseline x86-64 (RUSTFLAGS='-C target-cpu=x86-64'; "
                        "the default build targets the building CPU, see .cargo/config.toml), run in the same "
                        "alternation and reported as 'furnace:portable'")
    p.add_argument("--llvm-avx2", action="store_true",
                   help="also run each llvm_* variant with its JIT limited to AVX2 (8 lanes), in a worker "
                        "process, reported as 'mitsuba3:VARIANT:avx2' (on a CPU with AVX-512: the same core "
                        "with only the vector width changed)")
    p.add_argument("--furnace-sampler", default="independent",
                   choices=["independent", "stratified", "sobol"],
                   help="furnace's --sampler (default independent, as the issue's measurement)")
    p.add_argument("--mitsuba-sampler", default="independent",
                   choices=["independent", "stratified", "multijitter", "orthogonal", "ldsampler"],
                   help="the sampler plugin written into the export for Mitsuba (default independent); "
                        "with a low-discrepancy sampler in both, each renderer runs at its best pattern")
    p.add_argument("--json", default=None, help="write the results here")
    return p.parse_args(argv)


def t_quantile_975(df):
    """Student's t 0.975 quantile from the normal one by the Cornish-Fisher expansion
    (Abramowitz & Stegun 1964, eq. 26.7.5, three terms); within 0.3 % for df >= 4."""
    from statistics import NormalDist
    z = NormalDist().inv_cdf(0.975)
    return (z + (z ** 3 + z) / (4 * df) + (5 * z ** 5 + 16 * z ** 3 + 3 * z) / (96 * df ** 2)
            + (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / (384 * df ** 3))


def paired_ratio(base, other):
    """Geometric mean of other/base over paired repetitions, with its 95 % confidence interval
    (a t interval on the per-repetition log ratios; the repetitions alternate renderers, so
    the pairs share the machine's state). None with fewer than 3 pairs."""
    import math
    logs = [math.log(o / b) for b, o in zip(base, other) if b > 0 and o > 0]
    n = len(logs)
    if n < 3:
        return None
    mean = sum(logs) / n
    sd = math.sqrt(sum((x - mean) ** 2 for x in logs) / (n - 1))
    half = t_quantile_975(n - 1) * sd / math.sqrt(n)
    return {"ratio": math.exp(mean), "ci95": [math.exp(mean - half), math.exp(mean + half)], "pairs": n}


def read_rgb(mi, path):
    """Linear R, G, B and (when present) variance.R/G/B of an EXR, by channel name."""
    import numpy as np
    bmp = mi.Bitmap(path)
    data = np.array(bmp, dtype=np.float64).reshape(bmp.height(), bmp.width(), bmp.channel_count())
    names = [bmp.struct_()[i].name for i in range(bmp.channel_count())]
    chans = {n: data[..., i] for i, n in enumerate(names)}
    rgb = np.stack([chans[c] for c in "RGB"], axis=2)
    var = None
    if all(f"variance.{c}" in chans for c in "RGB"):
        var = np.stack([chans[f"variance.{c}"] for c in "RGB"], axis=2)
    return rgb, var


def main(argv=None):
    args = parse_args(argv)
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    mi.set_variant("scalar_spectral")
    speed_only = args.reference == "none"
    if speed_only:
        if not args.size or not re.fullmatch(r"[0-9]+x[0-9]+", args.size):
            sys.exit("--reference none needs --size WIDTHxHEIGHT (e.g. 256x256)")
        width, height = (int(v) for v in args.size.split("x"))
        ref_rgb, ref_var, ref_noise = None, None, 0.0
    else:
        if args.size:
            sys.exit("--size is only for --reference none (a reference sets the size)")
        ref_rgb, ref_var = read_rgb(mi, args.reference)
        height, width = ref_rgb.shape[0], ref_rgb.shape[1]
        # Mean variance of the reference's pixel means (its own noise).
        ref_noise = float(ref_var.mean()) if ref_var is not None else 0.0

    tmp = tempfile.mkdtemp(prefix="furnace_bench_")
    xml_dir = os.path.join(tmp, "export")
    subprocess.run([args.furnace, "export", args.scene, "--format", "mitsuba3", "--out", xml_dir],
                   check=True, stdout=subprocess.DEVNULL)
    xml = os.path.join(xml_dir, "scene.xml")
    if args.rr_depth is not None:
        if args.rr_depth < 1:
            sys.exit("--rr-depth must be at least 1 (Mitsuba refuses 0)")
        text = open(xml).read()
        line = '<integer name="max_depth" value="$max_depth"/>'
        if text.count(line) != 1:
            sys.exit(f"the export's integrator has no single {line}")
        text = text.replace(line, line + f'\n    <integer name="rr_depth" value="{args.rr_depth}"/>')
        with open(xml, "w") as f:
            f.write(text)
    if args.mitsuba_sampler == "orthogonal":
        # Mitsuba's orthogonal sampler rounds the sample count up to a prime's square
        root = round(args.spp ** 0.5)
        if root * root != args.spp or root < 2 or any(root % k == 0 for k in range(2, root)):
            sys.exit(f"--mitsuba-sampler orthogonal needs --spp the square of a prime (Mitsuba "
                     f"rounds {args.spp} up to one): 49, 121, 169, ...")
    if args.mitsuba_sampler != "independent":
        text = open(xml).read()
        line = '<sampler type="independent">'
        if text.count(line) != 1:
            sys.exit(f"the export has no single {line}")
        with open(xml, "w") as f:
            f.write(text.replace(line, f'<sampler type="{args.mitsuba_sampler}">'))
    samples = width * height * args.spp
    variants = [v for v in args.variants.split(",") if v]
    furnaces = {args.furnace_label: args.furnace}
    if args.furnace_portable:
        furnaces["furnace:portable"] = args.furnace_portable
    for extra in args.furnace_also:
        label, sep, path = extra.partition("=")
        if not sep or not label or not path:
            sys.exit(f"--furnace-also takes LABEL=PATH, not {extra!r}")
        if label in furnaces:
            sys.exit(f"--furnace-also: the label {label!r} is taken")
        furnaces[label] = path
    rows = {name: [] for name in furnaces}
    for v in variants:
        rows[f"mitsuba3:{v}"] = []
    mitsuba_depth = -1 if args.max_depth < 0 else args.max_depth + 1
    scenes = {}
    targets = {}
    for v in variants:
        mi.set_variant(v)
        dr.set_thread_count(args.threads)
        scenes[v] = mi.load_file(xml, spp=args.spp, width=width, height=height, max_depth=mitsuba_depth)
        dr.eval(mi.render(scenes[v], spp=args.spp, seed=999))  # warm-up (JIT for llvm variants)
        dr.sync_thread()
        if v.startswith("llvm"):
            try:
                targets[f"mitsuba3:{v}"] = LlvmJit(dr).describe()
            except RuntimeError as e:
                targets[f"mitsuba3:{v}"] = f"unknown ({e})"
    workers = {}
    if args.llvm_avx2:
        for v in variants:
            if not v.startswith("llvm"):
                continue
            name = f"mitsuba3:{v}:avx2"
            w = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--llvm-worker", v, xml,
                                  str(args.spp), str(width), str(height), str(mitsuba_depth), str(args.threads)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            ready = w.stdout.readline().strip()
            if not ready:
                sys.exit(f"the AVX2 worker for {v} stopped before its first render (exit {w.wait()})")
            targets[name] = ready
            workers[name] = w
            rows[name] = []
        if not workers:
            sys.exit("--llvm-avx2 needs an llvm_* variant in --variants")

    # relMSE (x - r)^2 / (r^2 + eps), eps = 0.01 (Rousselle et al. 2011): bright emitter pixels
    # would otherwise dominate MSE with a few heavy-tailed values. The reference's own variance
    # enters the same way and is subtracted.
    eps = 1e-2
    if not speed_only:
        weight = 1.0 / (ref_rgb ** 2 + eps)
        ref_term = float((ref_var * weight).mean()) if ref_var is not None else 0.0

    def mse(img):
        if speed_only:
            return float("nan")
        d = np.asarray(img, dtype=np.float64)[..., :3] - ref_rgb
        return float((d * d * weight).mean()) - ref_term

    for rep in range(args.reps):
        for name, binary in furnaces.items():
            out = os.path.join(tmp, f"{name.replace(':', '-')}-{rep}.exr")
            depths = [] if args.max_depth < 0 else ["--max-depth", str(args.max_depth)]
            if args.rr_depth is not None:
                depths += ["--rr-depth", str(args.rr_depth)]
            r = subprocess.run([binary, "render", args.scene, "--width", str(width), "--height", str(height),
                                "--spp", str(args.spp), "--threads", str(args.threads), "--seed", str(100 + rep),
                                "--observer", "mitsuba3", "--sampler", args.furnace_sampler,
                                "--out", out] + depths,
                               check=True, capture_output=True, text=True)
            secs = float(re.search(r"([0-9.]+) s wall", r.stdout).group(1))
            if speed_only:
                rows[name].append((secs, mse(None)))
            else:
                mi.set_variant("scalar_spectral")
                rgb, _ = read_rgb(mi, out)
                rows[name].append((secs, mse(rgb)))
            print(f"rep {rep}: {name} {secs:.3f} s", file=sys.stderr)
        for v in variants:
            mi.set_variant(v)
            dr.set_thread_count(args.threads)
            t0 = time.perf_counter()
            img = mi.render(scenes[v], spp=args.spp, seed=100 + rep)
            dr.eval(img)
            dr.sync_thread()  # LLVM variants launch kernels asynchronously
            secs = time.perf_counter() - t0
            rows[f"mitsuba3:{v}"].append((secs, mse(None if speed_only else np.array(img))))
        for name, w in workers.items():
            path = os.path.join(tmp, f"{name.replace(':', '-')}-{rep}.npy")
            w.stdin.write(f"{100 + rep} {path}\n")
            w.stdin.flush()
            answer = w.stdout.readline().strip()
            if not answer:
                sys.exit(f"the worker {name} stopped (exit {w.wait()})")
            rows[name].append((float(answer), mse(None if speed_only else np.load(path))))
    for w in workers.values():
        w.stdin.close()
        w.wait()

    result = {"scene": os.path.relpath(args.scene, REPO), "width": width, "height": height, "spp": args.spp,
              "max_depth_bounces": args.max_depth, "rr_depth": 5 if args.rr_depth is None else args.rr_depth,
              "threads": args.threads, "reps": args.reps,
              "furnace_sampler": args.furnace_sampler, "mitsuba_sampler": args.mitsuba_sampler,
              "reference": None if speed_only else os.path.relpath(args.reference, REPO),
              "reference_mean_variance": None if speed_only else ref_noise,
              "furnace_binaries": {k: os.path.relpath(v, REPO) for k, v in furnaces.items()},
              "furnace_builds": {k: furnace_build(v) for k, v in furnaces.items()},
              "mitsuba": mi.__version__, "llvm_targets": targets, "platform": platform.platform(), "cpu": cpu_description(), "renderers": {}}
    base = None
    print(f"CPU: {cpu_description()}")
    for k, v in result["furnace_builds"].items():
        print(f"{k}: {v}")
    for k, v in targets.items():
        print(f"{k}: JIT target {v}")
    print(f"{width}x{height}, {args.spp} spp, {args.max_depth} bounces, roulette from bounce "
          f"{5 if args.rr_depth is None else args.rr_depth}, {args.threads} threads, "
          f"median of {args.reps} alternating runs; "
          + ("speed only (no reference)" if speed_only else f"error against {result['reference']}"))
    if speed_only:
        print(f"{'renderer':<32} {'time s':>8} {'M samples/s':>12} {'speed vs furnace':>17}")
    else:
        print(f"{'renderer':<32} {'time s':>8} {'M samples/s':>12} {'relMSE':>11} {'1/(relMSE t)':>12} {'time to equal error':>20}")
    for name, runs in rows.items():
        t = statistics.median(x[0] for x in runs)
        if base is None:
            base = (t, None)
        if speed_only:
            m = eff = rel = float("nan")
            result["renderers"][name] = {"median_seconds": t, "samples_per_second": samples / t,
                                         "samples_per_second_vs_furnace": base[0] / t,
                                         "runs": [x[0] for x in runs]}
        else:
            m = statistics.median(x[1] for x in runs)
            eff = 1.0 / (m * t) if m > 0 else float("inf")
            if base[1] is None:
                base = (t, m)
            rel = (m * t) / (base[1] * base[0])
            result["renderers"][name] = {"median_seconds": t, "samples_per_second": samples / t,
                                         "median_rel_mse": m, "efficiency": eff,
                                         "time_to_equal_error_vs_furnace": rel, "runs": runs}
        if speed_only:
            print(f"{name:<32} {t:>8.3f} {samples / t / 1e6:>12.3f} {base[0] / t:>16.3f}x")
        else:
            print(f"{name:<32} {t:>8.3f} {samples / t / 1e6:>12.3f} {m:>11.4e} {eff:>12.4e} {rel:>19.3f}x")
    # Paired comparisons with furnace (the first renderer): time per repetition, and for the
    # time to equal error relMSE x time per repetition.
    first = next(iter(rows))
    print(f"paired over {args.reps} repetitions, 95 % confidence intervals (t on log ratios):")
    for name, runs in rows.items():
        if name == first:
            continue
        base = rows[first]
        speed = paired_ratio([x[0] for x in base], [x[0] for x in runs])
        entry = result["renderers"][name]
        entry["paired_time_ratio_vs_furnace"] = speed
        line = f"  {name:<30} time / furnace's "
        line += "n/a" if speed is None else f"{speed['ratio']:.3f} [{speed['ci95'][0]:.3f}, {speed['ci95'][1]:.3f}]"
        if not speed_only:
            eq = paired_ratio([x[0] * x[1] for x in base], [x[0] * x[1] for x in runs])
            entry["paired_time_to_equal_error_vs_furnace"] = eq
            line += "; time to equal error / furnace's "
            line += "n/a" if eq is None else f"{eq['ratio']:.3f} [{eq['ci95'][0]:.3f}, {eq['ci95'][1]:.3f}]"
        print(line)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=2)
            f.write("\n")
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["--llvm-worker"]:
        sys.exit(llvm_worker(sys.argv[2:]))
    sys.exit(main())
