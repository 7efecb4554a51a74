#!/usr/bin/env python3
"""Render a furnace scene interchange JSON (docs/scene-json.md, version 1) with Blender Cycles.

Runs with Blender's Python module (`pip install bpy==5.0.1`, Python 3.11; see README.md next to
this script), builds the scene with bpy, renders one image on the CPU and writes <out> (OpenEXR,
channels R, G, B, 32-bit float, linear Rec.709 = furnace's linear sRGB, no view transform) and
<stem>.json (sidecar: renderer, version, every setting used, wall time).

Anything Cycles cannot express is refused: one line `unsupported: <what and why>` on stderr and
exit code 3. Invalid input (bad JSON, wrong format/version, bad CLI) exits 2.

Settings that make the render comparable with furnace (each read back into the sidecar):
  * Path depth. furnace's max_depth D counts bounces (0 = emitters seen directly, 1 = direct
    light, -1/null = unlimited). Cycles' `max_bounces` = B gives emission seen directly PLUS
    next-event estimation at the first hit PLUS B further bounces, i.e. Cycles' B = furnace's
    D - 1 (measured: closed box E = 1, R = 0.5 reads 1.5 at B = 0, 1.75 at B = 1, 1.875 at
    B = 2; reference/cycles/README.md). D = 0 therefore has no Cycles setting of its own: it is
    rendered exactly by dropping every BSDF (surfaces keep only their emission, so nothing is
    reflected, and paths end at the first hit) and by turning volumes into pure absorbers of
    sigma_a + sigma_s (extinction stays, in-scattering goes); the sidecar says so
    (`depth_zero_mode`).
    Unlimited = 1024, Cycles' largest value (Russian roulette ends paths first; P(1024 bounces
    at albedo <= 0.9) ~ 1e-47). The per-type caps (diffuse, glossy, transmission, volume) are set
    to the same value so only the total counts; transparent bounces (null boundaries) get 1024
    and are not bounces, as in furnace; min_light_bounces = min_transparent_bounces = 0.
    Source: Blender manual, Cycles > Render Settings > Light Paths
    (docs.blender.org/manual/en/latest/render/cycles/render_settings/light_paths.html).
  * Clamping off: sample_clamp_direct = sample_clamp_indirect = 0 (0 disables; manual, Light Paths
    > Clamping). filter_glossy (`blur_glossy`) = 0; caustics_reflective = caustics_refractive =
    True (manual, Light Paths > Caustics).
  * No denoiser (use_denoising = False), no adaptive sampling (use_adaptive_sampling = False),
    light threshold light_sampling_threshold = 0, light tree off (use_light_tree = False), path
    guiding off, no time limit, direct light sampling = multiple importance sampling (as furnace)
    (manual, Cycles > Render Settings > Sampling).
  * Sampler: `sampling_pattern` = TABULATED_SOBOL with scrambling distance 1 (fully decorrelated
    pixels; blue-noise patterns would correlate neighbouring pixels); `seed` = --seed, animated
    seed off; the seed changes the pattern's scrambling (manual, Sampling > Advanced > Seed).
    Tabulated Sobol is quasi-random: one render's pixel noise is not i.i.d. sampling noise, but
    renders with different seeds are independent, which is what furnace's batches use.
  * Pixel filter: BOX, filter_width = 1.0 pixel (manual, Cycles > Render Settings > Film).
  * CPU device, --threads worker threads (render.threads_mode = FIXED).
  * Colour: working space Linear Rec.709 (Blender 5.0's default for a new file;
    read-only in bpy, so checked), view transform
    Standard, look None, exposure 0, gamma 1, film_exposure 1; the EXR holds the scene-linear
    render result (float formats skip the view transform; image output colour management
    overridden to Linear Rec.709 to be explicit). Verified: an emitter of rgb (17, 12, 4) seen
    directly reads exactly (17, 12, 4).
  * No motion blur, no compositing, no sequencer, dither 0, film not transparent.

Scene mapping (docs/scene-json.md):
  * Camera: pinhole; Blender cameras look down their local -Z with +Y up, so the object matrix has
    columns (right, up', -forward) with right = forward x up (image x to the camera's right) and
    up' = right x forward; sensor_fit VERTICAL, angle_y = fov_y. clip_start = 1e-6 x scene extent
    (Blender's minimum 1e-6), clip_end = 1e6 x extent.
  * Triangles: one Blender face each, vertices in the given order, so Blender's face normal
    (counter-clockwise winding) is (b - a) x (c - a) as in the JSON; flat shading.
  * Spheres: Cycles' analytic sphere is a point-cloud point (ray-sphere intersection), made here
    with a Geometry Nodes "Mesh to Points" modifier; its normal points outwards and flip_normals
    swaps the Backfacing test. Cycles intersects such a point only from OUTSIDE (measured: a camera
    inside a point sphere sees straight through it, 0 instead of 2 in the furnace-sphere test),
    so it is used only for diffuse and conductor spheres that do not contain the camera (no path
    can then be inside). Every other sphere (dielectric, null/medium boundary, or around the
    camera) is an icosphere of level --sphere-subdiv (default 7: 327 680 flat triangles, vertices
    on the sphere, faces at most 1.8e-5 r inside it), stated on stderr and in the sidecar
    (`spheres`).
  * diffuse -> Diffuse BSDF (roughness 0 = Lambert; two-sided in Cycles).
  * conductor -> Metallic BSDF, distribution GGX (single scattering, like furnace), fresnel_type
    PHYSICAL_CONDUCTOR with IOR = eta_rgb and Extinction = k_rgb per channel (the complex Fresnel
    equations per RGB channel; manual, Shader Nodes > Metallic BSDF). perfect -> Glossy BSDF GGX
    of colour 1 (Glossy BSDF has no Fresnel term: reflectance 1 at every angle). Cycles'
    roughness r gives alpha = r^2 (Cycles squares the node's Roughness before the microfacet
    closure: intern/cycles/kernel/svm/closure.h; not measured here), so roughness = sqrt(alpha). alpha_x != alpha_y is refused: the JSON gives no tangent frame.
  * dielectric -> Glass BSDF, GGX, IOR = ior (the side opposite the normal is inside, as Cycles
    assumes: hitting a back face uses 1/IOR), roughness = sqrt(alpha). Cycles' refraction does NOT
    scale radiance by 1/eta^2 (furnace's does): measured with the camera at the centre of a glass
    sphere (ior 1.5) under an environment of 1, Cycles reads 1.000, furnace's convention 2.25. The
    two agree when every path starts and ends in the same medium (camera and lights outside all
    dielectrics), so a scene whose camera or an emitter lies inside a dielectric is refused.
  * null -> no surface shader: Cycles treats the object as a pure volume boundary (or an
    invisible one without a medium).
  * ward -> refused (Cycles has no Ward BRDF).
  * emission: Emission shader of colour rgb, strength 1, added to the BSDF. One-sided: mixed
    with black by Geometry > Backfacing (the back of the emitter is black, the BSDF stays), and
    the material's emission_sampling = FRONT (BACK when flipped, FRONT_BACK when two-sided).
  * point light -> POINT light, radius (shadow_soft_size) 0, soft falloff off, exposure 0,
    colour = intensity_rgb / m, energy = m * 4 pi [W] with m = max channel: Cycles' point light of
    power P W has radiant intensity P / (4 pi) W/sr in render units (verified: a point light of
    intensity 1 over a diffuse plane of albedo 0.5 at distance 1 reads 0.5/pi; README).
  * environment -> World Background of colour radiance_rgb, strength 1 (pixel = radiance).
  * media -> Volume Coefficients node (Blender 5.0): Absorption Coefficients = sigma_a_rgb,
    Scatter Coefficients = sigma_s_rgb (per scene unit), phase Henyey-Greenstein with
    Anisotropy = g (isotropic: g = 0) or Rayleigh (manual, Shader Nodes > Volume Coefficients /
    Volume Scatter). A medium is the interior of the shape(s) naming it, or, when no shape
    bounds it and it is the camera's medium, the World volume. Cycles adds the coefficients of
    overlapping volumes (its volume stack), so nested media are refused, and so is a
    transmissive (dielectric or null) shape whose exterior is a medium.

Example:
    ~/venvs/cycles/bin/python reference/cycles/render.py --scene scene.json --out /tmp/x.exr \
        --spp 64 --width 64 --height 64 --seed 1 --max-depth -1 --threads 2
"""

import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scene_json as sj  # noqa: E402  (shared with reference/luxcore/render.py)
from scene_json import Invalid, Unsupported, vec  # noqa: E402

UNLIMITED_BOUNCES = 1024  # Cycles' largest max_bounces


def parse_args(argv=None):
    p = sj.parser(__doc__.split("\n")[0], default_subdiv=7)
    p.add_argument("--cycles-max-bounces", type=int, default=None,
                   help="verification only: set Cycles' max_bounces directly, bypassing the depth mapping")
    p.add_argument("--max-truncation", type=float, default=1e-4,
                   help="largest relative bound on the energy an unlimited depth loses to Cycles' 1024-bounce "
                        "limit (a^(K+1)/(1-a) at K = 1025 furnace bounces, for the largest albedo a < 1); above "
                        "it the scene is refused, not rendered low (default: %(default)s)")
    p.add_argument("--no-emitter-sampling", action="store_true",
                   help="verification only: no light sampling of emissive surfaces (every emitter material's "
                        "emission_sampling = NONE), so Cycles finds them by BSDF sampling alone")
    p.add_argument("--allow-eta-mismatch", action="store_true",
                   help="verification only: render a camera or emitter inside a dielectric instead of refusing")
    return p.parse_args(argv)


def subpixels(width, height, spp):
    """Blender renders at least 4 x 4 pixels (a 1 x 1 request came back 4 x 4). A smaller image is
    rendered with each pixel split into f x f sub-pixels of the same camera (the image plane is
    unchanged) at spp / f^2 samples each, and the sub-pixels are averaged: with a one-pixel box
    filter that is the same estimate of the same pixel. Returns f (1 for images of 4 px or more)."""
    f = 1 if min(width, height) >= 4 else -(-4 // min(width, height))
    if spp % (f * f):
        raise Unsupported(f"a {width}x{height} image: Blender renders at least 4x4 px, so each pixel is "
                          f"{f}x{f} sub-pixels, and {spp} spp is not a multiple of {f * f}")
    return f


def read_exr_uncompressed(path):
    """(width, height, {channel: [float] row-major from the top}) of a scanline OpenEXR file with
    NO compression and FLOAT channels, as Blender writes with exr_codec NONE (OpenEXR file
    layout: magic, version, header attributes name/type/size/value, offset table, then per
    scanline block y, size and each channel's row in name order)."""
    import struct
    data = open(path, "rb").read()
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError(f"{path}: not an OpenEXR file")
    flags = struct.unpack_from("<I", data, 4)[0]
    if flags & 0x200 or flags & 0x1000:
        raise ValueError(f"{path}: tiled or multi-part EXR")
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        tend = data.index(b"\0", end + 1)
        size = struct.unpack_from("<i", data, tend + 1)[0]
        attrs[name] = data[tend + 5:tend + 5 + size]
        pos = tend + 5 + size
    pos += 1
    if attrs["compression"][0] != 0:
        raise ValueError(f"{path}: compressed EXR (need exr_codec NONE)")
    chans, q, cl = [], 0, attrs["channels"]
    while cl[q] != 0:
        end = cl.index(b"\0", q)
        ptype = struct.unpack_from("<i", cl, end + 1)[0]
        if ptype != 2:
            raise ValueError(f"{path}: channel pixel type {ptype}, need FLOAT (2)")
        chans.append(cl[q:end].decode())
        q = end + 1 + 16
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    offsets = struct.unpack_from(f"<{h}Q", data, pos)
    planes = {c: [0.0] * (w * h) for c in chans}
    for off in offsets:
        y, _size = struct.unpack_from("<2i", data, off)
        row = y - y0
        at = off + 8
        for c in chans:
            planes[c][row * w:(row + 1) * w] = struct.unpack_from(f"<{w}f", data, at)
            at += 4 * w
    return w, h, planes


def box_average(plane, big_w, f):
    """The mean of each f x f block of a row-major image `big_w` wide."""
    w, h = big_w // f, len(plane) // big_w // f
    return [math.fsum(plane[(y * f + j) * big_w + x * f + i] for j in range(f) for i in range(f)) / (f * f)
            for y in range(h) for x in range(w)]


def write_exr_float_rgb(path, width, height, planes):
    """Writes R, G, B (row-major from the top) as an uncompressed scanline OpenEXR of FLOAT
    channels (the layout read_exr_uncompressed reads)."""
    import struct

    def attr(name, typ, value):
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(value)) + value
    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<4i", 0, 0, width - 1, height - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + attr("channels", "chlist", chlist)
              + attr("compression", "compression", b"\0") + attr("dataWindow", "box2i", box)
              + attr("displayWindow", "box2i", box) + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
              + attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    block = 8 + 3 * 4 * width
    start = len(header) + 8 * height
    body = struct.pack(f"<{height}Q", *(start + y * block for y in range(height)))
    for y in range(height):
        body += struct.pack("<2i", y, 3 * 4 * width)
        for c in "BGR":
            body += struct.pack(f"<{width}f", *planes["RGB".index(c)][y * width:(y + 1) * width])
    tmp = path + ".part"
    with open(tmp, "wb") as f:
        f.write(header + body)
    os.replace(tmp, path)


def check_supported(s, allow_eta_mismatch=False):
    """Raises Unsupported for everything Cycles cannot express (before Blender is touched);
    returns the medium that fills the world (the camera's, bounded by no shape), if any."""
    mats, media = s["materials"], s["media"]
    for i, m in enumerate(mats):
        t = m.get("type")
        if t == "ward":
            raise Unsupported(f"material {i}: ward: Cycles has no Ward BRDF")
        if t == "conductor":
            if m["alpha_x"] != m["alpha_y"]:
                raise Unsupported(f"material {i}: anisotropic conductor (alpha_x {m['alpha_x']} != alpha_y "
                                  f"{m['alpha_y']}): scene JSON v1 gives no tangent frame to orient it")
        elif t == "dielectric":
            if not m["ior"] > 0:
                raise Invalid(f"material {i}: ior {m['ior']} must be > 0")
        elif t not in ("diffuse", "null"):
            raise Unsupported(f"material {i}: unknown type {t!r}")
    for i, md in enumerate(media):
        ph = md["phase"]["type"]
        if ph not in ("isotropic", "hg", "rayleigh"):
            raise Unsupported(f"medium {i}: phase {ph!r}")
        if ph == "hg" and not (-1 < md["phase"]["g"] < 1):
            raise Unsupported(f"medium {i}: hg g = {md['phase']['g']} outside (-1, 1)")
    bounded = set()
    for i, sh in enumerate(s["shapes"]):
        if sh["type"] not in ("mesh", "sphere"):
            raise Unsupported(f"shape {i}: unknown type {sh['type']!r}")
        mat = mats[sh["material"]]
        transmissive = mat["type"] in ("dielectric", "null")
        inner, outer = sh.get("interior"), sh.get("exterior")
        if inner is not None and transmissive:
            bounded.add(inner)
            if outer is not None:
                raise Unsupported(f"shape {i}: nested media (interior {inner}, exterior {outer}): Cycles adds "
                                  "the coefficients of overlapping volumes instead of replacing them")
        if outer is not None and transmissive:
            raise Unsupported(f"shape {i}: a {mat['type']} surface with exterior medium {outer} and interior "
                              f"{inner}: Cycles would keep the outer volume inside the shape (volume stack)")
        em = sh.get("emission")
        if em is not None and mat["type"] == "null":
            raise Unsupported(f"shape {i}: emission on a null (index-matched) boundary")
    cam_medium = s["camera"].get("medium")
    world_medium = cam_medium if (cam_medium is not None and cam_medium not in bounded) else None
    for i, sh in enumerate(s["shapes"]):
        outer = sh.get("exterior")
        if outer is not None and outer not in bounded and outer != world_medium:
            raise Unsupported(f"shape {i}: exterior medium {outer} is bounded by no shape and is not the "
                              "camera's medium: Cycles cannot place it")
    envs = [l for l in s["lights"] if l["type"] == "environment"]
    if len(envs) > 1:
        raise Unsupported(f"{len(envs)} environment lights: Cycles has one World")
    for l in s["lights"]:
        if l["type"] not in ("point", "environment"):
            raise Unsupported(f"light type {l['type']!r}")
        if world_medium is not None and l["type"] == "environment":
            raise Unsupported("an environment light seen through a world-filling medium")
    # Cycles' refraction does not scale radiance by 1/eta^2 (measured: a camera at the centre of a
    # glass sphere of ior 1.5 under an environment of 1 reads 1.000, furnace 2.25), so images
    # differ whenever a path starts and ends in media of different index: refuse those.
    where = [("the camera", s["camera"]["position"])] + sj.emitter_points(s)
    for what, p in where:
        k = None if allow_eta_mismatch else sj.inside_dielectric(s, p)
        if k is not None:
            raise Unsupported(f"{what} lies inside dielectric shape {k}: Cycles does not scale radiance by "
                              "1/eta^2 at refraction (furnace does), so this image would differ by eta^2")
    return world_medium


def cycles_bounces(depth):
    """furnace bounces D (-1 = unlimited) -> (Cycles max_bounces, depth-zero mode)."""
    if depth > UNLIMITED_BOUNCES + 1:
        raise Unsupported(f"max_depth {depth}: Cycles' max_bounces is at most {UNLIMITED_BOUNCES} "
                          f"(furnace depth {UNLIMITED_BOUNCES + 1}); Blender would clamp it silently")
    if depth < 0:
        return UNLIMITED_BOUNCES, False
    if depth == 0:
        return 0, True
    return depth - 1, False


class Builder:
    def __init__(self, bpy, s, args, depth_zero):
        self.bpy, self.s, self.args, self.depth_zero = bpy, s, args, depth_zero
        self.materials = {}
        self.sphere_notes = []
        self.volume_mats = {}

    # -- materials --------------------------------------------------------------------------
    def _new_material(self, name):
        bpy = self.bpy
        m = bpy.data.materials.new(name)
        if not m.node_tree:
            m.use_nodes = True
        nt = m.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        out.target = "CYCLES"
        return m, nt, out

    def _volume_node(self, nt, medium_index):
        md = self.s["media"][medium_index]
        v = nt.nodes.new("ShaderNodeVolumeCoefficients")
        v.inputs["Absorption Coefficients"].default_value = vec(md["sigma_a_rgb"], 3, "sigma_a_rgb")
        v.inputs["Scatter Coefficients"].default_value = vec(md["sigma_s_rgb"], 3, "sigma_s_rgb")
        v.inputs["Emission Coefficients"].default_value = (0.0, 0.0, 0.0)
        if self.depth_zero:  # depth 0: no in-scattering, extinction stays
            v.inputs["Absorption Coefficients"].default_value = [
                a + b for a, b in zip(vec(md["sigma_a_rgb"], 3, "sigma_a_rgb"), vec(md["sigma_s_rgb"], 3, "sigma_s_rgb"))]
            v.inputs["Scatter Coefficients"].default_value = (0.0, 0.0, 0.0)
        ph = md["phase"]
        if ph["type"] == "rayleigh":
            v.phase = "RAYLEIGH"
        else:
            v.phase = "HENYEY_GREENSTEIN"
            v.inputs["Anisotropy"].default_value = float(ph["g"]) if ph["type"] == "hg" else 0.0
        return v

    def _bsdf(self, nt, mat, flip):
        t = mat["type"]
        if t == "diffuse":
            n = nt.nodes.new("ShaderNodeBsdfDiffuse")
            n.inputs["Color"].default_value = (*vec(mat["rgb"], 3, "rgb"), 1.0)
            n.inputs["Roughness"].default_value = 0.0
            return n
        if t == "conductor":
            alpha = float(mat["alpha_x"])
            if mat.get("perfect"):
                n = nt.nodes.new("ShaderNodeBsdfGlossy")
                n.distribution = "GGX"
                n.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
                n.inputs["Anisotropy"].default_value = 0.0
            else:
                n = nt.nodes.new("ShaderNodeBsdfMetallic")
                n.distribution = "GGX"
                n.fresnel_type = "PHYSICAL_CONDUCTOR"
                n.inputs["IOR"].default_value = vec(mat["eta_rgb"], 3, "eta_rgb")
                n.inputs["Extinction"].default_value = vec(mat["k_rgb"], 3, "k_rgb")
                n.inputs["Anisotropy"].default_value = 0.0
                n.inputs["Thin Film Thickness"].default_value = 0.0
            n.inputs["Roughness"].default_value = math.sqrt(alpha)
            return n
        if t == "dielectric":
            n = nt.nodes.new("ShaderNodeBsdfGlass")
            n.distribution = "GGX"
            n.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
            ior = float(mat["ior"])
            n.inputs["IOR"].default_value = 1.0 / ior if flip else ior
            n.inputs["Roughness"].default_value = math.sqrt(float(mat["alpha"]))
            n.inputs["Thin Film Thickness"].default_value = 0.0
            return n
        return None  # null

    def material(self, shape, flip):
        mat_index = shape["material"]
        em = shape.get("emission")
        inner = shape.get("interior")
        key = (mat_index, repr(em), inner, flip)
        if key in self.materials:
            return self.materials[key]
        m, nt, out = self._new_material(f"mat{len(self.materials)}")
        mat = self.s["materials"][mat_index]
        bsdf = None if self.depth_zero else self._bsdf(nt, mat, flip)
        surface = bsdf
        if em is not None:
            e = nt.nodes.new("ShaderNodeEmission")
            e.inputs["Color"].default_value = (*vec(em["rgb"], 3, "emission.rgb"), 1.0)
            e.inputs["Strength"].default_value = 1.0
            if em.get("two_sided"):
                emit = e
                m.cycles.emission_sampling = "FRONT_BACK"
            else:
                geo = nt.nodes.new("ShaderNodeNewGeometry")
                mix = nt.nodes.new("ShaderNodeMixShader")
                # Fac = Backfacing: 0 on the front -> first input (emission), 1 on the back ->
                # second input (left empty = no closure = black). Flipped: the other way round.
                nt.links.new(geo.outputs["Backfacing"], mix.inputs["Fac"])
                nt.links.new(e.outputs["Emission"], mix.inputs[2 if flip else 1])
                emit = mix
                m.cycles.emission_sampling = "BACK" if flip else "FRONT"
            if surface is None:
                surface = emit
            else:
                add = nt.nodes.new("ShaderNodeAddShader")
                nt.links.new(surface.outputs[0], add.inputs[0])
                nt.links.new(emit.outputs[0], add.inputs[1])
                surface = add
        else:
            m.cycles.emission_sampling = "NONE"
        if self.args.no_emitter_sampling:
            m.cycles.emission_sampling = "NONE"
        if surface is None and mat["type"] != "null":
            # depth 0 and no emission: a black, opaque surface (nothing is reflected).
            surface = nt.nodes.new("ShaderNodeEmission")
            surface.inputs["Strength"].default_value = 0.0
        if surface is not None:
            nt.links.new(surface.outputs[0], out.inputs["Surface"])
        if inner is not None and mat["type"] in ("dielectric", "null"):
            vol = self._volume_node(nt, inner)
            nt.links.new(vol.outputs[0], out.inputs["Volume"])
        self.materials[key] = m
        return m

    # -- shapes -----------------------------------------------------------------------------
    def add_mesh(self, name, verts, faces, material):
        bpy = self.bpy
        me = bpy.data.meshes.new(name)
        me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
        me.shade_flat()
        me.materials.append(material)
        ob = bpy.data.objects.new(name, me)
        bpy.context.scene.collection.objects.link(ob)
        return ob

    def add_point_sphere(self, name, center, radius, material):
        """An analytic sphere: a one-vertex mesh turned into one point-cloud point by Geometry
        Nodes (Mesh to Points, radius r); Cycles intersects points as true spheres."""
        bpy = self.bpy
        me = bpy.data.meshes.new(name)
        me.from_pydata([tuple(center)], [], [])
        ob = bpy.data.objects.new(name, me)
        bpy.context.scene.collection.objects.link(ob)
        ng = bpy.data.node_groups.new(name + "_points", "GeometryNodeTree")
        ng.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        ng.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        gi = ng.nodes.new("NodeGroupInput")
        go = ng.nodes.new("NodeGroupOutput")
        m2p = ng.nodes.new("GeometryNodeMeshToPoints")
        m2p.mode = "VERTICES"
        m2p.inputs["Radius"].default_value = float(radius)
        sm = ng.nodes.new("GeometryNodeSetMaterial")
        sm.inputs["Material"].default_value = material
        ng.links.new(gi.outputs[0], m2p.inputs["Mesh"])
        ng.links.new(m2p.outputs["Points"], sm.inputs["Geometry"])
        ng.links.new(sm.outputs["Geometry"], go.inputs[0])
        mod = ob.modifiers.new("points", "NODES")
        mod.node_group = ng
        return ob

    def shapes(self):
        cam = self.s["camera"]["position"]
        for i, sh in enumerate(self.s["shapes"]):
            if sh["type"] == "mesh":
                pos = [vec(p, 3, f"shape {i} position") for p in sh["positions"]]
                self.add_mesh(f"shape{i}", pos, sh["triangles"], self.material(sh, flip=False))
                continue
            c, r = vec(sh["center"], 3, "center"), float(sh["radius"])
            mtype = self.s["materials"][sh["material"]]["type"]
            cam_inside = math.dist(cam, c) <= r * (1 + 1e-9)
            if mtype in ("diffuse", "conductor") and not cam_inside:
                # Analytic: only the outside of an opaque sphere can be reached (camera outside,
                # no path enters it), and that is all a point-cloud sphere shows.
                flip = bool(sh.get("flip_normals"))
                self.add_point_sphere(f"shape{i}", c, r, self.material(sh, flip))
                self.sphere_notes.append({"shape": i, "geometry": "analytic (Cycles point-cloud point)"})
                continue
            why = "contains the camera" if cam_inside else f"is {mtype}, so rays enter it"
            pos, tris, note = sj.tessellate_sphere(sh, self.args.sphere_subdiv)
            # the winding already follows flip_normals, so the material is not flipped
            self.add_mesh(f"shape{i}", pos, tris, self.material(sh, flip=False))
            note = {"shape": i, **note, "why": f"the sphere {why}; Cycles' point-cloud spheres are hit only "
                                               "from outside"}
            self.sphere_notes.append(note)
            print(f"note: shape {i}: sphere tessellated ({note['geometry']}; it {why}); the faces lie up to "
                  f"{note['max_radial_deviation_relative']:.3g} r = {note['max_radial_deviation']:.3g} "
                  "scene units inside the sphere", file=sys.stderr)

    # -- lights, world, camera --------------------------------------------------------------
    def lights(self, world_medium):
        bpy = self.bpy
        world = bpy.data.worlds.new("world")
        bpy.context.scene.world = world
        if world.node_tree is None:  # bpy 5.0 creates it; use_nodes is deprecated
            world.use_nodes = True
        nt = world.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        out = nt.nodes.new("ShaderNodeOutputWorld")
        bg = nt.nodes.new("ShaderNodeBackground")
        bg.inputs["Strength"].default_value = 1.0
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        world.cycles.sampling_method = "NONE"
        for i, l in enumerate(self.s["lights"]):
            if l["type"] == "environment":
                bg.inputs["Color"].default_value = (*vec(l["radiance_rgb"], 3, "radiance_rgb"), 1.0)
                world.cycles.sampling_method = "AUTOMATIC"
            else:
                rgb = vec(l["intensity_rgb"], 3, "intensity_rgb")
                mx = max(rgb)
                ld = bpy.data.lights.new(f"light{i}", "POINT")
                ld.shadow_soft_size = 0.0
                ld.use_soft_falloff = False
                ld.exposure = 0.0
                ld.normalize = True
                ld.color = [v / mx for v in rgb] if mx > 0 else (0.0, 0.0, 0.0)
                ld.energy = 4 * math.pi * mx  # W; intensity = energy / (4 pi) W/sr (verified)
                ld.cycles.use_multiple_importance_sampling = True
                ob = bpy.data.objects.new(f"light{i}", ld)
                ob.location = vec(l["position"], 3, "position")
                bpy.context.scene.collection.objects.link(ob)
        nt.links.new(bg.outputs[0], out.inputs["Surface"])
        if world_medium is not None:
            vol = self._volume_node(nt, world_medium)
            nt.links.new(vol.outputs[0], out.inputs["Volume"])

    def camera(self, width, height):
        import mathutils
        bpy = self.bpy
        c = self.s["camera"]
        pos, fwd, right, up = sj.camera_frame(c)
        cd = bpy.data.cameras.new("camera")
        cd.type = "PERSP"
        cd.sensor_fit = "VERTICAL"
        cd.angle_y = math.radians(float(c["fov_y_deg"]))
        cd.shift_x = cd.shift_y = 0.0
        ext = sj.scene_extent(self.s)
        cd.clip_start = max(1e-6 * ext, 1e-6)
        cd.clip_end = 1e6 * ext
        ob = bpy.data.objects.new("camera", cd)
        m = mathutils.Matrix.Identity(4)
        for r in range(3):
            m[r][0], m[r][1], m[r][2], m[r][3] = right[r], up[r], -fwd[r], pos[r]
        ob.matrix_world = m
        bpy.context.scene.collection.objects.link(ob)
        bpy.context.scene.camera = ob
        return {"clip_start": cd.clip_start, "clip_end": cd.clip_end, "angle_y_rad": cd.angle_y,
                "sensor_fit": cd.sensor_fit}


def settings(bpy, sc, spp, seed, width, height, bounces, threads):
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = False
    c.time_limit = 0.0
    c.use_denoising = False
    c.use_preview_denoising = False
    c.light_sampling_threshold = 0.0
    c.use_light_tree = False
    c.direct_light_sampling_type = "MULTIPLE_IMPORTANCE_SAMPLING"
    c.use_guiding = False
    c.sampling_pattern = "TABULATED_SOBOL"
    c.scrambling_distance = 1.0
    c.auto_scrambling_distance = False
    c.use_sample_subset = False
    c.seed = seed
    c.use_animated_seed = False
    c.max_bounces = bounces
    c.diffuse_bounces = bounces
    c.glossy_bounces = bounces
    c.transmission_bounces = bounces
    c.volume_bounces = bounces
    c.transparent_max_bounces = UNLIMITED_BOUNCES
    c.min_light_bounces = 0
    c.min_transparent_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.use_fast_gi = False
    c.volume_biased = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.film_exposure = 1.0
    c.film_transparent_glass = False
    c.use_camera_cull = False
    c.use_distance_cull = False
    r = sc.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.film_transparent = False
    r.use_motion_blur = False
    r.use_compositing = False
    r.use_sequencer = False
    r.dither_intensity = 0.0
    r.threads_mode = "FIXED"
    r.threads = threads
    if bpy.data.colorspace.working_space != "Linear Rec.709":  # read-only; a new file's default
        raise SystemExit(f"working colour space is {bpy.data.colorspace.working_space!r}, need 'Linear Rec.709'")
    sc.display_settings.display_device = "sRGB"
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.view_settings.gamma = 1.0
    sc.view_settings.use_curve_mapping = False
    im = r.image_settings
    im.file_format = "OPEN_EXR"
    im.color_mode = "RGB"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    im.color_management = "OVERRIDE"
    im.linear_colorspace_settings.name = "Linear Rec.709"
    names = ["device", "samples", "use_adaptive_sampling", "time_limit", "use_denoising",
             "light_sampling_threshold", "use_light_tree", "direct_light_sampling_type", "use_guiding",
             "sampling_pattern", "scrambling_distance", "seed", "use_animated_seed", "max_bounces",
             "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
             "transparent_max_bounces", "min_light_bounces", "min_transparent_bounces", "sample_clamp_direct",
             "sample_clamp_indirect", "blur_glossy", "caustics_reflective", "caustics_refractive",
             "pixel_filter_type", "filter_width", "film_exposure"]
    used = {n: getattr(c, n) for n in names}
    used.update({"threads": r.threads, "working_space": bpy.data.colorspace.working_space,
                 "view_transform": sc.view_settings.view_transform, "look": sc.view_settings.look,
                 "exposure": sc.view_settings.exposure, "gamma": sc.view_settings.gamma,
                 "exr": f"{im.file_format} {im.color_mode} {im.color_depth}-bit float {im.exr_codec}, "
                        f"colour space {im.linear_colorspace_settings.name}"})
    return used


def main(argv=None):
    args = parse_args(argv)
    try:
        s = sj.load_scene(args.scene)
        width, height, spp, depth = sj.resolve_render(args, s)
        world_medium = check_supported(s, args.allow_eta_mismatch)
        bounces, depth_zero = cycles_bounces(depth)
        sub = subpixels(width, height, spp)
    except Unsupported as e:
        return sj.unsupported(e)
    except (Invalid, KeyError, TypeError, ValueError) as e:
        return sj.invalid(f"{type(e).__name__}: {e}" if not isinstance(e, Invalid) else e)
    if args.cycles_max_bounces is not None:
        bounces, depth_zero = args.cycles_max_bounces, False
    truncation = None
    if depth < 0 and args.cycles_max_bounces is None:
        # Cycles' 1024 bounces are furnace's 1025 (cycles_bounces); measured: the furnace sphere
        # at albedo 0.999 reads 641.0 +- 4.5 where E(1 - a^1026)/(1 - a) = 641.7 and E/(1 - a) = 1000
        truncation = sj.truncation(s, UNLIMITED_BOUNCES + 1)
        a, bound = truncation["max_albedo"], truncation["tail_bound_relative"]
        if bound is not None and bound > args.max_truncation:
            return sj.unsupported(
                f"an unlimited depth: Cycles ends every path after {UNLIMITED_BOUNCES} bounces (its largest "
                f"max_bounces), and the bound a^(K+1)/(1-a) on the share of the radiance that misses is "
                f"{bound:.2g} at albedo a = {a:g} (above --max-truncation {args.max_truncation:g})")

    t0 = time.perf_counter()
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    used = settings(bpy, sc, spp // (sub * sub), args.seed, width * sub, height * sub, bounces, args.threads)
    if sub > 1:
        sc.render.image_settings.exr_codec = "NONE"  # read back below to average the sub-pixels
    b = Builder(bpy, s, args, depth_zero)
    try:
        b.shapes()
        b.lights(world_medium)
        cam = b.camera(width, height)
    except (Invalid, KeyError, TypeError, ValueError) as e:
        return sj.invalid(e)
    out, stem = sj.out_paths(args.out)
    final = out
    if sub > 1:
        out = out + ".subpixels.exr"
    sc.render.filepath = out
    sc.render.use_file_extension = False
    t_load = time.perf_counter() - t0
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    t_render = time.perf_counter() - t0
    if not os.path.exists(out):
        print(f"error: Blender wrote no {out}", file=sys.stderr)
        return 1
    if sub > 1:
        big_w, big_h, planes = read_exr_uncompressed(out)
        write_exr_float_rgb(final, width, height, [box_average(planes[c], big_w, sub) for c in "RGB"])
        os.remove(out)
        out = final

    build = bpy.app.build_hash
    sj.write_sidecar(stem, {
        "renderer": "cycles",
        "version": bpy.app.version_string,
        "build_hash": build.decode() if isinstance(build, bytes) else str(build),
        "scene": os.path.abspath(args.scene),
        "spp": spp, "seed": args.seed, "width": width, "height": height,
        "threads": args.threads,
        "max_depth_furnace": depth,
        "max_bounces_cycles": bounces,
        "depth_mapping": "Cycles max_bounces = furnace bounces - 1; furnace 0 = every BSDF dropped (surfaces "
                         "keep only their emission); unlimited = 1024 with Russian roulette",
        "depth_zero_mode": "BSDFs dropped, emission only" if depth_zero else None,
        "depth_override": args.cycles_max_bounces is not None,
        "unlimited_truncation": truncation,
        "subpixels": None if sub == 1 else
        f"{sub}x{sub} sub-pixels at {spp // (sub * sub)} spp each, averaged (Blender renders at least 4x4 px)",
        "eta_mismatch_allowed": args.allow_eta_mismatch,
        "emitter_sampling": not args.no_emitter_sampling,
        "settings": used,
        "camera": cam,
        "spheres": b.sphere_notes,
        "world_medium": world_medium,
        "rgb_space": "linear Rec.709 primaries, D65 (Blender 'Linear Rec.709' working space), radiance in the "
                     "scene JSON's units (an emitter of rgb c reads c); compare with furnace's observer cie1931",
        "channels": ["R", "G", "B"],
        "time_s": t_render,
        "load_time_s": t_load,
        "samples_per_second": width * height * spp / t_render,
    })
    print(f"cycles {bpy.app.version_string}: {width}x{height} @ {spp} spp, max_bounces={bounces}"
          f"{' (depth 0: emission only)' if depth_zero else ''}, seed={args.seed}, threads={args.threads}: "
          f"{t_render:.2f} s; wrote {out}, {stem}.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
