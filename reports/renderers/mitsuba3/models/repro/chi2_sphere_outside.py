"""chi2 `area sphere (outside)`: furnace reported ∫pdf dω = 0.9993 over the sphere and a
chi-square p of 3e-19. Is Mitsuba's pdf_direction short of mass, or furnace's quadrature?

Scene as the model server builds it: a sphere, centre (0.3, 0.2, 2), r = 0.5, emitting outwards,
receiving point p = 0. Mitsuba samples the cone of directions subtended by the sphere uniformly
(sphere.cpp sample_direction) and pdf_direction answers 1/(2π(1 - cos α)) (uniform cone), the
model server summing it over the crossings of the ray (the far crossing is back-facing: 0)."""
from _common import *

setup("llvm_ad_spectral")
header("chi2 of area sphere (outside): Mitsuba's cone pdf vs furnace's bin quadrature")
C = np.array([0.3, 0.2, 2.0]); R = 0.5; L = 2.0
scene = mi.load_dict({"type": "scene", "shape": {"type": "sphere", "center": C.tolist(), "radius": R,
                      "emitter": {"type": "area", "radiance": {"type": "uniform", "value": L}}}})
em = scene.emitters()[0]
d0 = np.linalg.norm(C); sin_a = R / d0; cos_a = np.sqrt(1 - sin_a ** 2)
Omega = 2 * np.pi * (1 - cos_a); axis = C / d0
print("exact cone from p = 0: sin α = %.9f, solid angle Ω = %.10f sr, 1/Ω = %.8f sr^-1" % (sin_a, Omega, 1 / Omega))


def mitsuba_pdf(w):
    """What the model server answers for emitter.pdf_direction: trace p + t·w, sum over crossings."""
    n = w.shape[0]
    it = dr.zeros(mi.Interaction3f, n)
    it.p = mi.Point3f(0, 0, 0); it.wavelengths = mi.Spectrum(500, 550, 600, 650)
    ray = mi.Ray3f(mi.Point3f(0, 0, 0), V(w)); alive = mi.Bool(True); total = mi.Float(0)
    for _ in range(4):
        si = scene.ray_intersect(ray, alive)
        alive = alive & si.is_valid()
        ds = mi.DirectionSample3f(scene, si, it)
        total = total + dr.select(alive, em.pdf_direction(it, ds, alive), 0.0)
        ray = si.spawn_ray(V(w))
    return np1(total)


# 1. the value and the support of Mitsuba's pdf
frame_u = np.cross(axis, [1.0, 0, 0]); frame_u /= np.linalg.norm(frame_u); frame_v = np.cross(axis, frame_u)


def cone_dirs(theta, phi):
    t, p = np.broadcast_arrays(np.atleast_1d(theta), np.atleast_1d(phi))
    return (np.cos(t)[:, None] * axis + np.sin(t)[:, None] * (np.cos(p)[:, None] * frame_u + np.sin(p)[:, None] * frame_v))


alpha = np.arcsin(sin_a)
inside = mitsuba_pdf(cone_dirs(np.linspace(0, alpha * 0.999, 2000), np.linspace(0, 2 * np.pi, 2000)))
print("pdf_direction inside the cone: min %.8f max %.8f (exact 1/Ω %.8f, relative %.1e)"
      % (inside.min(), inside.max(), 1 / Omega, abs(inside.mean() * Omega - 1)))
phis = np.linspace(0, 2 * np.pi, 64, endpoint=False); edge = []
for ph in phis:  # bisect the silhouette: the largest angle from the axis with pdf > 0
    lo, hi = alpha * 0.99, alpha * 1.01
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if mitsuba_pdf(cone_dirs(mid, ph))[0] > 0: lo = mid
        else: hi = mid
    edge.append(lo)
edge = np.array(edge)
print("silhouette of Mitsuba's pdf (64 azimuths, bisection): angle/α - 1 in [%.1e, %.1e]; the mass "
      "this moves across the exact cone's edge: %.1e of the total" % (edge.min() / alpha - 1, edge.max() / alpha - 1,
      np.mean(cos_a - np.cos(edge)) / (1 - cos_a)))

# 2. ∫ pdf dω of Mitsuba's pdf_direction in cone-aligned coordinates (the hard edge is on a node line)
xt, wt = np.polynomial.legendre.leggauss(400); xp, wp = np.polynomial.legendre.leggauss(400)
total = 0.0
for lo, hi in [(0, alpha * (1 - 1e-6)), (alpha * (1 - 1e-6), alpha * 1.01)]:
    th = 0.5 * (hi - lo) * xt + 0.5 * (hi + lo); thw = 0.5 * (hi - lo) * wt
    ph = np.pi * xp + np.pi; phw = np.pi * wp
    T, P = np.meshgrid(th, ph, indexing="ij")
    vals = mitsuba_pdf(cone_dirs(T.ravel(), P.ravel())).reshape(T.shape)
    total += (vals * np.sin(T) * thw[:, None] * phw[None, :]).sum()
print("∫ Mitsuba pdf_direction dω, cone-aligned Gauss-Legendre (edge resolved): %.7f" % total)


# 3. furnace's own rule (src/stats/sphere.rs: 24 x 48 bins equal in cos θ and φ, 32 x 32
#    Gauss-Legendre nodes per bin) applied to the EXACT uniform-cone pdf, in f64
def furnace_masses(pdf, tb=24, pb=48, sub=32):
    x, w = np.polynomial.legendre.leggauss(sub); ww = np.outer(w, w).ravel()
    dc, dphi = 2 / tb, 2 * np.pi / pb; m = np.zeros(tb * pb)
    for s in range(tb):
        c = np.clip(1 - s * dc - 0.5 * dc + 0.5 * dc * x, -1, 1)
        for q in range(pb):
            ph = (q + 0.5) * dphi + 0.5 * dphi * x
            Cc, P = np.meshgrid(c, ph, indexing="ij"); S = np.sqrt(np.maximum(1 - Cc * Cc, 0))
            d = np.stack([S * np.cos(P), S * np.sin(P), Cc], -1).reshape(-1, 3)
            m[s * pb + q] = (ww * pdf(d)).sum() * 0.25 * dc * dphi
    return m


def exact_pdf(d):
    return np.where(d @ axis >= cos_a, 1 / Omega, 0.0)


m32 = furnace_masses(exact_pdf)
m32_mi = furnace_masses(mitsuba_pdf)
print("furnace's rule, 32x32 nodes per bin: exact pdf -> %.6f, Mitsuba's pdf -> %.6f (furnace reported 0.9993)"
      % (m32.sum(), m32_mi.sum()))
for sub in (64, 128, 256):
    print("   same rule with %3d x %3d nodes per bin, exact pdf -> %.7f" % (sub, sub, furnace_masses(exact_pdf, sub=sub).sum()))

# 4. the chi-square of Mitsuba's samples against both sets of expected masses
N = 200000
rng = np.random.default_rng(1)
u = rng.random((N, 2))
it = dr.zeros(mi.Interaction3f, N); it.p = mi.Point3f(0, 0, 0); it.wavelengths = mi.Spectrum(500, 550, 600, 650)
ds, spec = em.sample_direction(it, mi.Point2f(F(u[:, 0]), F(u[:, 1])))
d = np3(ds.d); pdf_s = np1(ds.pdf)
print("samples: %d, all with pdf %.8f (1/Ω relative %.1e); all inside the exact cone: %s"
      % (N, pdf_s.mean(), abs(pdf_s.mean() * Omega - 1), bool(np.all(d @ axis >= cos_a - 1e-6))))
c = np.clip(d[:, 2], -1, 1); strip = np.where(c >= 0, 23 - np.minimum(((1 + c) * 12).astype(int), 23),
                                              np.minimum(((1 - c) * 12).astype(int), 23))
phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi); sector = np.minimum((phi / (2 * np.pi) * 48).astype(int), 47)
counts = np.bincount(strip * 48 + sector, minlength=24 * 48)


m256 = furnace_masses(exact_pdf, sub=256)


def edge_bins(pdf, tb=24, pb=48, sub=32):
    """Bins whose 32 x 32 node values are not all equal (an edge crosses them) or differ from a
    neighbour's (an edge may pass between their nodes)."""
    x, w = np.polynomial.legendre.leggauss(sub)
    dc, dphi = 2 / tb, 2 * np.pi / pb; lo = np.zeros((tb, pb)); hi = np.zeros((tb, pb))
    for st in range(tb):
        c = np.clip(1 - st * dc - 0.5 * dc + 0.5 * dc * x, -1, 1)
        for q in range(pb):
            ph = (q + 0.5) * dphi + 0.5 * dphi * x
            Cc, P = np.meshgrid(c, ph, indexing="ij"); S = np.sqrt(np.maximum(1 - Cc * Cc, 0))
            v = pdf(np.stack([S * np.cos(P), S * np.sin(P), Cc], -1).reshape(-1, 3)); lo[st, q], hi[st, q] = v.min(), v.max()
    mark = lo != hi
    for ds in (-1, 0, 1):
        for dq in (-1, 0, 1):
            nlo = np.roll(np.roll(lo, dq, axis=1), ds, axis=0); nhi = np.roll(np.roll(hi, dq, axis=1), ds, axis=0)
            rows = np.ones(tb, bool)
            if ds == 1: rows[0] = False
            if ds == -1: rows[-1] = False
            mark |= ((nlo != lo) | (nhi != hi)) & rows[:, None]
    return mark.ravel()


mark = edge_bins(mitsuba_pdf)
m_a = np.where(mark, m256, m32)
print("proposal (a): 256 x 256 nodes only in the %d of %d bins with an edge or next to one -> sum %.7f"
      % (mark.sum(), mark.size, m_a.sum()))
m16 = furnace_masses(exact_pdf, sub=16)
e32 = m32 * N; keep = e32 >= 5
with np.errstate(invalid="ignore", divide="ignore"):
    x2b = (((counts - e32) ** 2 / (e32 + (N * np.abs(m32 - m16)) ** 2))[keep]).sum()
dofb = keep.sum() - 1
for name, m in [("furnace's 32x32 nodes", m32), ("256x256 nodes (sum %.6f)" % m256.sum(), m256),
                ("proposal (a)", m_a)]:
    x2, dof, p = chi2_gof(counts, m * N)
    print("chi-square of Mitsuba's 200000 samples, expected from %-40s: χ² = %8.1f, dof %d, p = %.2g" % (name, x2, dof, p))
print("(furnace's pooling of bins with expected < 5, src/stats/chi2.rs; furnace's own run: p 3.2e-19)")
print("proposal (b): furnace's 32x32 masses, each bin's variance widened by its quadrature error estimate (N·|m32 - m16|)²:"
      " χ² = %.1f, dof %d, p = %.2g" % (x2b, dofb, chi2_sf(x2b, dofb)))
