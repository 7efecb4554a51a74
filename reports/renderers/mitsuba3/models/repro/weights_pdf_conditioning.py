"""sample_weights, per-sample consistency: the pdf(wo, wi) of a sampled direction differs from the
sample's own pdf by 16-17 % (GGX α = 1e-4, conductor and dielectric), 2.6 % (dielectric GGX α = 0.1
η = 1.5), 0.5 % (η = 1.0001) and 0.3 % (Beckmann α = 0.3), against furnace's float32 tolerance 1e-3.

Mitsuba's sample() computes bs.pdf from the microfacet normal m it drew (exact direction, before
rounding); pdf(wo, wi) recomputes the half vector from the returned float32 wi. Both are the same
closed form (roughconductor.cpp / roughdielectric.cpp). Here, at furnace's outgoing angles (30°, 60°,
89.9°), with the f64 formula (_ref64.vndf_pdf) as the reference and the pdf's spread over the six
float32 neighbours of wi (one ulp in one component) as the measure of its conditioning."""
from _common import *
from _ref64 import vndf_pdf

setup("llvm_ad_spectral")
header("sample_weights: sampled pdf vs pdf(wo, wi) at float32")
ctx = mi.BSDFContext(mi.TransportMode.Radiance)
MODELS = [
    ("conductor/ggx α=1e-4", {"type": "roughconductor", "distribution": "ggx", "alpha": 1e-4, "eta": 0.2, "k": 3.0}, "ggx", 1e-4, None),
    ("dielectric/ggx α=1e-4 η=1.5", {"type": "roughdielectric", "distribution": "ggx", "alpha": 1e-4, "int_ior": 1.5, "ext_ior": 1.0}, "ggx", 1e-4, 1.5),
    ("dielectric/ggx α=0.1 η=1.5", {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.1, "int_ior": 1.5, "ext_ior": 1.0}, "ggx", 0.1, 1.5),
    ("dielectric/ggx α=0.3 η=1.0001", {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": 1.0001, "ext_ior": 1.0}, "ggx", 0.3, 1.0001),
    ("dielectric/beckmann α=0.3 η=1.5", {"type": "roughdielectric", "distribution": "beckmann", "alpha": 0.3, "int_ior": 1.5, "ext_ior": 1.0}, "beckmann", 0.3, 1.5),
    ("conductor/ggx α=0.3 perfect", {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3, "material": "none"}, "ggx", 0.3, None),
]
rng = np.random.default_rng(5)
print("columns: θo | largest |pdf(wo,wi) - bs.pdf|/max | Mitsuba pdf(wo,wi) vs the f64 formula at the same float32 wo, wi (median, max) |"
      "\n         samples beyond 1e-3 | of those, beyond the pdf's one-ulp spread (Mitsuba's pdf over wi's 6 float32 neighbours, + 1e-3) | beyond twice it"
      "\n         | beyond twice it + max(1e-3, 4ε32/|η-1|) (the proposed float32 rule)")
for name, d, kind, a, eta in MODELS:
    b = mi.load_dict(d)
    print(name)
    for th in (30.0, 60.0, 89.9):
        t = np.radians(th); n = 20000
        wo = f32(tiled([np.sin(t), 0.0, np.cos(t)], n))
        wi, w, sp, st = sample_bsdf(b, ctx, wo, rng.random((n, 2)), rng.random(n))
        ok = (sp > 0) & (w != 0)
        pa = bsdf_pdf(b, ctx, wo, wi)
        with np.errstate(invalid="ignore", divide="ignore"):
            p64 = vndf_pdf(wo, wi, a, kind, eta)
            rel = np.where(ok, np.abs(pa - sp) / np.maximum(pa, sp), 0)
            ar = np.abs(pa[ok] - p64[ok]) / p64[ok]
        nbs = np.array([bsdf_pdf(b, ctx, wo, x) for x in ulp_neighbours(wi)])
        lo, hi = nbs.min(0), nbs.max(0)
        beyond = ok & (rel > 1e-3)
        out1 = beyond & ((sp < lo - (hi - lo) * 0 - 1e-3 * hi) | (sp > hi + 1e-3 * hi))
        out2 = beyond & ((sp < lo - (hi - lo) - 1e-3 * hi) | (sp > hi + (hi - lo) + 1e-3 * hi))
        # proposed float32 rule: the spread twice, plus a relative floor max(1e-3, 4ε32/|η-1|) (η from the flags)
        floor = max(1e-3, 4 * EPS32 / abs(eta - 1)) if eta is not None else 1e-3
        out3 = beyond & ((sp < lo - (hi - lo) - floor * hi) | (sp > hi + (hi - lo) + floor * hi))
        print("   θo %5.1f° | %.2e | f64: %.1e, %.1e | %5d | %4d | %4d | %4d" % (th, rel.max(), np.nanmedian(ar), np.nanmax(ar), beyond.sum(), out1.sum(), out2.sum(), out3.sum()))
        if eta is not None and abs(eta - 1) < 1e-3:
            tr = ok & (wi[:, 2] * wo[:, 2] < 0)
            hv = np.linalg.norm(wo + eta * wi, axis=1)[tr]
            print("      η ≈ 1: transmitted samples have |wo + η·wi| (the unnormalised half vector) median %.1e: pdf()'s Jacobian"
                  " divides by its square, a sum of two dot products ≈ ±1 that cancel: 2·ε32/|wo + η·wi| = %.1e" % (np.median(hv), 2 * EPS32 / np.median(hv)))

print("\nwhy grazing reflection is worst: the half vector of wo at θo and its mirror direction is (wo + wi)/|wo + wi| with"
      "\n|wo + wi| = 2 cos θo; the x components (≈ ±1) cancel, so wi's float32 rounding (ε32 ≈ 6e-8) turns the half vector"
      "\nby ~ε32/(2 cos θo) rad, i.e. ε32/(2 α cos θo) lobe widths:")
for a in (1e-4, 0.1):
    for th in (30.0, 60.0, 89.9):
        print("   α = %-6g θo = %5.1f°: ε32/(2 α cos θo) = %.1e" % (a, th, EPS32 / (2 * a * np.cos(np.radians(th)))))
