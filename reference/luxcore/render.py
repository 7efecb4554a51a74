#!/usr/bin/env python3
"""Render a furnace scene interchange JSON (docs/scene-json.md, version 1) with LuxCoreRender.

Runs with `pyluxcore` (`pip install pyluxcore==2.11.2 numpy OpenEXR`; see README.md next to this
script), builds the scene through LuxCore's property API, renders one image with the PATHCPU
engine and writes <out> (OpenEXR, channels R, G, B, 32-bit float: LuxCore's RGB film output,
linear radiance without the image pipeline) and <stem>.json (sidecar: renderer, version, every
property used, wall time). The scene-JSON reading, camera frame, sphere tessellation and sidecar
are shared with the Cycles driver (reference/cycles/scene_json.py).

Anything LuxCore cannot express is refused: one line `unsupported: <what and why>` on stderr and
exit code 3. Invalid input exits 2.

Settings that make the render comparable with furnace (all in the sidecar):
  * Engine PATHCPU (unidirectional path tracing with next-event estimation and MIS),
    path.hybridbackforward.enable = false (no light tracing), no PhotonGI cache.
  * Path depth: LuxCore's path.pathdepth.total = N ends a path at its N-th vertex; next-event
    estimation is skipped at the last vertex unless it is also the first (src/slg/engines/
    pathtracer.cpp, PathDepthInfo::IsLastPathVertex), so N = furnace's D + 1 for D >= 1
    (measured on the closed box: N = 2, 3, 4 read 1.5, 1.75, 1.875; README). N = 1 renders direct
    light too (NEE without MIS at the first vertex), so D = 0 is rendered exactly by dropping
    every BSDF (surfaces keep only their emission; volumes keep extinction sigma_a + sigma_s as
    absorption and lose in-scattering), as in the Cycles driver. path.pathdepth.diffuse/glossy/
    specular = N, so only the total counts. Null boundaries are pass-through, not vertices.
  * Russian roulette OFF (path.russianroulette.depth = 2^20, never reached). LuxCore 2.11.2 biases
    its MIS when roulette is on: next-event estimation weights with the BSDF pdf times the
    survival probability, the BSDF-sampled hit of the same light with the bare pdf (pathtracer.cpp,
    DirectLightSampling vs DirectHitFiniteLight; EyePathInfo::lastBSDFPdfW never includes it), so
    the weights sum to more than 1: the closed box reads 1.8988 +- 0.0002 at N = 4 with roulette
    from depth 3 (LuxCore's default) against 1.875, and 2.047 unlimited against 2; with roulette
    off 1.8747 +- 0.0002 and 1.9998 +- 0.0002 (N = 64). An unlimited depth is therefore rendered
    as --unlimited-depth bounces (default 64); the sidecar records it with the scene's largest
    albedo a and the bound a^(K+1)/(1-a) on the relative size of the missing tail, and a scene
    whose bound exceeds --max-truncation (default 1e-4) is refused (exit 3), not rendered low:
    at K = 64 that is every scene with an albedo above about 0.86 and below 1 (an albedo of 1,
    a mirror, glass or white surface, has no bound: rendered, the sidecar saying so).
  * Clamping off: path.clamping.variance.maxvalue = 0. No denoiser and no noise estimation: no
    image pipeline is rendered, no NOISE channel exists (it is only allocated for adaptive
    sampling or a NOISE output), and sampler.random.adaptive.strength = 0.
  * Sampler RANDOM (independent uniform samples; sampler.random.adaptive.strength = 0), seed
    renderengine.seed = --seed + 1 (LuxCore replaces 0 by 1, so 0 and 1 would coincide).
  * Light strategy: lightstrategy.type = UNIFORM (one light chosen uniformly per NEE sample, as
    furnace does).
  * Pixel filter: film.filter.type = BOX, film.filter.width = 0.5: LuxCore's width is the
    filter's radius in pixels and a sample is placed by the filter's distribution around its own
    pixel's centre and added to that pixel only (PathTracer::GenerateEyeRay), so 0.5 = a box one
    pixel wide.
  * batch.haltspp = spp, batch.halttime = 0; native.threads.count = --threads.
  * Output: Film.GetOutputFloat(RGB): linear radiance per pixel (not tone-mapped, no gamma),
    written by this script with the OpenEXR module as FLOAT R, G, B (ZIP). LuxCore's film rows
    start at the bottom of the image; they are flipped so the EXR's first scanline is the top
    (verified by test d).
  * Colour: plain RGB triples are taken as given (Scene::GetColor applies no colour space to
    three numbers), so linear sRGB in = linear sRGB out; verified: an emitter of rgb (17, 12, 4)
    reads (17, 12, 4).

Scene mapping (docs/scene-json.md):
  * Camera: perspective, lookat.orig/target/up from the JSON, fieldofview = fov_y with
    screenwindow = (-W/H, W/H, -1 - 2/H, 1 - 2/H): the field of view then spans the image height
    (LuxCore's default spans the shorter side), and the window is lowered by one pixel because
    PerspectiveCamera::InitRay maps a film coordinate y to raster H - y - 1 rather than H - y,
    which shifts LuxCore's image down by one pixel (measured: the white-furnace sphere's edge
    rows came out at 10 and 55 instead of 9 and 54; with the correction at 9 and 54, as Cycles
    and the analytic projection). cliphither = 1e-6 x scene extent, clipyon = 1e30, lens radius 0.
  * Triangles: one LuxCore mesh per shape, vertices in the given order; LuxCore's geometric
    normal is (b - a) x (c - a) and emission leaves on that side only (TriangleLight); no vertex
    normals, so shading = geometric normal (flat).
  * Spheres: LuxCore has no analytic sphere: an icosphere of --sphere-subdiv (default 7, 327 680
    triangles) with its vertices on the sphere; its largest radial gap (1.8e-5 r at level 7) is
    printed and recorded in the sidecar.
  * diffuse -> matte (Lambertian, kd = rgb; it reflects on both sides).
  * conductor: perfect and alpha 0 -> mirror with kr = 1 (reflectance 1, no Fresnel). Everything
    else refused: LuxCore's rough metal (metal2) uses Schlick's 1994 microfacet distribution, not
    GGX, and it has no smooth mirror with a complex-index Fresnel term.
  * dielectric: alpha 0 -> glass, interiorior = ior, exteriorior = 1 (relative index), kr = kt = 1,
    no dispersion. Its transmission carries radiance (x eta^2, as furnace; verified). Rough glass
    refused (roughglass uses the Schlick distribution too).
  * null -> null material (pass-through). ward -> refused.
  * emission: material emission = rgb, gain 1, power 0, efficiency 0, normalizebycolor false,
    theta 90 (Lambertian emitter), one-sided (front = normal side); two-sided emission refused.
  * point light: type point, color = 4 pi x intensity_rgb, gain 1, power 0 (LuxCore's point light
    has radiant intensity color x gain / (4 pi); verified over a diffuse plane).
  * environment: constantinfinite, color = radiance_rgb, gain 1.
  * media: homogeneous volumes with absorption = sigma_a_rgb, scattering =
    sigma_s_rgb, multiscattering = true (the default, false, scatters once). Phase: LuxCore uses
    Schlick's approximation of Henyey-Greenstein (k = 1.55 g - 0.55 g^3), so only isotropic
    media (g = 0, where both are 1/(4 pi)) are accepted; hg with g != 0 and rayleigh are refused.
    Interior/exterior volumes per material (shape); the camera's medium is scene.camera.volume
    (auto-detection off); a medium bounded by no shape is the world's default volume.
"""

import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "cycles"))
import scene_json as sj  # noqa: E402  (shared with reference/cycles/render.py)
from scene_json import Invalid, Unsupported, vec  # noqa: E402

RR_OFF = 1 << 20  # a path.russianroulette.depth no path reaches


def parse_args(argv=None):
    p = sj.parser(__doc__.split("\n")[0], default_subdiv=7)
    p.add_argument("--unlimited-depth", type=int, default=64,
                   help="bounces rendered for an unlimited depth: LuxCore's Russian roulette biases its MIS, so "
                        "it is off and paths are truncated here (default: %(default)s)")
    p.add_argument("--max-truncation", type=float, default=1e-4,
                   help="largest relative bound on the energy an unlimited depth loses to the truncation "
                        "(a^(K+1)/(1-a) for the largest albedo a < 1); above it the scene is refused, not "
                        "rendered biased (default: %(default)s)")
    p.add_argument("--luxcore-pathdepth", type=int, default=None,
                   help="verification only: set path.pathdepth.total directly, bypassing the depth mapping")
    p.add_argument("--luxcore-rr-depth", type=int, default=None,
                   help="verification only: set path.russianroulette.depth directly")
    p.add_argument("--render-lossless-media", action="store_true",
                   help="verification only: render an unlimited depth in a lossless scattering medium instead of "
                        "refusing it")
    p.add_argument("--luxcore-epsilon-min", type=float, default=None,
                   help="verification only: set LuxCore's minimum ray epsilon (scene.epsilon.min) directly")
    return p.parse_args(argv)


def check_supported(s):
    """Raises Unsupported for everything LuxCore cannot express; returns the world medium."""
    for i, m in enumerate(s["materials"]):
        t = m.get("type")
        if t == "ward":
            raise Unsupported(f"material {i}: ward: LuxCore has no Ward BRDF")
        if t == "conductor":
            if m.get("perfect") and m["alpha_x"] == 0 and m["alpha_y"] == 0:
                continue
            if m["alpha_x"] > 0 or m["alpha_y"] > 0:
                raise Unsupported(f"material {i}: rough conductor (alpha {m['alpha_x']}, {m['alpha_y']}): LuxCore's "
                                  "metal2 uses Schlick's 1994 microfacet distribution, not GGX")
            raise Unsupported(f"material {i}: smooth conductor with complex index: LuxCore's mirror has no "
                              "Fresnel term and metal2 is a Schlick-distribution microfacet model")
        elif t == "dielectric":
            if not m["ior"] > 0:
                raise Invalid(f"material {i}: ior {m['ior']} must be > 0")
            if m["alpha"] > 0:
                raise Unsupported(f"material {i}: rough dielectric (alpha {m['alpha']}): LuxCore's roughglass "
                                  "uses Schlick's 1994 microfacet distribution, not GGX")
        elif t not in ("diffuse", "null"):
            raise Unsupported(f"material {i}: unknown type {t!r}")
    for i, md in enumerate(s["media"]):
        ph = md["phase"]
        if ph["type"] == "rayleigh":
            raise Unsupported(f"medium {i}: Rayleigh phase function: LuxCore has none")
        if ph["type"] == "hg" and ph["g"] != 0:
            raise Unsupported(f"medium {i}: Henyey-Greenstein g = {ph['g']}: LuxCore's volumes use Schlick's "
                              "approximation of HG (k = 1.55 g - 0.55 g^3), a different phase function")
        if ph["type"] not in ("isotropic", "hg"):
            raise Unsupported(f"medium {i}: phase {ph['type']!r}")
    bounded = set()
    for i, sh in enumerate(s["shapes"]):
        if sh["type"] not in ("mesh", "sphere"):
            raise Unsupported(f"shape {i}: unknown type {sh['type']!r}")
        em = sh.get("emission")
        if em is not None:
            if em.get("two_sided"):
                raise Unsupported(f"shape {i}: two-sided emission: LuxCore's triangle lights emit on the "
                                  "normal's side only")
            if s["materials"][sh["material"]]["type"] == "null":
                raise Unsupported(f"shape {i}: emission on a null (index-matched) boundary")
        if sh.get("interior") is not None:
            bounded.add(sh["interior"])
    for l in s["lights"]:
        if l["type"] not in ("point", "environment"):
            raise Unsupported(f"light type {l['type']!r}")
    cm = s["camera"].get("medium")
    return cm if (cm is not None and cm not in bounded) else None


def luxcore_depth(depth, unlimited):
    """furnace bounces D (-1 = unlimited) -> (path.pathdepth.total, depth-zero mode)."""
    if depth < 0:
        return unlimited + 1, False
    if depth == 0:
        return 1, True
    return depth + 1, False


def fmt(v):
    return " ".join(repr(float(x)) for x in v)


class Builder:
    def __init__(self, pyluxcore, s, args, depth_zero):
        self.lx, self.s, self.args, self.depth_zero = pyluxcore, s, args, depth_zero
        self.props = []  # (key, value-string) in order, for the sidecar
        self.materials = {}
        self.sphere_notes = []

    def set(self, key, value):
        self.props.append((key, value))

    def properties(self, keys_prefix=None):
        p = self.lx.Properties()
        for k, v in self.props:
            if keys_prefix is None or k.startswith(keys_prefix):
                p.SetFromString(f"{k} = {v}\n")
        return p

    def volumes(self):
        for i, md in enumerate(self.s["media"]):
            sa = vec(md["sigma_a_rgb"], 3, f"medium {i} sigma_a_rgb")
            ss = vec(md["sigma_s_rgb"], 3, f"medium {i} sigma_s_rgb")
            if self.depth_zero:  # no in-scattering at depth 0; extinction stays
                sa, ss = [a + b for a, b in zip(sa, ss)], [0.0, 0.0, 0.0]
            k = f"scene.volumes.vol{i}"
            self.set(f"{k}.type", '"homogeneous"')
            self.set(f"{k}.absorption", fmt(sa))
            self.set(f"{k}.scattering", fmt(ss))
            self.set(f"{k}.asymmetry", "0.0 0.0 0.0")
            self.set(f"{k}.multiscattering", "1")
            self.set(f"{k}.ior", "1.0")

    def material(self, sh):
        key = (sh["material"], repr(sh.get("emission")), sh.get("interior"), sh.get("exterior"))
        if key in self.materials:
            return self.materials[key]
        name = f"mat{len(self.materials)}"
        k = f"scene.materials.{name}"
        mat = self.s["materials"][sh["material"]]
        t = mat["type"]
        if t == "null":
            self.set(f"{k}.type", '"null"')
        elif self.depth_zero:
            self.set(f"{k}.type", '"matte"')
            self.set(f"{k}.kd", "0.0 0.0 0.0")
        elif t == "diffuse":
            self.set(f"{k}.type", '"matte"')
            self.set(f"{k}.kd", fmt(vec(mat["rgb"], 3, "rgb")))
        elif t == "conductor":  # perfect and smooth (check_supported)
            self.set(f"{k}.type", '"mirror"')
            self.set(f"{k}.kr", "1.0 1.0 1.0")
        elif t == "dielectric":
            self.set(f"{k}.type", '"glass"')
            self.set(f"{k}.kr", "1.0 1.0 1.0")
            self.set(f"{k}.kt", "1.0 1.0 1.0")
            self.set(f"{k}.interiorior", repr(float(mat["ior"])))
            self.set(f"{k}.exteriorior", "1.0")
        em = sh.get("emission")
        if em is not None:
            self.set(f"{k}.emission", fmt(vec(em["rgb"], 3, "emission.rgb")))
            self.set(f"{k}.emission.gain", "1.0 1.0 1.0")
            self.set(f"{k}.emission.gain.normalizebycolor", "0")
            self.set(f"{k}.emission.power", "0.0")
            self.set(f"{k}.emission.efficiency", "0.0")
            self.set(f"{k}.emission.normalizebycolor", "0")
            self.set(f"{k}.emission.theta", "90.0")
        if sh.get("interior") is not None:
            self.set(f"{k}.volume.interior", f'"vol{sh["interior"]}"')
        if sh.get("exterior") is not None:
            self.set(f"{k}.volume.exterior", f'"vol{sh["exterior"]}"')
        self.materials[key] = name
        return name

    def shapes(self, scene):
        for i, sh in enumerate(self.s["shapes"]):
            if sh["type"] == "mesh":
                pos = [tuple(vec(p, 3, f"shape {i} position")) for p in sh["positions"]]
                tris = [tuple(t) for t in sh["triangles"]]
            else:
                pos, tris, note = sj.tessellate_sphere(sh, self.args.sphere_subdiv)
                pos, tris = [tuple(p) for p in pos], [tuple(t) for t in tris]
                note = {"shape": i, **note, "why": "LuxCore has no analytic sphere"}
                self.sphere_notes.append(note)
                print(f"note: shape {i}: sphere tessellated ({note['geometry']}); the faces lie up to "
                      f"{note['max_radial_deviation_relative']:.3g} r = {note['max_radial_deviation']:.3g} "
                      "scene units inside the sphere", file=sys.stderr)
            if not tris:
                continue
            scene.DefineMesh(f"mesh{i}", pos, tris, None, None, None, None)
            mat = self.material(sh)
            self.set(f"scene.objects.obj{i}.shape", f'"mesh{i}"')
            self.set(f"scene.objects.obj{i}.material", f'"{mat}"')

    def lights(self, world_medium):
        for i, l in enumerate(self.s["lights"]):
            k = f"scene.lights.light{i}"
            if l["type"] == "environment":
                self.set(f"{k}.type", '"constantinfinite"')
                self.set(f"{k}.color", fmt(vec(l["radiance_rgb"], 3, "radiance_rgb")))
                self.set(f"{k}.gain", "1.0 1.0 1.0")
            else:
                self.set(f"{k}.type", '"point"')
                self.set(f"{k}.position", fmt(vec(l["position"], 3, "position")))
                self.set(f"{k}.color", fmt([4 * math.pi * v for v in vec(l["intensity_rgb"], 3, "intensity_rgb")]))
                self.set(f"{k}.gain", "1.0 1.0 1.0")
                self.set(f"{k}.power", "0.0")
                self.set(f"{k}.efficiency", "0.0")
                self.set(f"{k}.normalizebycolor", "0")
        if world_medium is not None:
            self.set("scene.world.volume.default", f'"vol{world_medium}"')

    def camera(self, width, height):
        c = self.s["camera"]
        pos, fwd, right, up = sj.camera_frame(c)
        a = width / height
        self.set("scene.camera.type", '"perspective"')
        self.set("scene.camera.lookat.orig", fmt(pos))
        self.set("scene.camera.lookat.target", fmt(sj.add(pos, fwd)))
        self.set("scene.camera.up", fmt(up))
        self.set("scene.camera.fieldofview", repr(float(c["fov_y_deg"])))
        # One pixel lower than (-a, a, -1, 1): PerspectiveCamera::InitRay maps film y to raster
        # H - y - 1 instead of H - y, which would shift the image down by one pixel.
        dy = 2.0 / height
        self.set("scene.camera.screenwindow", fmt([-a, a, -1.0 - dy, 1.0 - dy]))
        self.set("scene.camera.lensradius", "0.0")
        self.set("scene.camera.cliphither", repr(1e-6 * sj.scene_extent(self.s)))
        self.set("scene.camera.clipyon", "1e30")
        self.set("scene.camera.autovolume.enable", "0")
        if c.get("medium") is not None:
            self.set("scene.camera.volume", f'"vol{c["medium"]}"')


def config_props(width, height, spp, seed, pathdepth, threads, rr_depth):
    return [
        ("renderengine.type", '"PATHCPU"'),
        ("renderengine.seed", str(seed + 1)),
        ("native.threads.count", str(threads)),
        ("sampler.type", '"RANDOM"'),
        ("sampler.random.adaptive.strength", "0.0"),
        ("lightstrategy.type", '"UNIFORM"'),
        ("path.pathdepth.total", str(pathdepth)),
        ("path.pathdepth.diffuse", str(pathdepth)),
        ("path.pathdepth.glossy", str(pathdepth)),
        ("path.pathdepth.specular", str(pathdepth)),
        ("path.russianroulette.depth", str(rr_depth)),
        ("path.russianroulette.cap", "0.5"),
        ("path.clamping.variance.maxvalue", "0.0"),
        ("path.forceblackbackground.enable", "0"),
        ("path.hybridbackforward.enable", "0"),
        ("film.width", str(width)),
        ("film.height", str(height)),
        ("film.filter.type", '"BOX"'),
        ("film.filter.width", "0.5"),
        ("film.outputs.0.type", '"RGB"'),
        ("film.outputs.0.filename", '"unused.exr"'),
        ("batch.haltspp", str(spp)),
        ("batch.halttime", "0"),
    ]


def write_exr(path, rgb):
    import OpenEXR
    import numpy as np
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    chans = {c: np.ascontiguousarray(rgb[:, :, k], dtype=np.float32) for k, c in enumerate("RGB")}
    OpenEXR.File(header, chans).write(path)


def main(argv=None):
    args = parse_args(argv)
    try:
        s = sj.load_scene(args.scene)
        width, height, spp, depth = sj.resolve_render(args, s)
        world_medium = check_supported(s)
    except Unsupported as e:
        return sj.unsupported(e)
    except (Invalid, KeyError, TypeError, ValueError) as e:
        return sj.invalid(e)
    pathdepth, depth_zero = luxcore_depth(depth, args.unlimited_depth)
    if args.luxcore_pathdepth is not None:
        pathdepth, depth_zero = args.luxcore_pathdepth, False
    truncation = None
    if depth < 0 and args.luxcore_pathdepth is None:
        truncation = sj.truncation(s, args.unlimited_depth)
        a, bound = truncation["max_albedo"], truncation["tail_bound_relative"]
        if bound is not None and bound > args.max_truncation:
            return sj.unsupported(
                f"an unlimited depth: with roulette off (LuxCore 2.11.2's roulette biases its MIS) paths end "
                f"at {args.unlimited_depth} bounces, and the bound a^(K+1)/(1-a) on the share of the radiance "
                f"that misses is {bound:.2g} at albedo a = {a:g} (above --max-truncation "
                f"{args.max_truncation:g}); give a finite --max-depth or a larger --unlimited-depth")
        lossless = [i for i, md in enumerate(s["media"])
                    if any(ss > 0 and sa == 0 for sa, ss in zip(md["sigma_a_rgb"], md["sigma_s_rgb"]))]
        if lossless and not args.render_lossless_media:
            return sj.unsupported(
                f"an unlimited depth in a lossless scattering medium (medium {lossless[0]}): paths scatter about "
                f"(optical radius)^2 times and the loss to the {args.unlimited_depth}-bounce truncation has no "
                f"bound; and LuxCore 2.11.2 gains energy along long paths in such a medium (null-bounded "
                f"sphere, sigma_s 4, 2048 bounces: 2.93 +- 0.14 for 1; reports/renderers/four/FINDINGS.md)")

    # numpy and OpenEXR must be imported before pyluxcore: its wheel preloads TBB's malloc proxy, and
    # an extension loaded after it aborts with "free(): invalid pointer" (pyluxcore 2.11.2).
    import numpy as np
    import OpenEXR  # noqa: F401
    t0 = time.perf_counter()
    import pyluxcore
    pyluxcore.Init(lambda msg: None)  # LuxCore's log goes nowhere (it is verbose)
    b = Builder(pyluxcore, s, args, depth_zero)
    scene = pyluxcore.Scene()
    try:
        b.volumes()
        b.shapes(scene)
        b.lights(world_medium)
        b.camera(width, height)
    except (Invalid, KeyError, TypeError, ValueError) as e:
        return sj.invalid(e)
    scene.Parse(b.properties("scene."))
    rr_depth = RR_OFF if args.luxcore_rr_depth is None else args.luxcore_rr_depth
    cfg_list = config_props(width, height, spp, args.seed, pathdepth, args.threads, rr_depth)
    # LuxCore's ray epsilons are absolute lengths (defaults 1e-5 and 0.1, for scenes metres
    # across); a scene smaller than 1 unit gets both scaled by its extent, as a user modelling
    # at that scale would set them (measured: at scale 1e-4 the default 1e-5 reads the
    # concave furnace -3 % and the area light -13 %; reports/renderers/four/FINDINGS.md)
    extent = sj.scene_extent(s)
    if extent < 1.0:
        cfg_list += [("scene.epsilon.min", repr(1e-5 * extent)), ("scene.epsilon.max", repr(0.1 * extent))]
    if args.luxcore_epsilon_min is not None:
        cfg_list.append(("scene.epsilon.min", repr(args.luxcore_epsilon_min)))
    cfg = pyluxcore.Properties()
    for k, v in cfg_list:
        cfg.SetFromString(f"{k} = {v}\n")
    config = pyluxcore.RenderConfig(cfg, scene)
    session = pyluxcore.RenderSession(config)
    t_load = time.perf_counter() - t0
    t0 = time.perf_counter()
    session.Start()
    while True:
        time.sleep(0.05)
        session.UpdateStats()
        if session.HasDone():
            break
    session.Stop()
    t_render = time.perf_counter() - t0
    stats = session.GetStats()
    film = session.GetFilm()
    buf = np.zeros(width * height * 3, dtype=np.float32)
    film.GetOutputFloat(pyluxcore.FilmOutputType.RGB, buf)
    rgb = buf.reshape(height, width, 3)[::-1]  # LuxCore's row 0 is the bottom
    total = float(stats.Get("stats.renderengine.total.samplecount").GetFloat())  # haltspp may overshoot
    out, stem = sj.out_paths(args.out)
    write_exr(out, rgb)

    sj.write_sidecar(stem, {
        "renderer": "luxcore",
        "version": pyluxcore.Version(),
        "scene": os.path.abspath(args.scene),
        "spp": spp, "seed": args.seed, "luxcore_seed": args.seed + 1, "width": width, "height": height,
        "threads": args.threads,
        "samples_total": total,
        "spp_measured": (total / (width * height)) if total else None,
        "max_depth_furnace": depth,
        "pathdepth_total_luxcore": pathdepth,
        "depth_mapping": "path.pathdepth.total = furnace bounces + 1; furnace 0 = every BSDF dropped (emission "
                         "only, volumes absorb sigma_a + sigma_s); unlimited = --unlimited-depth bounces",
        "russian_roulette": "off" if rr_depth >= RR_OFF else f"on from depth {rr_depth} (verification only)",
        "unlimited_truncation": truncation,
        "depth_zero_mode": "BSDFs dropped, emission only" if depth_zero else None,
        "depth_override": args.luxcore_pathdepth is not None,
        "config": dict(cfg_list),
        "scene_properties": dict(b.props) if len(b.props) < 2000 else f"{len(b.props)} properties",
        "spheres": b.sphere_notes,
        "world_medium": world_medium,
        "rgb_space": "linear RGB as given (the scene JSON's linear sRGB / Rec.709), radiance in the scene JSON's "
                     "units (an emitter of rgb c reads c); compare with furnace's observer cie1931",
        "channels": ["R", "G", "B"],
        "time_s": t_render,
        "load_time_s": t_load,
        "samples_per_second": (total or width * height * spp) / t_render,
        "luxcore_stats": {k: stats.Get(k).GetValuesString() for k in stats.GetAllNames()
                          if k.startswith("stats.renderengine")},
    })
    # A Python log handler still installed at interpreter exit aborts (GIL not held); remove it.
    pyluxcore.SetLogHandler(None)
    print(f"luxcore {pyluxcore.Version()}: {width}x{height} @ {spp} spp "
          f"(measured {total / (width * height) if total else '?'}), pathdepth={pathdepth}"
          f"{' (depth 0: emission only)' if depth_zero else ''}, seed={args.seed + 1}, threads={args.threads}: "
          f"{t_render:.2f} s; wrote {out}, {stem}.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
