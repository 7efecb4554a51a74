"""hg (g = ±0.999) and phase (g = ±0.9999) on Mitsuba's Henyey-Greenstein (src/phase/hg.cpp).

furnace reported: hg check, g = ±0.999: mean cosine 0.9990 ± 5.8e-4 as expected but p = 0; phase
check: `hg g=±0.9999` pdf returned NaN for some directions (ERROR).

The test is furnace's (src/harness/model/phase.rs, measure_phase_at) re-done here in numpy on
Mitsuba's answers: wo = (0, 0, -1), μ = wi.z; 40 μ bins of near-equal mass from Mitsuba's own
eval (graded Gauss-Legendre quadrature), none narrower than 1e-5 (furnace's float32
`mu_resolution`); 16 φ bins of φ = atan2(wi.y, wi.x) against uniform; z test of the mean cosine;
Bonferroni over the three."""
from _common import *
from _ref64 import hg as hg64

setup("llvm_ad_spectral")
header("Henyey-Greenstein near |g| = 1 in float32")
GLX = np.array([0.1834346424956498, 0.525532409916329, 0.7966664774136267, 0.9602898564975363])
GLW = np.array([0.362683783378362, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763])
up = sorted([1 - 10 ** (-14 + 14 * i / 80) for i in range(81)] + [1.0])
EDGES = np.unique(np.array([-x for x in up] + up))


def mitsuba_p(ph, mu):
    """Mitsuba's eval at scattering cosine μ, as furnace queries it: wo = -z, wi = (√(1-μ²), 0, μ)."""
    mu = np.asarray(mu, dtype=np.float64); n = mu.size
    m = dr.zeros(mi.MediumInteraction3f, n); w = mi.Vector3f(0, 0, -1); m.wi = w; m.sh_frame = mi.Frame3f(w)
    wi = np.stack([np.sqrt(np.maximum(1 - mu * mu, 0)), np.zeros(n), mu], 1)
    v, p = ph.eval_pdf(mi.PhaseFunctionContext(None), m, V(wi))
    return np1(p)


def nodes(a, b, edges=EDGES):
    pts = np.concatenate([[a], edges[(edges > a) & (edges < b)], [b]])
    c = 0.5 * (pts[1:] + pts[:-1]); h = 0.5 * (pts[1:] - pts[:-1])
    x = np.concatenate([c[:, None] + h[:, None] * GLX, c[:, None] - h[:, None] * GLX], 1).ravel()
    w = np.concatenate([h[:, None] * GLW, h[:, None] * GLW], 1).ravel()
    return x, w


def integral(f, a, b, edges=EDGES):
    x, w = nodes(a, b, edges)
    return float((w * f(x)).sum())


def furnace_phase_test(ph, g, N=100000, mu_bins=40, phi_bins=16, resolution=1e-5, seed=2, drop_undefined_phi=False):
    p = lambda x: mitsuba_p(ph, x)
    norm = 2 * np.pi * integral(p, -1, 1)
    mean_c = 2 * np.pi * integral(lambda x: x * p(x), -1, 1)
    second = 2 * np.pi * integral(lambda x: x * x * p(x), -1, 1)
    cum = np.concatenate([[0], np.cumsum([2 * np.pi * integral(p, a, b, np.array([])) for a, b in zip(EDGES[:-1], EDGES[1:])])])
    total = cum[-1]; be = [-1.0]
    for q in range(1, mu_bins):
        target = total * q / mu_bins
        i = int(np.clip(np.searchsorted(cum, target, side="left"), 1, len(EDGES) - 1))
        t = (target - cum[i - 1]) / max(cum[i] - cum[i - 1], 1e-308)
        e = EDGES[i - 1] + np.clip(t, 0, 1) * (EDGES[i] - EDGES[i - 1])
        if e > be[-1] + resolution and e < 1 - resolution:
            be.append(e)
    be.append(1.0); be = np.array(be)
    expected = np.array([N * 2 * np.pi * integral(p, a, b) for a, b in zip(be[:-1], be[1:])])
    rng = np.random.default_rng(seed); u = rng.random((N, 2))
    m = dr.zeros(mi.MediumInteraction3f, N); w = mi.Vector3f(0, 0, -1); m.wi = w; m.sh_frame = mi.Frame3f(w)
    wi, wt, pdf = ph.sample(mi.PhaseFunctionContext(None), m, 0.5, mi.Point2f(F(u[:, 0]), F(u[:, 1])))
    wi = np3(wi); mu = np.clip(wi[:, 2], -1, 1)
    b = np.clip(np.searchsorted(be, mu, side="right"), 1, len(be) - 1) - 1
    counts = np.bincount(b, minlength=len(be) - 1)
    undefined = (wi[:, 0] == 0) & (wi[:, 1] == 0)       # sin θ = 0: φ = atan2(0, 0) = 0
    keep = ~undefined if drop_undefined_phi else np.ones(N, bool)
    phi = np.mod(np.arctan2(wi[keep, 1], wi[keep, 0]), 2 * np.pi)
    pc = np.bincount(np.minimum((phi / (2 * np.pi) * phi_bins).astype(int), phi_bins - 1), minlength=phi_bins)
    x2m, dm, pm = chi2_gof(counts, expected)
    x2p, dp, pp = chi2_gof(pc, np.full(phi_bins, keep.sum() / phi_bins))
    se = max(mu.std(ddof=1) / np.sqrt(N), np.sqrt(max(second - mean_c ** 2, 0) / N))
    z = (mu.mean() - g) / se
    from math import erfc, sqrt
    pz = erfc(abs(z) / sqrt(2))
    return dict(norm=norm, mean_c=mean_c, n_mu_bins=len(be) - 1, top_bin=(be[-2], counts[-1], expected[-1]),
                p_mu=pm, p_phi=pp, p_z=pz, z=z, p=min(1, 3 * min(pm, pp, pz)), undefined=int(undefined.sum()),
                phi_bin0=(int(pc[0]), keep.sum() / phi_bins), mu_sample=mu, pdf=np1(pdf), edges=be, counts=counts)


print("\n1. hg check at g = ±0.999 (and g = ±0.9 for comparison), 100000 draws, furnace's rule re-done in numpy")
for g in (0.999, -0.999, 0.9, -0.9):
    ph = mi.load_dict({"type": "hg", "g": g}); g32 = float(np.float32(g))
    r = furnace_phase_test(ph, g)
    r2 = furnace_phase_test(ph, g, drop_undefined_phi=True)
    print("  g = %+.3f: ∫p dω = %.7f, mean cosine %.7f (quadrature of Mitsuba's eval) | %d draws with wi.x = wi.y = 0 (φ undefined, "
          "furnace bins them as φ = 0): φ bin 0 holds %d vs %.0f expected"
          % (g, r["norm"], r["mean_c"], r["undefined"], r["phi_bin0"][0], r["phi_bin0"][1]))
    print("             furnace's rule: p(μ) %.3g, p(φ) %.3g, p(z) %.3g -> p %.3g | φ without the undefined draws: p(φ) %.3g"
          % (r["p_mu"], r["p_phi"], r["p_z"], r["p"], r2["p_phi"]))
    # the same μ bins, expected counts from the exact HG (f64, g as the float32 Mitsuba stores)
    be = r["edges"]
    cdf = lambda m: 0.0 if m <= -1 else (1.0 if m >= 1 else 2 * np.pi * integral(lambda x: hg64(x, g32), -1, m))
    exp_exact = 100000 * np.diff([cdf(e) for e in be])
    x2, dof, pe = chi2_gof(r["counts"], exp_exact)
    print("             Mitsuba's draws against the EXACT HG (f64) in the same μ bins, i.e. the sampler alone: χ² %.1f, dof %d, p %.3g"
          % (x2, dof, pe))
    # Mitsuba's formula order vs the stable order, both in float32, at the float32 μ furnace's queries become
    x, w = nodes(-1, 1)
    mu32 = f32(x).astype(np.float32)   # wo = -z, wi.z = μ: the dot product is -μ exactly
    gg = np.float32(g)
    t_mi = np.float32(1) + gg * gg + np.float32(2) * gg * (-mu32)            # hg.cpp: 1 + g² + 2g·cos
    ag = np.float32(abs(g)); sg = np.float32(np.sign(g))
    t_st = (np.float32(1) - ag) ** 2 + np.float32(2) * ag * (np.float32(1) - sg * mu32)  # (1-|g|)² + 2|g|(1 ∓ μ): exact 1 ∓ μ
    p_mi = (np.float32(1 / (4 * np.pi)) * (np.float32(1) - gg * gg) / (t_mi * np.sqrt(t_mi))).astype(np.float64)
    p_st = (np.float32(1 / (4 * np.pi)) * (np.float32(1) - gg * gg) / (t_st * np.sqrt(t_st))).astype(np.float64)
    print("             ∫p dω in float32 numpy on furnace's nodes: hg.cpp's order %.6f, (1-|g|)² + 2|g|(1 - sign(g)·μ) order %.6f; f64 %.9f"
          % (2 * np.pi * (w * p_mi).sum(), 2 * np.pi * (w * p_st).sum(), 2 * np.pi * (w * hg64(x, g32)).sum()))

print("\n   why sin θ = 0: Mitsuba's sample computes cos θ = (1 + g² - s²)/(2g) in float32; float32 has no value in"
      "\n   (1 - 2^-25, 1), so every cos θ within 3e-8 of 1 becomes exactly 1 (and sin θ = √(1 - cos² θ) = 0 once cos² θ rounds to 1).")
g = 0.999
for thr in (2 ** -25, 2 ** -24):
    a = (1 - g) ** 2 + 2 * g * thr
    mass = (1 - g * g) / (2 * g) * (1 / (1 - g) - 1 / np.sqrt(a))
    print("   exact HG g = 0.999: probability of 1 - μ < %.2e is %.4f" % (thr, mass))

print("\n2. g = ±0.9999: eval/pdf at directions within float32 rounding of exact forward scattering")
for g in (0.9999, -0.9999):
    ph = mi.load_dict({"type": "hg", "g": g})
    rng = np.random.default_rng(7); n = 100000
    theta = 10 ** rng.uniform(-9, -2, n); phi = rng.uniform(0, 2 * np.pi, n)   # angle from exact forward
    wo = rng.normal(size=(n, 3)); wo /= np.linalg.norm(wo, axis=1, keepdims=True)  # random orientations
    fwd = -np.sign(g) * wo
    t1 = np.cross(fwd, [0.0, 0.0, 1.0]); t1 /= np.linalg.norm(t1, axis=1, keepdims=True); t2 = np.cross(fwd, t1)
    wi = f32(np.cos(theta)[:, None] * fwd + np.sin(theta)[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2))
    wo = f32(wo)                                                                 # unit in f64, then float32
    m = dr.zeros(mi.MediumInteraction3f, n); w = V(wo); m.wi = w; m.sh_frame = mi.Frame3f(w)
    v, p = ph.eval_pdf(mi.PhaseFunctionContext(None), m, V(wi))
    p = np1(p)
    dot = (wo * wi).sum(1)                                    # exact (f64) dot of the float32 inputs
    g32 = np.float32(g)
    temp32 = np.float32(1) + g32 * g32 + np.float32(2) * g32 * dot.astype(np.float32)   # hg.cpp's temp in float32
    temp_exact = (1 + float(g32) ** 2) + 2 * float(g32) * dot                          # the same, exactly, same inputs
    bad = ~np.isfinite(p)
    print("  g = %+.4f: %d random wo, wi at 1e-9..1e-2 rad from exact forward (float32): Mitsuba pdf NaN %d, inf %d (all at angles <= %.1e rad); "
          "finite elsewhere, max %.3g" % (g, n, np.isnan(p).sum(), np.isinf(p).sum(), theta[bad].max() if bad.any() else 0, p[~bad].max()))
    print("      hg.cpp's 1 + g² + 2g·(wo·wi) emulated in float32 (numpy): negative %d, zero %d; in exact arithmetic on the same float32 "
          "inputs: negative %d (where |wo·wi| > 1: the float32 vectors are not exactly unit), smallest %.2e; (1 - |g|)² = %.1e vs float32 spacing below 2: %.1e"
          % ((temp32 < 0).sum(), (temp32 == 0).sum(), (temp_exact < 0).sum(), temp_exact.min(),
             (1 - abs(float(g32))) ** 2, np.spacing(np.float32(1.5))))
    mu = np.clip(-dot, -1, 1)
    print("      the same formula in f64 written as (1-g)² + 2g(1-μ) with μ clamped to [-1, 1]: finite everywhere, peak %.4g = %.4g (1/(4π)·(1+g)/(1-g)²)"
          % (hg64(mu, float(g32)).max(), (1 + abs(float(g32))) / (4 * np.pi * (1 - abs(float(g32))) ** 2)))
    N = 100000; u = np.random.default_rng(2).random((N, 2))
    m = dr.zeros(mi.MediumInteraction3f, N); w = mi.Vector3f(0, 0, -1); m.wi = w; m.sh_frame = mi.Frame3f(w)
    wi_s, wt, pdf_s = ph.sample(mi.PhaseFunctionContext(None), m, 0.5, mi.Point2f(F(u[:, 0]), F(u[:, 1])))
    wi_s = np3(wi_s); pdf_s = np1(pdf_s); pdf_again = np1(ph.eval_pdf(mi.PhaseFunctionContext(None), m, V(wi_s))[1])
    print("      Mitsuba's own sampler, %d draws: sample pdf inf %d, NaN %d; pdf(wo, wi) at the drawn directions inf %d, NaN %d; "
          "draws exactly forward (wi.x = wi.y = 0): %d"
          % (N, np.isinf(pdf_s).sum(), np.isnan(pdf_s).sum(), np.isinf(pdf_again).sum(), np.isnan(pdf_again).sum(),
             ((wi_s[:, 0] == 0) & (wi_s[:, 1] == 0)).sum()))

print("\n3. conditioning: relative error of hg.cpp's float32 eval against the f64 formula at the same float32 inputs")
for g in (0.9, 0.99, 0.999, 0.9999):
    ph = mi.load_dict({"type": "hg", "g": g}); g32 = float(np.float32(g))
    one_m = np.concatenate([[0.0], np.geomspace(1e-9, 1e-1, 4000)])
    mu = f32(1 - one_m)
    pm = mitsuba_p(ph, mu)
    wi = f32(np.stack([np.sqrt(1 - mu * mu), np.zeros_like(mu), mu], 1))
    mu_in = wi[:, 2]                                            # wo = -z: μ = wi.z exactly
    ref = hg64(mu_in, g32)
    ok = np.isfinite(pm)
    rel = np.abs(pm[ok] / ref[ok] - 1)
    print("  g = %.4f: max relative error %.2e over 1 - μ in {0} ∪ [1e-9, 0.1] where finite (non-finite answers: %d); bound 2·ε32/(1-g)² = %.2e"
          % (g, rel.max(), (~ok).sum(), 2 * EPS32 / (1 - g32) ** 2))

print("\n4. ∫p dω of Mitsuba's float32 eval vs g (furnace's graded quadrature on Mitsuba's answers), against the same")
print("   formula in float32 written as (1-|g|)² + 2|g|(1 - sign(g)·μ) at the same float32 μ (what rounding of the")
print("   direction alone costs); hg.cpp's constant 1 + g² is rounded twice (g², then the sum: float32 spacing 1.2e-7 below 2)")
for g in (0.9, 0.99, 0.995, 0.998, 0.999, 0.9995):
    ph = mi.load_dict({"type": "hg", "g": g}); gg = np.float32(g)
    n_mi = 2 * np.pi * integral(lambda x: mitsuba_p(ph, x), -1, 1)
    x, w = nodes(-1, 1); mu32 = f32(x).astype(np.float32)
    t_st = (np.float32(1) - gg) ** 2 + np.float32(2) * gg * (np.float32(1) - mu32)
    p_st = (np.float32(1 / (4 * np.pi)) * (np.float32(1) - gg * gg) / (t_st * np.sqrt(t_st))).astype(np.float64)
    one_g2 = np.float32(1) + gg * gg
    print("  g = %-6g ∫p: Mitsuba %.5f, stable order %.5f | (1 - g)² = %.2e, float32 error of the constant 1 + g²: %+.1e"
          % (g, n_mi, 2 * np.pi * (w * p_st).sum(), (1 - float(gg)) ** 2, float(one_g2) - (1 + float(gg) ** 2)))

print("\n5. the same g = ±0.999 in scalar_spectral (one Python call per query): a different float32 rounding sequence")
setup("scalar_spectral")
ctx = mi.PhaseFunctionContext(None)
for g in (0.999, -0.999):
    ph = mi.load_dict({"type": "hg", "g": g})
    m = mi.MediumInteraction3f(); w = mi.Vector3f(0, 0, -1); m.wi = w; m.sh_frame = mi.Frame3f(w)
    x, wq = nodes(-1, 1)
    vals = np.array([float(ph.eval_pdf(ctx, m, mi.Vector3f(float(np.sqrt(max(1 - t * t, 0))), 0.0, float(t)))[1]) for t in x])
    u = np.random.default_rng(2).random((100000, 2)); und = 0
    for a, b in u:
        wi_s, wt, pdf = ph.sample(ctx, m, 0.5, mi.Point2f(float(a), float(b)))
        und += (wi_s.x == 0 and wi_s.y == 0)
    print("  g = %+.3f: ∫p dω of the scalar eval %.6f (llvm_ad_spectral: 0.966303); draws with wi.x = wi.y = 0: %d of 100000 (llvm: ~6100)"
          % (g, 2 * np.pi * (wq * vals).sum(), und))
