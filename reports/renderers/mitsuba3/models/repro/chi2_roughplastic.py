"""chi2 `plastic/roughplastic ggx α=0.1 η=1.5` and `beckmann α=0.3`: furnace reported (llvm_ad_spectral)
∫pdf dω = 1.009-1.021 over the sphere while every draw gave a sample.

Mitsuba 3.9.1 src/bsdfs/roughplastic.cpp, pdf() and eval_pdf(): `active &= cos_theta_i > 0 &&
cos_theta_o > 0`, then t_i = lerp_gather(..., active) and the lobe probability
prob_specular = (1 - t_i)·w / ((1 - t_i)·w + t_i·(1 - w)); the result is returned WITHOUT a final
`& active`/select. The scalar variant leaves early (`dr::none_or<false>(active)`: 0); a vectorised
variant computes the masked-off lanes: for wi below the horizon the masked gather gives t_i = 0,
so prob_specular = 1 and pdf = D·G1/(4 cos θo), the whole specular lobe's density there, although
sample() picked that lobe only with probability prob_specular(t_i(cos θo)) < 1."""
from _common import *
from _ref64 import vndf_pdf

D_GGX = {"type": "roughplastic", "distribution": "ggx", "alpha": 0.1, "diffuse_reflectance": 0.5,
         "int_ior": 1.5, "ext_ior": 1.0}
D_BECK = dict(D_GGX, distribution="beckmann", alpha=0.3)
wo80 = [np.sin(np.radians(80)), 0.0, np.cos(np.radians(80))]
below = np.array([[-0.99, 0.0, -0.05], [-0.95, 0.10, -0.10], [-0.97, -0.05, -0.02]])
below /= np.linalg.norm(below, axis=1, keepdims=True)
above = np.array([[-0.98, 0.0, 0.17]]) / np.linalg.norm([-0.98, 0.0, 0.17])

# 1. pdf(wo, wi) below the horizon: scalar vs llvm, same Mitsuba, same directions
res = {}
for var in ("scalar_spectral", "llvm_ad_spectral"):
    setup(var)
    b = mi.load_dict(D_GGX); ctx = mi.BSDFContext()
    vals = []
    for w in list(below) + list(above):
        if var.startswith("scalar"):
            si = mi.SurfaceInteraction3f(); si.wi = mi.Vector3f(*wo80); si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
            si.wavelengths = mi.Spectrum(500, 550, 600, 650)
            vals.append((float(b.pdf(ctx, si, mi.Vector3f(*w))), float(b.eval(ctx, si, mi.Vector3f(*w))[0])))
        else:
            p = bsdf_pdf(b, ctx, tiled(wo80, 1), np.array([w]))[0]
            vals.append((p, bsdf_fcos(b, ctx, tiled(wo80, 1), np.array([w]))[0]))
    res[var] = vals
setup("llvm_ad_spectral")
header("roughplastic: pdf of the vectorised variants below the horizon")
print("wo = θ 80° (protocol wo = Mitsuba si.wi); pdf(wo, wi) and eval (f·cos) per variant:")
for k, w in enumerate(list(below) + list(above)):
    print("  wi = [% .4f % .4f % .4f]  scalar_spectral pdf %-10.6g eval %-4g | llvm_ad_spectral pdf %-10.6g eval %g"
          % (*w, res["scalar_spectral"][k][0], res["scalar_spectral"][k][1], res["llvm_ad_spectral"][k][0], res["llvm_ad_spectral"][k][1]))

# 2. what that density is, and what the sampler actually does below the horizon
ctx = mi.BSDFContext()
for name, d, kind, a in (("ggx α=0.1", D_GGX, "ggx", 0.1), ("beckmann α=0.3", D_BECK, "beckmann", 0.3)):
    b = mi.load_dict(d)
    print("\nplastic/roughplastic %s η=1.5, llvm_ad_spectral" % name)
    p_b = bsdf_pdf(b, ctx, tiled(wo80, len(below)), below)
    print("  pdf below the horizon / (D·G1(wo)/(4 cos θo), the specular lobe alone in f64): %s"
          % np.round(p_b / vndf_pdf(f32(tiled(wo80, len(below))), f32(below), a, kind), 5))
    xg, wg = np.polynomial.legendre.leggauss(120)

    def panels(edges):
        pts = [0.5 * (b_ - a_) * xg + 0.5 * (b_ + a_) for a_, b_ in zip(edges[:-1], edges[1:])]
        wts = [0.5 * (b_ - a_) * wg for a_, b_ in zip(edges[:-1], edges[1:])]
        return np.concatenate(pts), np.concatenate(wts)
    ph, pw = panels([0.0, np.pi - 1.0, np.pi - 0.3, np.pi - 0.1, np.pi - 0.03, np.pi,
                     np.pi + 0.03, np.pi + 0.1, np.pi + 0.3, np.pi + 1.0, 2 * np.pi])
    for deg in (0, 45, 80, 89):
        wo = [np.sin(np.radians(deg)), 0.0, np.cos(np.radians(deg))]
        mass = {}
        # panels graded towards the horizon, where the grazing lobes are squeezed
        ce = [0.0, 3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3, 1.0]
        for half, edges in (("upper", ce), ("lower", [-e for e in ce[::-1]])):
            c, cw = panels(edges)
            Cc, P = np.meshgrid(c, ph, indexing="ij"); S = np.sqrt(1 - Cc * Cc)
            dirs = np.stack([S * np.cos(P), S * np.sin(P), Cc], -1).reshape(-1, 3)
            mass[half] = (bsdf_pdf(b, ctx, tiled(wo, len(dirs)), dirs).reshape(Cc.shape) * cw[:, None] * pw[None, :]).sum()
        N = 200000; rng = np.random.default_rng(deg)
        u = rng.random((N, 2)); uc = rng.random(N)
        wi, w, pdf_s, st = sample_bsdf(b, ctx, tiled(wo, N), u, uc)
        spec = (st & int(mi.BSDFFlags.GlossyReflection)) != 0
        low = wi[:, 2] <= 0
        ratio = ("%.1f" % (mass["lower"] / low.mean())) if low.sum() >= 100 else "n/a (%d draws)" % low.sum()
        print("  θo=%2d°: ∫pdf upper %.5f + lower %.5f = %.5f | draws: specular lobe chosen %.4f, above the horizon %.5f, "
              "below %.5f (all with bs.pdf > 0: %s, weight 0: %s); lower pdf mass / below-horizon draws = %s, 1/P(specular) = %.1f"
              % (deg, mass["upper"], mass["lower"], mass["upper"] + mass["lower"], spec.mean(), 1 - low.mean(), low.mean(),
                 bool(np.all(pdf_s[low] > 0)), bool(np.all(w[low] == 0)), ratio, 1 / spec.mean()))

# 3. the scalar variant: the same draws below the horizon have bs.pdf = 0 (rejected), so the
#    sampled fraction equals the pdf's mass (one angle, 20000 draws: a Python loop)
setup("scalar_spectral")
b = mi.load_dict(D_GGX); ctx = mi.BSDFContext()
si = mi.SurfaceInteraction3f(); si.wi = mi.Vector3f(*wo80); si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
si.wavelengths = mi.Spectrum(500, 550, 600, 650)
rng = np.random.default_rng(80); N = 20000; kept = 0; below_kept = 0
for u1, u2, uc in rng.random((N, 3)):
    bs, w = b.sample(ctx, si, float(uc), mi.Point2f(float(u1), float(u2)))
    if bs.pdf > 0:
        kept += 1; below_kept += bs.wo.z <= 0
print("\nscalar_spectral, ggx α=0.1, θo=80°: %d draws, %.4f with bs.pdf > 0, of them below the horizon: %d; "
      "pdf below the horizon is 0 (part 1), so ∫pdf = ∫ upper = the sampled fraction" % (N, kept / N, below_kept))
