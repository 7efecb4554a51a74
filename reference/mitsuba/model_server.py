#!/usr/bin/env python3
"""Mitsuba 3 model server for furnace's model protocol, version 1 (docs/model-protocol.md).

furnace starts this script (the `models = [...]` argv of a `renderers.toml` entry), sends
requests on stdin and reads replies on stdout; it runs furnace's model-level checks
(reciprocity, energy, albedo, chi-square, sample weights, phase functions, emitter sampling)
on Mitsuba's own BSDF, phase-function and emitter plugins. Everything else is logged on stderr.

    python3 reference/mitsuba/model_server.py --variant scalar_spectral
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \
        python3 reference/mitsuba/model_server.py --variant llvm_ad_spectral

llvm_* variants answer a whole batch with Dr.Jit arrays (one fused kernel per op and model,
compiled on first use and cached by Dr.Jit); scalar_* variants loop over the rows in Python.
Supported: scalar_spectral, scalar_rgb, llvm_ad_spectral, llvm_ad_rgb, llvm_ad_mono (polarized
variants are refused: their Spectrum is a Mueller matrix). Mitsuba computes in float32, so
every answer is a float32 value widened to f64 (relative rounding about 6e-8 per operation).

CATALOGUE (names marked * are furnace's own names for the same model at the same parameters,
`bsdfs()` and `phases()` of src/harness/model/catalogue.rs, formerly src/harness/registry.rs,
so results can be shown side by side; spectral-only rows are left out of RGB and mono
variants). Flags: D delta, 2 two_sided, T transmission, L lossless; η = `eta` flag;
α = `min_roughness` (- = null).

  BSDF name                                    Mitsuba plugin and parameters                     flags     η       α
  * diffuse/0.5                                diffuse reflectance=0.5                           .         1       -
  * diffuse/1                                  diffuse reflectance=1                             .         1       -
  * diffuse/0                                  diffuse reflectance=0                             .         1       -
  * diffuse/spectral-ramp                      diffuse regular 360..830 nm 0.05..0.95 (spectral) .         1       -
  * conductor/smooth n=0.2 k=3                 conductor eta=0.2 k=3                             D         1       0
  * conductor/smooth perfect                   conductor material="none" (η=0, k=1: F=1)          D L       1       0
  * conductor/ggx α=0.3 spectral n,k           roughconductor ggx α=0.3 n 1.2..0.2 k 2..4 (spec.) .         1       0.3
  * conductor/ggx αx=0.1 αy=0.5                roughconductor ggx alpha_u=0.1 alpha_v=0.5 n=1.5 k=2 .      1       0.1
  * conductor/ggx α=0.05 perfect               roughconductor ggx α=0.05 material="none"         .         1       0.05
  * conductor/ggx α=0.3 perfect                roughconductor ggx α=0.3 material="none"          .         1       0.3
  * conductor/ggx α=1 perfect                  roughconductor ggx α=1 material="none"            .         1       1
  * conductor/ggx α=1e-4                       roughconductor ggx α=1e-4 n=0.2 k=3               .         1       1e-4
    conductor/ggx α=0.3 perfect, sample_visible=false   as above, Walter et al. 2007 D sampling  .         1       0.3
    conductor/beckmann α=0.3 perfect           roughconductor beckmann α=0.3 material="none"     .         1       0.3
    conductor/beckmann αx=0.1 αy=0.5           roughconductor beckmann 0.1/0.5 n=1.5 k=2         .         1       0.1
  * dielectric/smooth η=1.5                    dielectric int_ior=1.5 ext_ior=1                  D T L     1.5     0
    dielectric/smooth η=1.5046 (Mitsuba bk7)   dielectric int_ior="bk7" (a constant in Mitsuba)  D T L     1.5046  0
  * dielectric/smooth η=1.0001                 dielectric int_ior=1.0001                         D T L     1.0001  0
  * dielectric/ggx α=0.1 η=1.5                 roughdielectric ggx α=0.1 int_ior=1.5             T         1.5     0.1
  * dielectric/ggx α=0.5 η=1.5                 roughdielectric ggx α=0.5 int_ior=1.5             T         1.5     0.5
    dielectric/ggx α=0.3 η=1.5046 (Mitsuba bk7) roughdielectric ggx α=0.3 int_ior="bk7"         T         1.5046  0.3
  * dielectric/ggx α=0.3 η=1.0001              roughdielectric ggx α=0.3 int_ior=1.0001          T         1.0001  0.3
  * dielectric/ggx α=1e-4 η=1.5                roughdielectric ggx α=1e-4 int_ior=1.5            T         1.5     1e-4
    dielectric/beckmann α=0.3 η=1.5            roughdielectric beckmann α=0.3 int_ior=1.5        T         1.5     0.3
    thindielectric/η=1.5                       thindielectric int_ior=1.5                        D 2 T L   1 (!)   0
    plastic/smooth ρd=0.5 η=1.5                plastic diffuse_reflectance=0.5 int_ior=1.5       D         1       0
    plastic/roughplastic ggx α=0.1 η=1.5       roughplastic ggx α=0.1 ρd=0.5 int_ior=1.5         .         1       0.1
    plastic/roughplastic beckmann α=0.3 η=1.5  roughplastic beckmann α=0.3 ρd=0.5 int_ior=1.5    .         1       0.3
    principled/base 0.5 roughness 0.5          principled (defaults: specular 0.5 i.e. η=1.5)    .         1       0.25
    principled/metallic 1 roughness 0.3 anisotropic 0.5  principled base 0.8 metallic 1 ...      .         1       0.0667
    principled/clearcoat 1 gloss 0.5           principled roughness 0.5 clearcoat 1 gloss 0.5   .         1       0.0505
    principled/spec_trans 1 roughness 0.3 η=1.5  principled base 1 spec_trans 1 eta 1.5          T         1.5     0.09
    twosided/diffuse 0.5                       twosided(diffuse 0.5)                             2         1       -
    twosided/conductor ggx α=0.3 perfect       twosided(roughconductor ggx α=0.3 "none")         2         1       0.3
    blendbsdf/0.3 diffuse 0.5 + 0.7 conductor ggx α=0.3 perfect   blendbsdf weight=0.7           .         1       0.3

  (!) a thin sheet sends light back into the medium it came from, so the relative index across
      it (what `eta` means for generalised reciprocity) is 1; the sheet's 1.5 is in `params`.
  principled α = max(0.001, roughness²), anisotropic: αx = r²/a, αy = r²·a, a = √(1 − 0.9·an)
      (Burley 2012, "Physically-Based Shading at Disney", §5.4 and addendum B.2; Mitsuba's
      principledhelpers.h calc_dist_params): an = 0.5, r = 0.3 gives αx = 0.1214, αy = 0.0667.
      The clearcoat lobe is GTR1 with α = lerp(0.1, 0.001, gloss) = 0.0505 (principled.cpp);
      min_roughness counts it although it is neither GGX nor Beckmann.

  phase name      Mitsuba plugin     mean_cosine
  * isotropic     isotropic          0
  * hg g=G        hg g=G             G, for G in -0.9999 -0.999 -0.9 -0.5 -0.3 0 0.3 0.5 0.9 0.999 0.9999
  * rayleigh      rayleigh           0

  emitter name              scene (positions in m; radiance a flat spectrum, {'type':'uniform'})
    area rectangle          furnace's `light quad`: parallelogram corner (-1,-0.7,0.8), edges (2,0,0.3),
                            (0,1.6,0.2), emitting towards the origin, L = 1
    area sphere (inside)    furnace's `light sphere`: centre (0.3,0.2,0.4), r = 1.2, flip_normals (emits
                            inwards), L = 1; the receiving point p = 0 is inside
    area sphere (outside)   centre (0.3,0.2,2), r = 0.5, emits outwards, L = 2; p = 0 is outside
    area triangles          furnace's `light triangles`: 2 triangles (4 vertices) emitting towards the
                            origin, L = 1.5
    point                   position (0.2,-0.3,1.5), intensity 2 W/sr/nm (delta)
    constant                uniform environment, L = 0.7 (infinite: dist = ∞)
  Each emitter's `params` give its geometry and `p`, the receiving point the scene was built
  for (all of the emitter's surface faces it). Mitsuba's area emitters are one-sided: seen from
  behind, `sample_direction` still returns a direction (radiance 0) while `pdf_direction` is 0.

MITSUBA CONVENTIONS HANDLED (Mitsuba 3.9.1; docs "BSDF" / "Emitter" / "PhaseFunction" API
reference and the plugin sources named below):
  * BSDF.eval returns f·|cos θ| of the light-side direction (src/bsdfs/diffuse.cpp:
    `reflectance * InvPi * cos_theta_o`); the protocol's eval has no cosine: we divide by
    |wi.z| (0 at wi.z = 0, where Mitsuba's product is 0 and f is not recoverable).
  * Mitsuba's si.wi points towards the viewer (= protocol wo) and its `wo` argument towards the
    light (= protocol wi); BSDFSample3f.wo is the protocol's sampled wi. Both are in the local
    shading frame, z = normal, exactly as in the protocol.
  * BSDF.sample(ctx, si, sample1, sample2) returns (BSDFSample3f, weight = f·|cos|/pdf); the
    protocol's uc is sample1 (lobe choice), (u1, u2) is sample2. For a Dirac lobe bs.pdf is the
    lobe's discrete selection probability (src/bsdfs/dielectric.cpp: r_i or t_i), as the
    protocol asks.
  * Mitsuba rejects a sample by masking its weight to 0, often with bs.pdf and
    bs.sampled_type still set: diffuse.cpp sets bs.pdf before masking (vectorised variants);
    roughdielectric.cpp keeps a reflection whose direction fell below the horizon with weight 0,
    bs.pdf > 0 and sampled_type GlossyReflection, although eval/pdf there are the transmission
    lobe's (non-zero). We report "no sample" (flags 0) when bs.pdf <= 0, or when the weight is
    0 in every lane and not explained by the model being black there (f = 0 and pdf > 0 at the
    sampled direction, from BSDF.eval_pdf; so diffuse/0 keeps its samples), or the lobe is a
    Dirac lobe, or the direction is on the far side of a model without transmission (a
    reflection below the horizon: llvm roughplastic keeps those with bs.pdf > 0 because its
    pdf() is not masked there, while scalar_spectral returns bs.pdf = 0 for the same draws).
    Without this, ~0.7 % of roughdielectric α=0.5 samples fail weight = f·cos/pdf.
  * BSDFContext(TransportMode.Radiance): f carries radiance across refraction (roughdielectric
    scales transmission by 1/η², "Missing term in the original paper", matching the protocol's
    f(wo,wi)/η(wo)² = f(wi,wo)/η(wi)², Veach 1997 §5.2).
  * Wavelengths: spectral variants take the request's four λ on si.wavelengths (also on
    MediumInteraction3f and Interaction3f); RGB variants ignore them and answer R, G, B, G in
    the four lanes; mono answers its one value in all four lanes (said in the hello `version`).
  * Phase functions: Mitsuba's mi.wi and `wo` both point away from the scattering point (hg.cpp
    evaluates 1 + g² + 2g·(wo·wi), peaked at wo = −wi for g > 0): the protocol's convention, so
    protocol wo -> mi.wi, protocol wi -> Mitsuba wo (checked numerically by model_client_test.py:
    the mean of −wo·wi over samples is g). PhaseFunction.sample builds its direction in
    mi.sh_frame, which Mitsuba's medium code sets to Frame3f(mi.wi) (src/render/medium.cpp:49);
    a hand-made MediumInteraction3f must set it too or samples come out in a zero frame.
  * Emitter.sample_direction returns (DirectionSample3f, radiance / pdf); the protocol wants the
    radiance itself, so we multiply by ds.pdf (for a point light pdf = 1 and the value is I/d²).
    It takes two random numbers only: the protocol's uc is ignored (a mesh picks its triangle by
    reusing sample.y, src/render/mesh.cpp `m_area_pmf.sample_reuse`).
  * An infinite emitter's DirectionSample3f.dist is 2·(bounding-sphere radius) (constant.cpp);
    the protocol wants ∞.
  * A plain float `radiance`/`intensity` on an emitter in a spectral variant is NOT flat: it is
    upsampled as that multiple of the D65 illuminant (the loaded plugin prints D65Spectrum); we
    use {'type': 'uniform', 'value': L}. Float BSDF parameters do become UniformSpectrum.
  * Emitter.pdf_direction needs a DirectionSample3f of the emitter point; we trace p + t·wi
    through the one-emitter scene and sum the pdf over every crossing (up to 4) with
    DirectionSample3f(scene, si, it), as the protocol asks; area emitters answer 0 for a
    back-facing point (area.cpp: dot(ds.d, ds.n) < 0), and a sphere seen from outside is
    sampled in its cone of directions, whose pdf the near crossing carries.
  * Mitsuba's logger writes to stdout (src/core/logger.cpp: StreamAppender(&std::cout)); fd 1
    is redirected to stderr before Mitsuba is imported and the protocol writes to a private
    duplicate of the original stdout.
  * Mitsuba computes in float32, and the f64 inputs are rounded to float32 first. Recomputing a
    sample's pdf or f from its returned (rounded) direction therefore differs from the sample's
    own values where the lobe is very narrow or a half vector cancels: about ε32/(2α cos θo)
    for a reflection (17 % for GGX α = 1e-4 at θo = 89.9°, 3e-4 at 30°), 0.5 % for
    roughdielectric η = 1.0001 (2ε32/|wo + η·wi|); 1e-5 elsewhere. Float32 conditioning, not a
    Mitsuba bias: reports/renderers/mitsuba3/models/FINDINGS.md.
  * Henyey–Greenstein at |g| = 0.9999 (hg.cpp, float32 1 + g² + 2g·cos θ): the denominator
    cancels near the peak, so eval is inf at exact forward (backward for g < 0) scattering,
    59 % of samples report pdf = inf (cos θ rounds to ≥ 1 in `sample`; 200 000 samples, both
    scalar_spectral and llvm_ad_spectral), and eval at the sampled directions is off by a
    median 8–10 % from the same formula in f64 at the same float32 directions. Served as is:
    furnace's own catalogue includes these g.
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time

PROTOCOL = 1
MAX_BATCH = 1_048_576

# ---------------------------------------------------------------------------------------------
# Catalogue
# ---------------------------------------------------------------------------------------------


def bflags(delta=False, two_sided=False, transmission=False, eta=1.0, lossless=False,
           dispersive=False, min_roughness=None):
    """A BSDF's hello flags (docs/model-protocol.md, "Hello"). `min_roughness` is given as the
    microfacet α and reported as the lobes' angular width: a transmitted lobe is narrowed by
    |η − 1| (a facet tilted by θm deviates the refracted ray by about (η − 1)θm), so a
    transmissive model reports α·min(1, |η − 1|), as furnace's catalogue does."""
    if transmission and min_roughness:
        min_roughness = min_roughness * min(1.0, abs(eta - 1.0))
    return {"delta": delta, "two_sided": two_sided, "transmission": transmission, "eta": eta,
            "lossless": lossless, "dispersive": dispersive, "min_roughness": min_roughness}


def uniform(v):
    """A flat spectrum (the same value at every wavelength / in every RGB channel)."""
    return {"type": "uniform", "value": v}


def ramp(a, b):
    """Linear in λ from a at 360 nm to b at 830 nm (furnace's `Spectrum::tabulated` ramps);
    Mitsuba's `regular` spectrum interpolates linearly between its samples."""
    return {"type": "regular", "wavelength_min": 360.0, "wavelength_max": 830.0,
            "values": f"{a}, {b}"}


def rough_conductor(dist, au, av=None, eta=None, k=None, **extra):
    d = {"type": "roughconductor", "distribution": dist}
    if av is None:
        d["alpha"] = au
    else:
        d["alpha_u"], d["alpha_v"] = au, av
    if eta is None:
        d["material"] = "none"   # perfect mirror: η = 0, k = 1, |r| = 1 at every angle
    else:
        d["eta"], d["k"] = eta, k
    d.update(extra)
    return d


def rough_dielectric(dist, alpha, ior):
    return {"type": "roughdielectric", "distribution": dist, "alpha": alpha, "int_ior": ior,
            "ext_ior": 1.0}


DIFFUSE_05 = {"type": "diffuse", "reflectance": 0.5}
GGX03_PERFECT = rough_conductor("ggx", 0.3)
BK7 = 1.5046  # Mitsuba's "bk7" entry in include/mitsuba/render/ior.h (a constant, not Sellmeier)

# (name, Mitsuba dict, flags, spectral_only)
BSDFS = [
    ("diffuse/0.5", DIFFUSE_05, bflags(), False),
    ("diffuse/1", {"type": "diffuse", "reflectance": 1.0}, bflags(), False),
    ("diffuse/0", {"type": "diffuse", "reflectance": 0.0}, bflags(), False),
    ("diffuse/spectral-ramp", {"type": "diffuse", "reflectance": ramp(0.05, 0.95)}, bflags(), True),
    ("conductor/smooth n=0.2 k=3", {"type": "conductor", "eta": 0.2, "k": 3.0},
     bflags(delta=True, min_roughness=0.0), False),
    ("conductor/smooth perfect", {"type": "conductor", "material": "none"},
     bflags(delta=True, lossless=True, min_roughness=0.0), False),
    ("conductor/ggx α=0.3 spectral n,k",
     rough_conductor("ggx", 0.3, eta=ramp(1.2, 0.2), k=ramp(2.0, 4.0)),
     bflags(min_roughness=0.3), True),
    ("conductor/ggx αx=0.1 αy=0.5", rough_conductor("ggx", 0.1, 0.5, eta=1.5, k=2.0),
     bflags(min_roughness=0.1), False),
    ("conductor/ggx α=0.05 perfect", rough_conductor("ggx", 0.05), bflags(min_roughness=0.05), False),
    ("conductor/ggx α=0.3 perfect", GGX03_PERFECT, bflags(min_roughness=0.3), False),
    ("conductor/ggx α=1 perfect", rough_conductor("ggx", 1.0), bflags(min_roughness=1.0), False),
    ("conductor/ggx α=1e-4", rough_conductor("ggx", 1e-4, eta=0.2, k=3.0),
     bflags(min_roughness=1e-4), False),
    ("conductor/ggx α=0.3 perfect, sample_visible=false",
     rough_conductor("ggx", 0.3, sample_visible=False), bflags(min_roughness=0.3), False),
    ("conductor/beckmann α=0.3 perfect", rough_conductor("beckmann", 0.3),
     bflags(min_roughness=0.3), False),
    ("conductor/beckmann αx=0.1 αy=0.5", rough_conductor("beckmann", 0.1, 0.5, eta=1.5, k=2.0),
     bflags(min_roughness=0.1), False),
    ("dielectric/smooth η=1.5", {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0},
     bflags(delta=True, transmission=True, eta=1.5, lossless=True, min_roughness=0.0), False),
    ("dielectric/smooth η=1.5046 (Mitsuba bk7)",
     {"type": "dielectric", "int_ior": "bk7", "ext_ior": "vacuum"},
     bflags(delta=True, transmission=True, eta=BK7, lossless=True, min_roughness=0.0), False),
    ("dielectric/smooth η=1.0001", {"type": "dielectric", "int_ior": 1.0001, "ext_ior": 1.0},
     bflags(delta=True, transmission=True, eta=1.0001, lossless=True, min_roughness=0.0), False),
    ("dielectric/ggx α=0.1 η=1.5", rough_dielectric("ggx", 0.1, 1.5),
     bflags(transmission=True, eta=1.5, min_roughness=0.1), False),
    ("dielectric/ggx α=0.5 η=1.5", rough_dielectric("ggx", 0.5, 1.5),
     bflags(transmission=True, eta=1.5, min_roughness=0.5), False),
    ("dielectric/ggx α=0.3 η=1.5046 (Mitsuba bk7)", rough_dielectric("ggx", 0.3, "bk7"),
     bflags(transmission=True, eta=BK7, min_roughness=0.3), False),
    ("dielectric/ggx α=0.3 η=1.0001", rough_dielectric("ggx", 0.3, 1.0001),
     bflags(transmission=True, eta=1.0001, min_roughness=0.3), False),
    ("dielectric/ggx α=1e-4 η=1.5", rough_dielectric("ggx", 1e-4, 1.5),
     bflags(transmission=True, eta=1.5, min_roughness=1e-4), False),
    ("dielectric/beckmann α=0.3 η=1.5", rough_dielectric("beckmann", 0.3, 1.5),
     bflags(transmission=True, eta=1.5, min_roughness=0.3), False),
    # R' + T' = 1 with the sheet's inter-reflections summed as a geometric series,
    # R' = R + T²R/(1 − R²) = 2R/(1 + R) for T = 1 − R (Mitsuba thindielectric.cpp,
    # `r *= 2/(1 + r)`); light leaves into the medium it came from: relative η = 1. Its
    # straight-through lobe is BSDFFlags.Null, which Mitsuba counts in both Delta and
    # Transmission (include/mitsuba/render/bsdf.h), so it reports flags 1|2|4.
    ("thindielectric/η=1.5", {"type": "thindielectric", "int_ior": 1.5, "ext_ior": 1.0},
     bflags(delta=True, two_sided=True, transmission=True, eta=1.0, lossless=True,
            min_roughness=0.0), False),
    ("plastic/smooth ρd=0.5 η=1.5",
     {"type": "plastic", "diffuse_reflectance": 0.5, "int_ior": 1.5, "ext_ior": 1.0},
     bflags(delta=True, min_roughness=0.0), False),
    ("plastic/roughplastic ggx α=0.1 η=1.5",
     {"type": "roughplastic", "distribution": "ggx", "alpha": 0.1, "diffuse_reflectance": 0.5,
      "int_ior": 1.5, "ext_ior": 1.0}, bflags(min_roughness=0.1), False),
    ("plastic/roughplastic beckmann α=0.3 η=1.5",
     {"type": "roughplastic", "distribution": "beckmann", "alpha": 0.3,
      "diffuse_reflectance": 0.5, "int_ior": 1.5, "ext_ior": 1.0},
     bflags(min_roughness=0.3), False),
    ("principled/base 0.5 roughness 0.5", {"type": "principled"},
     bflags(min_roughness=0.25), False),
    ("principled/metallic 1 roughness 0.3 anisotropic 0.5",
     {"type": "principled", "base_color": 0.8, "metallic": 1.0, "roughness": 0.3,
      "anisotropic": 0.5}, bflags(min_roughness=0.09 * math.sqrt(1.0 - 0.45)), False),
    ("principled/clearcoat 1 gloss 0.5",
     {"type": "principled", "clearcoat": 1.0, "clearcoat_gloss": 0.5},
     bflags(min_roughness=0.0505), False),
    ("principled/spec_trans 1 roughness 0.3 η=1.5",
     {"type": "principled", "base_color": 1.0, "spec_trans": 1.0, "roughness": 0.3, "eta": 1.5},
     bflags(transmission=True, eta=1.5, min_roughness=0.09), False),
    ("twosided/diffuse 0.5", {"type": "twosided", "bsdf": DIFFUSE_05},
     bflags(two_sided=True), False),
    ("twosided/conductor ggx α=0.3 perfect", {"type": "twosided", "bsdf": GGX03_PERFECT},
     bflags(two_sided=True, min_roughness=0.3), False),
    ("blendbsdf/0.3 diffuse 0.5 + 0.7 conductor ggx α=0.3 perfect",
     {"type": "blendbsdf", "weight": 0.7, "bsdf_0": DIFFUSE_05, "bsdf_1": GGX03_PERFECT},
     bflags(min_roughness=0.3), False),
]

# furnace's names: format!("hg g={g}") of an f64 (Rust prints 0.0 as "0").
HG_G = [("-0.9999", -0.9999), ("-0.999", -0.999), ("-0.9", -0.9), ("-0.5", -0.5),
        ("-0.3", -0.3), ("0", 0.0), ("0.3", 0.3), ("0.5", 0.5), ("0.9", 0.9), ("0.999", 0.999),
        ("0.9999", 0.9999)]
PHASES = ([("isotropic", {"type": "isotropic"}, 0.0)]
          + [(f"hg g={s}", {"type": "hg", "g": g}, g) for s, g in HG_G]
          + [("rayleigh", {"type": "rayleigh"}, 0.0)])

QUAD = {"corner": [-1.0, -0.7, 0.8], "edge_u": [2.0, 0.0, 0.3], "edge_v": [0.0, 1.6, 0.2]}
SPHERE_IN = {"center": [0.3, 0.2, 0.4], "radius": 1.2}
SPHERE_OUT = {"center": [0.3, 0.2, 2.0], "radius": 0.5}
# furnace's `light triangles` mesh; faces wound so that the geometric normal
# (v1 − v0) × (v2 − v0) points towards the origin (Mitsuba area lights emit on that side).
TRI_VERTICES = [[-1.0, -1.0, 0.6], [1.5, -0.5, 1.0], [0.0, 1.2, 0.7], [-1.2, 0.8, 1.5]]
TRI_FACES = [[0, 2, 1], [0, 3, 2]]
POINT = {"position": [0.2, -0.3, 1.5], "intensity": 2.0}
ORIGIN = [0.0, 0.0, 0.0]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def quad_to_world(corner, eu, ev, towards):
    """A 4×4 matrix taking Mitsuba's rectangle [-1,1]² × {0} (normal +z) onto the parallelogram
    corner + s·eu + t·ev, s, t in [0, 1], with its normal on the side of the point `towards`.
    The third column is the unit normal, so the determinant is positive and Mitsuba's normal
    (the inverse transpose applied to +z) is ±(eu × ev)/|eu × ev|."""
    n = cross(eu, ev)
    ln = math.sqrt(sum(c * c for c in n))
    n = [c / ln for c in n]
    c = [corner[i] + 0.5 * (eu[i] + ev[i]) for i in range(3)]
    if sum((towards[i] - c[i]) * n[i] for i in range(3)) < 0.0:
        n = [-x for x in n]
        eu, ev = ev, eu   # keep the determinant positive while the normal flips
    return [[eu[0] / 2, ev[0] / 2, n[0], c[0]],
            [eu[1] / 2, ev[1] / 2, n[1], c[1]],
            [eu[2] / 2, ev[2] / 2, n[2], c[2]],
            [0.0, 0.0, 0.0, 1.0]]


def emitters(tmpdir):
    """(name, scene dict, flags, params); params carry the geometry and the receiving point."""
    obj = os.path.join(tmpdir, "triangles.obj")
    with open(obj, "w") as f:
        for v in TRI_VERTICES:
            f.write("v %r %r %r\n" % tuple(v))
        for t in TRI_FACES:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))

    def area(shape, L):
        shape = dict(shape)
        shape["emitter"] = {"type": "area", "radiance": uniform(L)}
        return {"type": "scene", "shape": shape}

    nodelta = {"delta": False}
    return [
        ("area rectangle",
         area({"type": "rectangle",
               "to_world": _transform(quad_to_world(QUAD["corner"], QUAD["edge_u"],
                                                    QUAD["edge_v"], ORIGIN))}, 1.0),
         nodelta,
         {"type": "area", "shape": "parallelogram", **QUAD, "emits_towards": "p",
          "radiance": 1.0, "p": ORIGIN}),
        ("area sphere (inside)",
         area({"type": "sphere", **SPHERE_IN, "flip_normals": True}, 1.0), nodelta,
         {"type": "area", "shape": "sphere", **SPHERE_IN, "emits": "inwards", "radiance": 1.0,
          "p": ORIGIN}),
        ("area sphere (outside)",
         area({"type": "sphere", **SPHERE_OUT}, 2.0), nodelta,
         {"type": "area", "shape": "sphere", **SPHERE_OUT, "emits": "outwards", "radiance": 2.0,
          "p": ORIGIN, "sampling": "cone of directions subtended (near side only)"}),
        ("area triangles",
         area({"type": "obj", "filename": obj, "face_normals": True}, 1.5), nodelta,
         {"type": "area", "shape": "triangles", "vertices": TRI_VERTICES, "faces": TRI_FACES,
          "emits": "along (v1-v0)x(v2-v0), towards p", "radiance": 1.5, "p": ORIGIN}),
        ("point",
         {"type": "scene", "emitter": {"type": "point", "position": POINT["position"],
                                       "intensity": uniform(POINT["intensity"])}},
         {"delta": True},
         {"type": "point", **POINT, "p": ORIGIN,
          "radiance_column": "intensity / distance^2 (W m^-2 nm^-1)"}),
        ("constant",
         {"type": "scene", "emitter": {"type": "constant", "radiance": uniform(0.7)}},
         {"delta": False},
         {"type": "constant", "radiance": 0.7, "p": ORIGIN, "at_infinity": True}),
    ]


def _transform(m):
    import mitsuba as mi
    return mi.ScalarTransform4f(m)


# ---------------------------------------------------------------------------------------------
# Protocol I/O
# ---------------------------------------------------------------------------------------------


class ProtocolError(Exception):
    pass


def read_exact(stream, size):
    chunks, got = [], 0
    while got < size:
        b = stream.read(size - got)
        if not b:
            raise EOFError("payload shorter than announced (%d of %d bytes)" % (got, size))
        chunks.append(b)
        got += len(b)
    return b"".join(chunks)


class Channel:
    def __init__(self, inp, out):
        self.inp, self.out = inp, out

    def read(self, np):
        line = self.inp.readline()
        if not line:
            return None, None
        try:
            header = json.loads(line)
            if not isinstance(header, dict):
                raise ValueError("not an object")
        except ValueError as e:
            # No way to know the payload length: answer and stop reading this stream.
            raise ProtocolError("header is not a JSON object: %s" % e) from None
        payload = None
        if "n" in header:
            n, w = header.get("n"), header.get("width")
            if not (isinstance(n, int) and isinstance(w, int) and n >= 0 and 0 < w <= 64):
                raise ProtocolError("bad n/width: %r/%r" % (n, w))
            raw = read_exact(self.inp, n * w * 8)
            payload = np.frombuffer(raw, dtype="<f8").reshape(n, w)
        return header, payload

    def write(self, np, header, payload=None):
        if payload is not None:
            payload = np.ascontiguousarray(payload, dtype="<f8")
            header = dict(header, n=payload.shape[0], width=payload.shape[1])
        self.out.write(json.dumps(header, ensure_ascii=False, separators=(",", ":")).encode() + b"\n")
        if payload is not None:
            self.out.write(payload.tobytes())
        self.out.flush()


# ---------------------------------------------------------------------------------------------
# Mitsuba side
# ---------------------------------------------------------------------------------------------

REQUEST_WIDTH = {"bsdf.eval": 10, "bsdf.pdf": 10, "bsdf.sample": 10, "phase.eval": 10,
                 "phase.pdf": 10, "phase.sample": 9, "emitter.sample_direction": 10,
                 "emitter.pdf_direction": 10}
OP_KIND = {op: op.split(".")[0] for op in REQUEST_WIDTH}


class Server:
    def __init__(self, variant, np, dr, mi, tmpdir):
        self.np, self.dr, self.mi = np, dr, mi
        self.variant = variant
        self.jit = dr.is_jit_v(mi.Float)
        self.channels = dr.size_v(mi.Spectrum)
        self.spectral = mi.is_spectral
        if mi.is_polarized:
            raise SystemExit("polarized variants are not supported (Spectrum is a Mueller matrix)")
        self.ctx = mi.BSDFContext(mi.TransportMode.Radiance)
        self.pctx = mi.PhaseFunctionContext(None, mi.TransportMode.Radiance)
        self.models = {}
        self.hello_models = []
        t0 = time.time()
        for name, d, flags, spectral_only in BSDFS:
            if spectral_only and not self.spectral:
                continue
            self._add(name, "bsdf", mi.load_dict(d), flags, d)
        for name, d, g in PHASES:
            self._add(name, "phase", mi.load_dict(d), {"mean_cosine": g}, d)
        for name, d, flags, params in emitters(tmpdir):
            scene = mi.load_dict(d)
            em = scene.emitters()[0]
            self._add(name, "emitter", (scene, em), flags, params)
        log("loaded %d models in %.2f s" % (len(self.models), time.time() - t0))

    def _add(self, name, kind, obj, flags, params):
        assert name not in self.models, name
        self.models[name] = (kind, obj, flags)
        if kind == "bsdf" or kind == "phase":
            params = _jsonable(params)
        if kind == "emitter":
            params = dict(params, unit=self.unit())
        self.hello_models.append({"name": name, "kind": kind, "flags": flags, "params": params})

    def unit(self):
        if self.spectral:
            return "W sr^-1 m^-2 nm^-1"
        return "Mitsuba %s units (linear RGB / mono)" % self.variant

    def version(self):
        v = "%s %s float32" % (self.mi.__version__, self.variant)
        if self.channels == 3:
            v += " (lanes R,G,B,G)"
        elif self.channels == 1:
            v += " (mono: one value in all four lanes)"
        return v

    # -- conversion helpers -------------------------------------------------------------------

    def F(self, col):
        """numpy column (n,) -> mi.Float (float32 for every shipped variant)."""
        return self.mi.Float(self.np.ascontiguousarray(col, dtype=self.np.float32))

    def V3(self, cols):
        return self.mi.Vector3f(self.F(cols[:, 0]), self.F(cols[:, 1]), self.F(cols[:, 2]))

    def P3(self, cols):
        return self.mi.Point3f(self.F(cols[:, 0]), self.F(cols[:, 1]), self.F(cols[:, 2]))

    def WL(self, cols):
        if not self.spectral:
            return None
        return self.mi.Spectrum(*[self.F(cols[:, i]) for i in range(4)])

    def out(self, x, k, n):
        """A Mitsuba value (Float: k = 1, Vector3f: k = 3, Spectrum: k = channels) -> (n, k)."""
        a = self.np.array(x, dtype=self.np.float64)
        if k == 1:
            a = a.reshape(1, -1)
        a = a.reshape(k, -1)
        return self.np.broadcast_to(a, (k, n)).T

    def lanes(self, spec):
        """(n, channels) -> (n, 4): spectral as is, RGB as R, G, B, G, mono repeated."""
        np = self.np
        if self.channels == 4:
            return spec
        if self.channels == 3:
            return spec[:, [0, 1, 2, 1]]
        return np.repeat(spec[:, :1], 4, axis=1)

    # -- Mitsuba calls, written once for Dr.Jit arrays (jit) or one row (scalar) --------------

    def _si(self, wo, wl, n):
        si = self.dr.zeros(self.mi.SurfaceInteraction3f, n)
        si.wi = wo                                    # Mitsuba's si.wi = protocol wo (viewer)
        si.sh_frame = self.mi.Frame3f(self.mi.Vector3f(0, 0, 1))
        si.n = self.mi.Normal3f(0, 0, 1)
        if wl is not None:
            si.wavelengths = wl
        return si

    def _mi(self, wo, wl, n):
        m = self.dr.zeros(self.mi.MediumInteraction3f, n)
        m.wi = wo                                     # both point away from the point
        m.sh_frame = self.mi.Frame3f(wo)              # what Medium::sample_interaction sets
        if wl is not None:
            m.wavelengths = wl
        return m

    def _it(self, p, wl, n):
        it = self.dr.zeros(self.mi.Interaction3f, n)
        it.p = p
        if wl is not None:
            it.wavelengths = wl
        return it

    def k_bsdf_eval(self, b, wo, wi, wl, n):
        return (b.eval(self.ctx, self._si(wo, wl, n), wi),)   # f·|cos θ_wi|

    def k_bsdf_pdf(self, b, wo, wi, wl, n):
        return (b.pdf(self.ctx, self._si(wo, wl, n), wi),)

    def k_bsdf_sample(self, b, wo, u, uc, wl, n):
        si = self._si(wo, wl, n)
        bs, weight = b.sample(self.ctx, si, uc, u)
        # eval and pdf at the sampled direction tell a rejected sample from a black one
        f_again, pdf_again = b.eval_pdf(self.ctx, si, bs.wo)
        return bs.wo, weight, bs.pdf, self.mi.Float(bs.sampled_type), f_again, pdf_again

    def k_phase_eval_pdf(self, ph, wo, wi, wl, n):
        value, pdf = ph.eval_pdf(self.pctx, self._mi(wo, wl, n), wi)
        return value, pdf

    def k_phase_sample(self, ph, wo, u, wl, n):
        # sample1 selects a component of blended phase functions; these have one: pass 0.5.
        wi, weight, pdf = ph.sample(self.pctx, self._mi(wo, wl, n), 0.5, u)
        return wi, weight, pdf

    def k_emitter_sample(self, scene_em, p, u, wl, n):
        _, em = scene_em
        ds, spec = em.sample_direction(self._it(p, wl, n), u)
        return ds.d, spec, ds.pdf, ds.dist

    def k_emitter_pdf(self, scene_em, p, wi, wl, n):
        mi, dr = self.mi, self.dr
        scene, em = scene_em
        it = self._it(p, wl, n)
        if em.get_shape() is None:
            # no surface to intersect: a point light (Mitsuba answers 0, a delta has no
            # density) or an environment (its density depends on the direction only)
            # (dr.zeros(DirectionSample3f, 1) fails in scalar variants: its bool field)
            ds = dr.zeros(mi.DirectionSample3f, n) if self.jit else mi.DirectionSample3f()
            ds.p, ds.d, ds.n, ds.dist, ds.pdf, ds.delta = p + wi, wi, -wi, 1.0, 0.0, False
            return (em.pdf_direction(it, ds),)
        total = mi.Float(0.0) if self.jit else 0.0
        alive = mi.Bool(True) if self.jit else True
        ray = mi.Ray3f(p, wi)
        for _ in range(4):                            # a sphere is crossed at most twice
            si = scene.ray_intersect(ray, alive)
            alive = alive & si.is_valid()
            if not self.jit and not alive:
                break
            ds = mi.DirectionSample3f(scene, si, it)
            total = total + dr.select(alive, em.pdf_direction(it, ds, alive), 0.0)
            ray = si.spawn_ray(wi)
        return (total,)

    # -- batch driver --------------------------------------------------------------------------

    def run(self, kernel, obj, args, outs):
        """Calls `kernel(obj, *mitsuba_args, n)` on the whole batch (jit) or row by row (scalar).
        args: list of (kind, numpy (n, k)); kinds 'v3', 'p3', 'p2', 'f', 'wl'.
        outs: list of output widths (1, 3 or 'spec'). Returns a list of numpy (n, k) arrays."""
        np, mi = self.np, self.mi
        n = args[0][1].shape[0]
        widths = [self.channels if k == "spec" else k for k in outs]
        if n == 0:
            return [np.zeros((0, w)) for w in widths]
        if self.jit:
            conv = []
            for kind, a in args:
                if kind == "v3":
                    conv.append(self.V3(a))
                elif kind == "p3":
                    conv.append(self.P3(a))
                elif kind == "p2":
                    conv.append(mi.Point2f(self.F(a[:, 0]), self.F(a[:, 1])))
                elif kind == "f":
                    conv.append(self.F(a[:, 0]))
                elif kind == "wl":
                    conv.append(self.WL(a))
            res = kernel(obj, *conv, n)
            self.dr.eval(*res)
            return [self.out(r, w, n) for r, w in zip(res, widths)]
        # scalar: one Python call per row
        cols = [(kind, a.tolist()) for kind, a in args]
        result = [np.empty((n, w)) for w in widths]
        V3, P3, P2, SP = mi.Vector3f, mi.Point3f, mi.Point2f, mi.Spectrum
        spectral = self.spectral
        for i in range(n):
            conv = []
            for kind, a in cols:
                r = a[i]
                if kind == "v3":
                    conv.append(V3(r[0], r[1], r[2]))
                elif kind == "p3":
                    conv.append(P3(r[0], r[1], r[2]))
                elif kind == "p2":
                    conv.append(P2(r[0], r[1]))
                elif kind == "f":
                    conv.append(r[0])
                elif kind == "wl":
                    conv.append(SP(r[0], r[1], r[2], r[3]) if spectral else None)
            res = kernel(obj, *conv, 1)
            for out, r, w in zip(result, res, widths):
                if w == 1:
                    out[i, 0] = float(r)
                else:
                    out[i, :] = list(r)
        return result

    # -- ops -----------------------------------------------------------------------------------

    def handle(self, op, model, q):
        np = self.np
        kind, obj, flags = self.models[model]
        n = q.shape[0]
        if op == "bsdf.eval":
            (fcos,) = self.run(self.k_bsdf_eval, obj, [("v3", q[:, 0:3]), ("v3", q[:, 3:6]),
                                                       ("wl", q[:, 6:10])], ["spec"])
            cos = np.abs(q[:, 5:6])
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(cos > 0.0, fcos / np.where(cos > 0.0, cos, 1.0), 0.0)
            return self.lanes(f)
        if op == "bsdf.pdf":
            (pdf,) = self.run(self.k_bsdf_pdf, obj, [("v3", q[:, 0:3]), ("v3", q[:, 3:6]),
                                                     ("wl", q[:, 6:10])], [1])
            return pdf
        if op == "bsdf.sample":
            wi, weight, pdf, stype, f_again, pdf_again = self.run(
                self.k_bsdf_sample, obj,
                [("v3", q[:, 0:3]), ("p2", q[:, 3:5]), ("f", q[:, 5:6]), ("wl", q[:, 6:10])],
                [3, "spec", 1, 1, "spec", 1])
            mi = self.mi
            st = stype[:, 0].astype(np.int64)
            delta = (st & int(mi.BSDFFlags.Delta)) != 0
            trans = (st & int(mi.BSDFFlags.Transmission)) != 0
            # Mitsuba rejects a sample by masking its weight to 0 (bs.pdf may stay > 0); a
            # zero weight is a genuine (black) sample only when f and pdf at the sampled
            # direction agree with it: f = 0 there and pdf > 0 (diffuse/0).
            black = np.all(weight == 0.0, axis=1)
            black_there = np.all(f_again == 0.0, axis=1) & (pdf_again[:, 0] > 0.0)
            # A zero-weight sample on the far side of a model without transmission is a
            # reflection that fell below the horizon: Mitsuba's path ends there, so it is "no
            # sample" whatever pdf() answers there (vectorised roughplastic answers > 0 below
            # the horizon, scalar 0: reports/renderers/mitsuba3/models/FINDINGS.md).
            wrong_side = (not flags["transmission"]) & (wi[:, 2] * q[:, 2] <= 0.0)
            valid = (pdf[:, 0] > 0.0) & ~(black & (delta | ~black_there | wrong_side))
            flags_col = np.where(valid, 1 + 2 * delta + 4 * trans, 0).astype(np.float64)
            res = np.concatenate([wi, self.lanes(weight), pdf, flags_col[:, None]], axis=1)
            res[~valid, :8] = 0.0
            return res
        if op in ("phase.eval", "phase.pdf"):
            value, pdf = self.run(self.k_phase_eval_pdf, obj,
                                  [("v3", q[:, 0:3]), ("v3", q[:, 3:6]), ("wl", q[:, 6:10])],
                                  ["spec", 1])
            return value[:, :1] if op == "phase.eval" else pdf
        if op == "phase.sample":
            wi, weight, pdf = self.run(self.k_phase_sample, obj,
                                       [("v3", q[:, 0:3]), ("p2", q[:, 3:5]), ("wl", q[:, 5:9])],
                                       [3, "spec", 1])
            return np.concatenate([wi, weight[:, :1], pdf], axis=1)
        if op == "emitter.sample_direction":
            d, spec, pdf, dist = self.run(self.k_emitter_sample, obj,
                                          [("p3", q[:, 0:3]), ("p2", q[:, 3:5]),
                                           ("wl", q[:, 6:10])], [3, "spec", 1, 1])
            radiance = self.lanes(spec) * pdf             # Mitsuba returns radiance / pdf
            valid = (pdf[:, 0] > 0.0) & np.isfinite(pdf[:, 0])
            if obj[1].is_environment():           # Mitsuba: 2 x bounding radius
                dist = np.full_like(dist, np.inf)
            fl = np.where(valid, 1 + 2 * int(flags["delta"]), 0).astype(np.float64)
            res = np.concatenate([d, radiance, pdf, dist, fl[:, None]], axis=1)
            res[~valid, :9] = 0.0
            return res
        if op == "emitter.pdf_direction":
            (pdf,) = self.run(self.k_emitter_pdf, obj,
                              [("p3", q[:, 0:3]), ("v3", q[:, 3:6]), ("wl", q[:, 6:10])],
                              [1])
            return pdf
        raise ProtocolError("unknown op %r" % op)

    def request(self, header, payload):
        op = header.get("op")
        if op == "hello":
            if header.get("protocol") != PROTOCOL:
                log("client speaks protocol %r, this server %d" % (header.get("protocol"), PROTOCOL))
            # Mitsuba's variants compute in float32 unless their name says double
            precision = "float64" if "double" in self.variant else "float32"
            return {"ok": True, "protocol": PROTOCOL, "renderer": "mitsuba3",
                    "version": self.version(), "precision": precision,
                    "models": self.hello_models}, None
        if op not in REQUEST_WIDTH:
            return {"ok": False, "error": "unknown op %r" % (op,)}, None
        model = header.get("model")
        if model not in self.models:
            return {"ok": False, "error": "unknown model %r" % (model,)}, None
        kind = self.models[model][0]
        if kind != OP_KIND[op]:
            return {"ok": False, "error": "model %r is a %s model, op %s needs a %s model"
                    % (model, kind, op, OP_KIND[op])}, None
        if payload is None:
            return {"ok": False, "error": "op %s needs a payload (n, width)" % op}, None
        n, w = payload.shape
        if w != REQUEST_WIDTH[op]:
            return {"ok": False, "error": "op %s takes rows of %d f64, got width %d"
                    % (op, REQUEST_WIDTH[op], w)}, None
        if n > MAX_BATCH:
            return {"ok": False, "error": "batch of %d rows exceeds %d" % (n, MAX_BATCH)}, None
        if not self.np.all(self.np.isfinite(payload)):
            return {"ok": False, "error": "non-finite value in the request payload"}, None
        t0 = time.perf_counter()
        res = self.handle(op, model, payload)
        dt = time.perf_counter() - t0
        log("%s %s n=%d %.3f s (%.0f queries/s)" % (op, model, n, dt, n / dt if dt > 0 else 0))
        return {"ok": True}, res


def _jsonable(d):
    return json.loads(json.dumps(d, default=str))


def log(msg):
    print("[mitsuba model server] " + msg, file=sys.stderr, flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", default="scalar_spectral",
                    help="Mitsuba variant (default: %(default)s)")
    args = ap.parse_args(argv)

    # The protocol owns the original stdout; everything else printed to fd 1 (Mitsuba's
    # logger, Dr.Jit warnings, stray prints) goes to stderr instead.
    proto_out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    proto_in = sys.stdin.buffer

    try:
        import numpy as np
        import drjit as dr
        import mitsuba as mi
        mi.set_variant(args.variant)
    except (ImportError, AttributeError, ValueError) as e:
        log("cannot start Mitsuba %s: %s (pip install mitsuba==3.9.1 numpy; llvm_* variants "
            "also need DRJIT_LIBLLVM_PATH)" % (args.variant, e))
        return 3
    mi.set_log_level(mi.LogLevel.Warn)

    ch = Channel(proto_in, proto_out)
    with tempfile.TemporaryDirectory(prefix="furnace-mitsuba-") as tmp:
        server = Server(args.variant, np, dr, mi, tmp)
        while True:
            try:
                header, payload = ch.read(np)
            except ProtocolError as e:
                ch.write(np, {"ok": False, "error": str(e)})
                return 2
            except EOFError as e:
                log(str(e))
                return 2
            if header is None or header.get("op") == "bye":
                return 0
            try:
                reply, res = server.request(header, payload)
            except Exception as e:   # a failed batch is an ok:false reply, not a dead server
                import traceback
                traceback.print_exc(file=sys.stderr)
                reply, res = {"ok": False, "error": "%s: %s" % (type(e).__name__, e)}, None
            ch.write(np, reply, res)


if __name__ == "__main__":
    sys.exit(main())
