"""reciprocity: FAIL for `dielectric/ggx α=0.3 η=1.5046 (Mitsuba bk7)` and `dielectric/beckmann α=0.3
η=1.5` (found by running furnace's reciprocity check per model), while the message shows the largest
*absolute* difference, `dielectric/ggx α=0.3 η=1.0001` 0.8894 vs 0.8899 (5.6e-4 relative), which is
inside furnace's float32 tolerance (|Δ| <= 1e-6 + 1e-3·max|f|).

Compared: f(wo,wi)/η(wo)² vs f(wi,wo)/η(wi)² (η = 1 above, the model's η below), on random
pairs over both hemispheres, θ <= 89.99°, exactly as furnace does. Mitsuba receives float32
directions. The f64 reference (_ref64.py, Walter et al. 2007 with Mitsuba's conventions) is
evaluated (a) at the same float32 inputs, (b) at those inputs renormalised exactly in f64."""
from _common import *
from _ref64 import rough_dielectric_fcos

setup("llvm_ad_spectral")
header("reciprocity of roughdielectric at float32")
ctx = mi.BSDFContext(mi.TransportMode.Radiance)


def rand_dirs(rng, n, thmax=89.99):
    cmin = np.cos(np.radians(thmax)); c = cmin + (1 - cmin) * rng.random(n); ph = 2 * np.pi * rng.random(n)
    s = np.sqrt(1 - c * c); sign = np.where(rng.random(n) < 0.5, -1, 1)
    return np.stack([s * np.cos(ph), s * np.sin(ph), sign * c], 1)


for name, d, kind, a, eta in [
        ("dielectric/ggx α=0.3 η=1.5046 (bk7)", {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": "bk7", "ext_ior": 1.0}, "ggx", 0.3, 1.5046),
        ("dielectric/beckmann α=0.3 η=1.5", {"type": "roughdielectric", "distribution": "beckmann", "alpha": 0.3, "int_ior": 1.5, "ext_ior": 1.0}, "beckmann", 0.3, 1.5),
        ("dielectric/ggx α=0.5 η=1.5", {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.5, "int_ior": 1.5, "ext_ior": 1.0}, "ggx", 0.5, 1.5),
        ("dielectric/ggx α=0.3 η=1.0001", {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": 1.0001, "ext_ior": 1.0}, "ggx", 0.3, 1.0001),
        ("dielectric/ggx α=0.1 η=1.5", {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.1, "int_ior": 1.5, "ext_ior": 1.0}, "ggx", 0.1, 1.5),
        # no f64 reference for principled: only the mechanism and the one-ulp test below
        ("principled/spec_trans 1 roughness 0.3 η=1.5", {"type": "principled", "base_color": 1.0, "spec_trans": 1.0, "roughness": 0.3, "eta": 1.5}, None, 0.09, 1.5)]:
    b = mi.load_dict(d)
    rng = np.random.default_rng(2); n = 400000
    A = f32(rand_dirs(rng, n)); B = f32(rand_dirs(rng, n))          # what Mitsuba receives
    eA = np.where(A[:, 2] < 0, eta, 1.0); eB = np.where(B[:, 2] < 0, eta, 1.0)
    m1 = bsdf_fcos(b, ctx, A, B) / np.abs(B[:, 2]) / eA ** 2
    m2 = bsdf_fcos(b, ctx, B, A) / np.abs(A[:, 2]) / eB ** 2
    err = np.abs(m1 - m2); sc = np.maximum(np.abs(m1), np.abs(m2)); peak = sc.max()
    bad = np.where(err > 1e-6 + 1e-3 * sc)[0]
    print("\n%s: %d random pairs, largest |f| %.4g; pairs beyond 1e-6 + 1e-3·max|f|: %d (all transmission pairs: %s)"
          % (name, n, peak, len(bad), bool(np.all(A[bad, 2] * B[bad, 2] < 0)) if len(bad) else "-"))
    i_abs = np.argmax(err)
    print("  largest absolute difference (what furnace's message shows): %.4g vs %.4g, relative %.1e -> %s"
          % (m1[i_abs], m2[i_abs], err[i_abs] / sc[i_abs], "within tolerance" if err[i_abs] <= 1e-6 + 1e-3 * sc[i_abs] else "beyond"))
    if not len(bad):
        continue
    # f64 reference at the same float32 inputs, and at the inputs renormalised in f64
    An = A[bad] / np.linalg.norm(A[bad], axis=1, keepdims=True); Bn = B[bad] / np.linalg.norm(B[bad], axis=1, keepdims=True)
    if kind is not None:
        r1 = rough_dielectric_fcos(A[bad], B[bad], a, eta, kind) / np.abs(B[bad, 2]) / eA[bad] ** 2
        r2 = rough_dielectric_fcos(B[bad], A[bad], a, eta, kind) / np.abs(A[bad, 2]) / eB[bad] ** 2
        n1 = rough_dielectric_fcos(An, Bn, a, eta, kind) / np.abs(Bn[:, 2]) / eA[bad] ** 2
        n2 = rough_dielectric_fcos(Bn, An, a, eta, kind) / np.abs(An[:, 2]) / eB[bad] ** 2
    # cos of the refracted angle relative to the generalised half vector, computed from the inside
    out = np.where((A[bad, 2] > 0)[:, None], An, Bn); inn = np.where((A[bad, 2] > 0)[:, None], Bn, An)
    h = out + eta * inn; h /= np.linalg.norm(h, axis=1, keepdims=True); h *= np.sign(h[:, 2])[:, None]
    ct2 = 1 - (1 - (inn * h).sum(1) ** 2) * eta ** 2                 # = (outside·h)² in exact arithmetic
    rel = lambda x, y: np.abs(x - y) / np.maximum(np.abs(x), np.abs(y))
    print("  at the failing pairs: f / largest |f| <= %.1e; Mitsuba asymmetry %.1e..%.1e relative (max |Δ| %.1e sr^-1, %.1e of the largest |f|)"
          % ((sc[bad] / peak).max(), rel(m1[bad], m2[bad]).min(), rel(m1[bad], m2[bad]).max(), err[bad].max(), err[bad].max() / peak))
    if kind is not None:
        print("    f64 formula at the SAME float32 inputs: asymmetry up to %.1e relative; at the inputs renormalised in f64: %.1e"
              % (rel(r1, r2).max(), rel(n1, n2).max()))
    print("    outside direction vs the half vector: cos θ_t,h = %.1e..%.1e; Snell from the inside, 1 - (1 - cos²)η², cancels: "
          "its float32-input error ~2ε32 relative to cos² θ_t,h = %.1e..%.1e; observed asymmetry / (2ε32/cos² θ_t,h): median %.2f, max %.2f"
          % (np.sqrt(ct2).min(), np.sqrt(ct2).max(), (2 * EPS32 / ct2).min(), (2 * EPS32 / ct2).max(),
             np.median(rel(m1[bad], m2[bad]) / (2 * EPS32 / ct2)), np.max(rel(m1[bad], m2[bad]) / (2 * EPS32 / ct2))))
    for tol in (1e-6, 1e-5):
        print("    a float32 floor of %.0e·(largest |f| of the model) instead of 1e-6 sr^-1: failing pairs %d"
              % (tol, np.sum(err > tol * peak + 1e-3 * sc)))
    # furnace-side remedy tested here: re-query a failing pair with each direction moved one float32
    # ulp in one component (12 neighbours per ordering) and allow the spread this shows
    def spread(Aa, Bb, eAa):
        vals = []
        for k, nb in enumerate(ulp_neighbours(Aa)):
            vals.append(bsdf_fcos(b, ctx, nb, Bb) / np.abs(Bb[:, 2]) / eAa ** 2)
        for nb in ulp_neighbours(Bb)[1:]:
            vals.append(bsdf_fcos(b, ctx, Aa, nb) / np.abs(nb[:, 2]) / eAa ** 2)
        vals = np.array(vals); return vals.max(0) - vals.min(0)
    s1 = spread(A[bad], B[bad], eA[bad]); s2 = spread(B[bad], A[bad], eB[bad])
    still = err[bad] > 1e-6 + 1e-3 * sc[bad] + s1 + s2
    print("    allowing the spread of f over one-ulp neighbours of the inputs: failing pairs %d of %d" % (still.sum(), len(bad)))
